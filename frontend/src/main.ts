// Crossroads studio: the scenario editor, batch runner, live runs and results browser (plain TypeScript).
import "./style.css";
import { $, api, Json, post } from "./api";
import { cancelBatch, reattach, refreshBatches, runBatch, showBatch } from "./batches";
import { applyDraft, loadDraft, saveDraft } from "./draft";
import { clearErrors, field, form, scenarioBody, showErrors } from "./form";
import {
  catalogueSource, currentSource, fillApproaches, fillLanes, fillPhases, geometryOf, limitElapsed,
  setSources, uploadSource,
} from "./intersections";
import { startLive, stopLive } from "./live";
import { fillPolicies, initPolicyUploads } from "./policies";
import { drawPreview } from "./preview";
import { initSearches } from "./searches";
import { uploadNetwork } from "./upload";

let scenarioId: number | null = null; // the saved scenario the form shows; null once edited
const policy = () => $<HTMLSelectElement>("#policy").value;

const SAVED_KEY = "crossroads.saved-scenario"; // sessionStorage: the saved scenario the form shows

function showSaved(id: number, name: string): void {
  scenarioId = id;
  $("#saved").textContent = `Saved as scenario #${id} (${name})`;
  $<HTMLButtonElement>("#run").disabled = false;
}

async function save(ev: Event): Promise<void> {
  ev.preventDefault();
  clearErrors();
  $("#save-error").textContent = "";
  try {
    const s = await post("/api/scenarios", scenarioBody());
    showSaved(s.id, s.name);
    sessionStorage.setItem(SAVED_KEY, JSON.stringify({ id: s.id, name: s.name }));
  } catch (e) {
    forget();
    showErrors(e);
    pointAtErrors();
  }
}

/** After a refused save: say so beside the button, and bring the first field in error into view
 *  (it may be far above or below the button). */
function pointAtErrors(): void {
  const first = form.querySelector<HTMLElement>(".invalid");
  const count = form.querySelectorAll(".field-error").length;
  const general = $("#form-error").textContent ?? "";
  if (first) {
    const label = (first.closest("label")?.firstChild?.textContent ?? first.getAttribute("name") ?? "").trim();
    $("#save-error").textContent = `Not saved: ${count} field${count > 1 ? "s" : ""} to fix`
      + (label ? ` (first: ${label})` : "") + (general ? `; ${general}` : "");
    first.scrollIntoView({ block: "center" });
    first.focus({ preventScroll: true });
  } else {
    $("#save-error").textContent = `Not saved: ${general}`;
  }
}

/** A changed scenario must be saved again before a batch runs it. */
function forget(): void {
  scenarioId = null;
  sessionStorage.removeItem(SAVED_KEY);
  $<HTMLButtonElement>("#run").disabled = true;
  $("#saved").textContent = "";
  $("#save-error").textContent = "";
}

/** The choices that depend on the network, after the intersection (or approach, task, lane)
 * changed, and the preview. */
async function networkChanged(what: "intersection" | "approach" | "task" | "lane"): Promise<void> {
  const source = currentSource();
  if (!source) return;
  $("#intersection-description").textContent = source.description;
  try {
    const geo = await geometryOf(source);
    if (what === "intersection") fillApproaches(geo);
    if (what !== "lane") fillLanes(geo, field("task").value);
    fillPhases(geo, field("task").value); // the ego's light in each phase depends on all of them
  } catch (e) {
    showErrors(e);
  }
  await drawPreview();
}

/** The ego's start defaults, from the scenario's JSON Schema (one definition, in the backend),
 * as the placeholders of its empty fields. */
async function egoDefaults(): Promise<void> {
  const schema = await api("/api/scenarios/schema");
  const ego = schema.$defs?.EgoSpec?.properties ?? {};
  for (const key of ["start_distance_m", "start_speed_mps"]) {
    const value = ego[key]?.default;
    if (typeof value === "number") (field(`ego.${key}`) as HTMLInputElement).placeholder = String(Math.round(value * 100) / 100);
  }
}

function wire(): void {
  field("intersection").addEventListener("change", () => void networkChanged("intersection"));
  field("approach").addEventListener("change", () => void networkChanged("approach"));
  field("task").addEventListener("change", () => void networkChanged("task"));
  field("lights.phase").addEventListener("change", () => {
    const source = currentSource();
    if (source) void geometryOf(source).then(limitElapsed);
  });
  field("ego.entrance_lane").addEventListener("change", () => void networkChanged("lane"));
  field("ego.start_distance_m").addEventListener("change", () => void drawPreview());
  const edited = (ev: Event) => {
    if (!(ev.target as HTMLElement).closest("[data-not-scenario]")) forget();
  };
  form.addEventListener("input", edited);
  form.addEventListener("change", edited);
  form.addEventListener("input", saveDraft);
  form.addEventListener("change", saveDraft);
  form.addEventListener("submit", (ev) => void save(ev));
  $("#upload").addEventListener("click", async () => {
    if (await uploadNetwork()) {
      forget();
      await networkChanged("intersection");
    }
  });
  $("#run").addEventListener("click", () => { if (scenarioId != null) void runBatch(scenarioId, policy()); });
  $("#cancel").addEventListener("click", () => void cancelBatch(Number($("#cancel").dataset.batch)));
  $("#live").addEventListener("click", () => void startLive(scenarioId, policy()));
  $("#live-stop").addEventListener("click", () => void stopLive());
  $("#refresh").addEventListener("click", () => void refreshBatches());
  $("#batches").addEventListener("click", (ev) => {
    const data = (ev.target as HTMLElement).dataset;
    if (data.batch) void showBatch(Number(data.batch));
    if (data.cancel) void cancelBatch(Number(data.cancel));
  });
}

/** The form as this tab left it (after a reload), else its defaults: the network's choices are
 *  filled in steps, each from the draft's value of the step before. */
async function restoreForm(): Promise<void> {
  const draft = loadDraft();
  if (draft) applyDraft(draft); // the network's own choices are refilled below, then set again
  await networkChanged("intersection");
  if (!draft) return;
  applyDraft(draft, ["approach"]);
  await networkChanged("approach");
  applyDraft(draft);
  const source = currentSource();
  if (source) limitElapsed(await geometryOf(source));
  await drawPreview();
  const saved = JSON.parse(sessionStorage.getItem(SAVED_KEY) ?? "null"); // unedited since its save
  if (saved?.id) showSaved(Number(saved.id), String(saved.name));
}

async function init(): Promise<void> {
  const [intersections, uploads, policies] = await Promise.all([
    api("/api/intersections"), api("/api/intersections/uploads"), api("/api/policies")]);
  setSources((intersections as Json[]).map(catalogueSource), (uploads as Json[]).map(uploadSource));
  initPolicyUploads();
  fillPolicies(policies as Json[]);
  wire();
  initSearches(() => scenarioId, policy);
  await egoDefaults();
  const [, batches] = await Promise.all([restoreForm(), refreshBatches()]);
  await reattach(batches);
}

init().catch((e) => { $("#form-error").textContent = `cannot reach the API: ${e}`; });
