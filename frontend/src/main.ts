// Crossroads studio: the scenario editor, batch runner, live runs and results browser (plain TypeScript).
import "./style.css";
import { $, api, esc, Json, post } from "./api";
import { cancelBatch, reattach, refreshBatches, resumeBatch, runBatch, showBatch } from "./batches";
import { applyDraft, Draft, loadDraft, saveDraft, specToDraft } from "./draft";
import { clearErrors, clearFieldErrors, field, form, scenarioBody, showErrors } from "./form";
import {
  catalogueSource, currentSource, fillApproaches, fillJunctions, fillLanes, fillPhases, fillTasks, geometryOf,
  limitElapsed, setSources, sourceKeyOf, tasksOfLane, uploadSource,
} from "./intersections";
import { comparePicked, picked, pickedChanged } from "./compare";
import { initLibrary, openStored, refreshLibrary } from "./library";
import { startLive, stopLive } from "./live";
import { fillPolicies, initPolicyUploads } from "./policies";
import { drawPreview, initPreview, LanePick, resetView, showPreviewStatus } from "./preview";
import { initSearches } from "./searches";
import { uploadNetwork } from "./upload";
import { initViewer } from "./viewer";

let scenarioId: number | null = null; // the saved scenario the form shows; null once edited
const policy = () => $<HTMLSelectElement>("#policy").value;

const SAVED_KEY = "crossroads.saved-scenario"; // sessionStorage: the saved scenario the form shows
const EDITING_KEY = "crossroads.editing"; // sessionStorage: the stored scenario the form came from

/** The stored scenario the form was opened from: its spec keeps the fields the form does not show
 *  (turn shares, description, …), and ``id`` is set while no batch has run it (Save replaces it). */
interface Editing { id: number | null; from: number; name: string; base: Json }
let editing: Editing | null = null;

function setEditing(e: Editing | null): void {
  editing = e;
  if (e) sessionStorage.setItem(EDITING_KEY, JSON.stringify(e));
  else sessionStorage.removeItem(EDITING_KEY);
  const hint = $("#editing");
  hint.innerHTML = !e ? ""
    : e.id != null
      ? `Editing stored scenario #${e.id} (${esc(e.name)}): Save replaces it. <button type="button" id="save-as-new">Save as a new scenario instead</button>`
      : `From stored scenario #${e.from} (${esc(e.name)}): Save stores a new scenario.`;
}

const isObject = (v: unknown): boolean => v != null && typeof v === "object" && !Array.isArray(v);

/** The form's scenario over the one it was opened from: what the form does not show is kept;
 *  the intersection (its net and junction), the ego's start and the abnormal traffic are the
 *  form's alone (an empty field: the default). */
const FORMS_ALONE = new Set(["intersection", "ego", "abnormal"]);
function merged(body: Json): Json {
  if (!editing) return body;
  const out: Json = { ...editing.base };
  for (const [k, v] of Object.entries(body)) {
    out[k] = !FORMS_ALONE.has(k) && isObject(v) && isObject(out[k]) ? { ...out[k], ...(v as Json) } : v;
  }
  if (!("approach" in body)) delete out.approach;
  return out;
}

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
    const body = merged(scenarioBody());
    const inPlace = editing?.id != null;
    const s = inPlace
      ? await api(`/api/scenarios/${editing!.id}`, { method: "PUT", body: JSON.stringify(body) })
      : await post("/api/scenarios", body);
    showSaved(s.id, s.name);
    if (editing) setEditing({ id: inPlace ? s.id : null, from: s.id, name: s.name, base: s.spec });
    void refreshLibrary();
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

/** The choices that depend on the network, after the intersection (or junction, approach, task,
 * lane) changed, and the preview. Each depends on the one before: the junctions on the network,
 * the approaches on the junction, the tasks on the approach (those with a candidate path), the
 * lanes on the task. */
async function networkChanged(what: "intersection" | "junction" | "approach" | "task" | "lane"): Promise<void> {
  const source = currentSource();
  if (!source) return;
  $("#intersection-description").textContent = source.description;
  if (what === "intersection" || what === "junction") {
    resetView();
    showPreviewStatus("");
    // what was said of the network's choices no longer holds: they are refilled below
    clearFieldErrors(["intersection", "approach", "task", "ego.entrance_lane"]);
  }
  try {
    if (what === "intersection") fillJunctions(source, await geometryOf(source, ""));
    const geo = await geometryOf(source);
    if (what === "intersection" || what === "junction") fillApproaches(geo);
    if (what !== "task" && what !== "lane") fillTasks(geo);
    if (what === "task") $("#task-hint").textContent = ""; // only tasks with a path can be picked
    if (what !== "lane") fillLanes(geo, field("task").value);
    fillPhases(geo, field("task").value); // the ego's light in each phase depends on all of them
  } catch (e) {
    showErrors(e);
  }
  await drawPreview();
}

/** A click on an entrance lane in the preview: that approach, lane and start distance go into the
 *  form (the task too, when the lane does not lead the one chosen), and the page says what was set. */
async function placeStart(pick: LanePick): Promise<void> {
  const source = currentSource();
  if (!source) return;
  const geo = await geometryOf(source);
  const tasks = tasksOfLane(geo, pick.approach, pick.lane);
  if (!tasks.length) {
    showPreviewStatus(`Lane ${pick.lane} leads ${pick.turns.join(", ") || "nowhere"}, with no candidate path `
      + `from approach ${pick.approach}: nothing set.`);
    return;
  }
  const approach = field("approach");
  if ((approach.value || geo.default_approach) !== pick.approach) approach.value = pick.approach;
  const task = field("task");
  const taskChanged = !tasks.includes(task.value);
  if (taskChanged) task.value = tasks[0];
  fillTasks(geo);
  fillLanes(geo, task.value);
  field("ego.entrance_lane").value = pick.lane;
  field("ego.start_distance_m").value = String(pick.distance);
  fillPhases(geo, task.value);
  forget();
  saveDraft();
  for (const name of ["approach", "ego.entrance_lane", "ego.start_distance_m", ...(taskChanged ? ["task"] : [])]) {
    const el = field(name);
    el.classList.remove("just-set");
    void el.getBoundingClientRect(); // restart the highlight
    el.classList.add("just-set");
  }
  showPreviewStatus(`Set from the click: approach ${pick.approach}, entrance lane ${pick.lane}, start ${pick.distance} m `
    + `before the stop line` + (taskChanged ? `; task ${task.value} (the lane leads ${pick.turns.join(", ")})` : "") + ".");
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
  field("intersection.junction").addEventListener("change", () => void networkChanged("junction"));
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
  $("#run").addEventListener("click", () => {
    if (scenarioId == null) return;
    if (editing?.id === scenarioId) setEditing({ ...editing, id: null }); // run: read-only from now on
    void runBatch(scenarioId, policy()).then(() => refreshLibrary());
  });
  $("#editing").addEventListener("click", (ev) => {
    if ((ev.target as HTMLElement).id === "save-as-new" && editing) setEditing({ ...editing, id: null });
  });
  $("#cancel").addEventListener("click", () => void cancelBatch(Number($("#cancel").dataset.batch)));
  $("#resume").addEventListener("click", () => void resumeBatch(Number($("#resume").dataset.batch)));
  $("#live").addEventListener("click", () => void startLive(scenarioId, policy()));
  $("#live-stop").addEventListener("click", () => void stopLive());
  $("#refresh").addEventListener("click", () => void refreshBatches());
  $("#batches").addEventListener("click", (ev) => {
    const data = (ev.target as HTMLElement).dataset;
    if (data.batch) void showBatch(Number(data.batch)).then(() => loadBatchScenario(Number(data.batch)));
    if (data.cancel) void cancelBatch(Number(data.cancel));
    if (data.resume) void resumeBatch(Number(data.resume));
  });
  $("#batches").addEventListener("change", (ev) => {
    const box = ev.target as HTMLInputElement;
    if (!box.dataset.pick) return;
    if (box.checked) picked.add(Number(box.dataset.pick));
    else picked.delete(Number(box.dataset.pick));
    pickedChanged();
  });
  $("#compare-picked").addEventListener("click", () => void comparePicked());
}

/** Put ``draft`` in the form: the network's choices are filled in steps, each from the draft's
 *  value of the step before. */
async function fillForm(draft: Draft | null): Promise<void> {
  if (draft) applyDraft(draft); // the network's own choices are refilled below, then set again
  await networkChanged("intersection");
  if (!draft) return;
  applyDraft(draft, ["intersection.junction"]);
  await networkChanged("junction");
  applyDraft(draft, ["approach"]);
  await networkChanged("approach");
  applyDraft(draft, ["task"]);
  await networkChanged("task");
  applyDraft(draft);
  const source = currentSource();
  if (source) limitElapsed(await geometryOf(source));
  await drawPreview();
}

/** The form as this tab left it (after a reload), else its defaults. */
async function restoreForm(): Promise<void> {
  await fillForm(loadDraft());
  const saved = JSON.parse(sessionStorage.getItem(SAVED_KEY) ?? "null"); // unedited since its save
  if (saved?.id) showSaved(Number(saved.id), String(saved.name));
  const from = JSON.parse(sessionStorage.getItem(EDITING_KEY) ?? "null");
  if (from?.base) setEditing(from);
}

/** Open a stored scenario in the form (the library's Open, a batch's Show). */
async function openScenario(row: Json, editable: boolean): Promise<void> {
  const key = sourceKeyOf(row.spec.intersection);
  if (!key) throw new Error(`scenario #${row.id} names an intersection this studio does not offer`);
  await fillForm(specToDraft(row.spec, key));
  clearErrors();
  saveDraft();
  setEditing({ id: editable ? row.id : null, from: row.id, name: row.name, base: row.spec });
  showSaved(row.id, row.name);
  sessionStorage.setItem(SAVED_KEY, JSON.stringify({ id: row.id, name: row.name }));
  $("#editor").scrollIntoView({ block: "start" });
}

/** "Show" on a batch: its results, and its scenario in the form. */
async function loadBatchScenario(batchId: number): Promise<void> {
  const b = await api(`/api/batches/${batchId}`);
  await openStored(b.scenario_id);
}

async function init(): Promise<void> {
  const [intersections, uploads, policies] = await Promise.all([
    api("/api/intersections"), api("/api/intersections/uploads"), api("/api/policies")]);
  setSources((intersections as Json[]).map(catalogueSource), (uploads as Json[]).map(uploadSource));
  initPolicyUploads();
  fillPolicies(policies as Json[]);
  wire();
  initPreview((pick) => void placeStart(pick));
  initViewer();
  initLibrary(openScenario);
  initSearches(() => scenarioId, policy);
  await egoDefaults();
  const [, batches] = await Promise.all([restoreForm(), refreshBatches(), refreshLibrary()]);
  await reattach(batches);
}

init().catch((e) => { $("#form-error").textContent = `cannot reach the API: ${e}`; });
