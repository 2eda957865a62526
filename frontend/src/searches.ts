// Failure search: start a search of the saved scenario's neighbourhood for the policy's failures,
// follow it (failures so far, best objective), and browse the failures it kept (parameters,
// distance from nominal, 3D playback, the scenario file, "save as regression scenario").
import { $, api, ApiError, esc, Json, messageOf, post, sleep } from "./api";
import { duration } from "./batches";

let current: number | null = null; // the search the panel follows

/** The parameters the panel offers, each with the range the form starts with (``off``: not ticked
 *  at first; ticking a timed over-speeder's field adds one to a scenario that has none). */
const PARAMETERS: { path: string; label: string; low?: number; high?: number; choices?: string; off?: boolean }[] = [
  { path: "abnormal.overspeed.share", label: "Over-speeding share", low: 0, high: 0.5 },
  { path: "abnormal.overspeed.excess", label: "Over-speeding excess", low: 0, high: 0.5 },
  { path: "abnormal.rounding.share", label: "Rounding share", low: 0, high: 0.5 },
  { path: "traffic.vehicles_per_hour", label: "Vehicles [1/h]", low: 200, high: 800 },
  { path: "traffic.cyclists_per_hour", label: "Cyclists [1/h]", low: 0, high: 300 },
  { path: "traffic.pedestrians_per_hour", label: "Pedestrians [1/h]", low: 0, high: 300 },
  { path: "lights.phase", label: "Light phase (choices)", choices: "0, 1, 4" },
  { path: "lights.elapsed_s", label: "Time in the phase [s]", low: 0, high: 9.5 },
  { path: "ego.start_distance_m", label: "Start distance [m]", low: 25, high: 60 },
  { path: "ego.start_speed_mps", label: "Start speed [m/s]", low: 0, high: 10 },
  { path: "abnormal.injection.arrive_s", label: "Over-speeder due at the line [s]", low: 0, high: 20, off: true },
  { path: "abnormal.injection.excess", label: "Over-speeder excess", low: 0, high: 0.5, off: true },
];

function parameterRows(): string {
  return PARAMETERS.map((p, i) => `<tr>
    <td><label class="check"><input type="checkbox" data-param="${i}" ${p.off ? "" : "checked"} /> ${esc(p.label)}</label></td>
    ${p.choices != null
      ? `<td colspan="2"><input data-choices="${i}" value="${esc(p.choices)}" aria-label="${esc(p.label)} choices" /></td>`
      : `<td><input type="number" step="any" data-low="${i}" value="${p.low}" aria-label="${esc(p.label)} low" /></td>
         <td><input type="number" step="any" data-high="${i}" value="${p.high}" aria-label="${esc(p.label)} high" /></td>`}
  </tr>`).join("");
}

function spaceParameters(): Json[] {
  const out: Json[] = [];
  PARAMETERS.forEach((p, i) => {
    if (!$<HTMLInputElement>(`[data-param="${i}"]`).checked) return;
    if (p.choices != null) {
      const text = $<HTMLInputElement>(`[data-choices="${i}"]`).value;
      out.push({ path: p.path, choices: text.split(",").map((s) => Number(s.trim())) });
    } else {
      out.push({ path: p.path, low: Number($<HTMLInputElement>(`[data-low="${i}"]`).value),
        high: Number($<HTMLInputElement>(`[data-high="${i}"]`).value) });
    }
  });
  return out;
}

/** The space's seed field: a pool of that many seeds to search among, or none (0: a seed per episode). */
function seedPool(): Json {
  const pool = Number($<HTMLInputElement>("#search-seed-pool").value);
  return pool > 0 ? { seed: { pool } } : {};
}

/** A refused search's problems, each with the field it names ("space.seed.pool: ..."). */
function withFields(e: unknown): string {
  if (!(e instanceof ApiError) || !Array.isArray(e.detail)) return messageOf(e);
  return e.detail.map((d: Json) => {
    const loc = (d.loc ?? []).filter((part: unknown) => part !== "body").join(".");
    return loc ? `${loc}: ${d.msg}` : d.msg;
  }).join("; ");
}

function status(text: string, error = false): void {
  const line = $("#search-status");
  line.textContent = text;
  line.classList.toggle("error", error);
}

/** Elapsed time since the search (re)started, its rate and the ETA of its search phase. */
function searchTiming(p: Json): string {
  const parts: string[] = [];
  if (p.elapsed_s != null) parts.push(`${duration(p.elapsed_s)} elapsed`);
  if (p.rate_per_min != null) parts.push(`${Number(p.rate_per_min).toFixed(1)} episodes/min`);
  if (p.eta_s != null) parts.push(`search phase: about ${duration(p.eta_s)} left`);
  return parts.length ? ` — ${parts.join(" · ")}` : "";
}

function progressText(s: Json): string {
  const p = s.progress;
  const best = s.best_objective == null ? "–" : Number(s.best_objective).toFixed(3);
  if (p) {
    const shrink = p.phase === "shrink" ? `, shrinking ${p.failures}/${p.to_shrink} (${p.shrink_episodes} episodes)` : "";
    return `search #${s.search_id} ${p.phase}: ${p.searched}/${p.budget} episodes, ${p.failing} failing, `
      + `best objective ${p.best_objective == null ? "–" : Number(p.best_objective).toFixed(3)}${shrink}${searchTiming(p)}`;
  }
  return `search #${s.search_id} ${s.state ?? s.status}: ${s.searched}/${s.budget} episodes, ${s.failing} failing, `
    + `${s.failures} failures kept (${s.distinct_failures} distinct), best objective ${best}`
    + (s.error ? ` — ${s.error}` : s.state === "interrupted" ? " — the server stopped while it ran; resume it" : "");
}

async function showFailures(searchId: number): Promise<void> {
  const failures: Json[] = await api(`/api/searches/${searchId}/failures`);
  const rows = failures.map((f) => {
    const moved = f.off_nominal.map((k: string) => `${esc(k)} = ${esc(Number(f.params[k]).toPrecision(4))}`).join("<br>") || "nominal";
    return `<tr class="failed"><td>${esc(f.name)}</td><td>${esc(f.seed)}</td><td>${esc(f.outcome)}</td>
      <td>${Number(f.distance).toFixed(3)}</td><td>${moved}</td>
      <td>${f.playback ? `<a class="playback" target="_blank" rel="noopener" href="${esc(f.playback)}" data-batch="${esc(f.batch_id ?? String(f.playback).split("/")[3])}" data-run="0">3D playback</a>` : "–"}
        · <a href="/api/searches/${searchId}/failures/${f.id}/scenario.yaml">scenario file</a>
        · <button type="button" data-save="${f.id}">Save as regression scenario</button></td></tr>`;
  }).join("");
  $("#search-failures").innerHTML = failures.length
    ? `<table><tr><th>Scenario</th><th>Seed</th><th>Outcome</th><th>Distance from nominal</th><th>Still off nominal</th><th></th></tr>${rows}</table>
       <p><a target="_blank" rel="noopener" href="/api/searches/${searchId}/report">Report: outcome against each parameter</a></p>`
    : `<p class="hint">No failures kept (yet).</p>`;
}

async function follow(searchId: number): Promise<void> {
  current = searchId;
  $<HTMLButtonElement>("#search-cancel").hidden = false;
  $<HTMLButtonElement>("#search-resume").hidden = true;
  let shown = -1;
  while (current === searchId) {
    let s: Json;
    try {
      s = await api(`/api/searches/${searchId}`);
    } catch (e) {
      status(messageOf(e), true);
      break;
    }
    status(progressText(s));
    $("#search-status").dataset.state = s.state ?? s.status;
    const kept = s.progress ? s.progress.failures : s.failures;
    if (kept !== shown) {
      shown = kept;
      await showFailures(searchId);
    }
    if (!s.progress && s.state !== "running") {
      // ended, or stopped under by the server: a cancelled or interrupted one can go on
      const resume = $<HTMLButtonElement>("#search-resume");
      resume.hidden = !(s.state === "interrupted" || s.state === "cancelled");
      resume.disabled = false;
      resume.dataset.search = String(searchId);
      break;
    }
    await sleep(1000);
  }
  $<HTMLButtonElement>("#search-cancel").hidden = true;
  $<HTMLButtonElement>("#search-start").disabled = false;
}

async function resume(searchId: number): Promise<void> {
  const button = $<HTMLButtonElement>("#search-resume");
  button.disabled = true;
  try {
    await post(`/api/searches/${searchId}/resume`);
    void follow(searchId);
  } catch (e) {
    status(messageOf(e), true);
    button.disabled = false;
  }
}

async function start(scenarioId: number | null, policy: string): Promise<void> {
  if (scenarioId == null) {
    status("Save the scenario first: the search starts from the saved one.", true);
    return;
  }
  const button = $<HTMLButtonElement>("#search-start");
  button.disabled = true;
  try {
    const s = await post("/api/searches", {
      policy, scenario_id: scenarioId, budget: Number($<HTMLInputElement>("#search-budget").value),
      sampler: $<HTMLSelectElement>("#search-sampler").value,
      space: { version: 1, name: "studio", parameters: spaceParameters(), ...seedPool() },
    });
    void follow(s.id);
  } catch (e) {
    status(withFields(e), true);
    button.disabled = false;
  }
}

/** Put the panel's parameter table in place and wire its buttons. */
export function initSearches(scenarioId: () => number | null, policy: () => string): void {
  $("#search-parameters").innerHTML = `<tr><th>Parameter</th><th>Low</th><th>High</th></tr>${parameterRows()}`;
  $("#search-start").addEventListener("click", () => void start(scenarioId(), policy()));
  $("#search-resume").addEventListener("click", () => void resume(Number($("#search-resume").dataset.search)));
  $("#search-cancel").addEventListener("click", async () => {
    if (current != null) await post(`/api/searches/${current}/cancel`).catch((e) => status(messageOf(e), true));
  });
  $("#search-failures").addEventListener("click", async (ev) => {
    const id = (ev.target as HTMLElement).dataset.save;
    if (!id || current == null) return;
    const saved = await post(`/api/searches/${current}/failures/${id}/save`);
    (ev.target as HTMLButtonElement).replaceWith(document.createTextNode(`saved as scenario #${saved.scenario_id}`));
  });
  api("/api/searches").then((list: Json[]) => {
    if (list.length) void follow(list[0].search_id);
  }, () => undefined);
}
