// Live run: one episode of the scenario in the form, driven in the 3D view (in the page) while it runs.
import { $, api, ApiError, esc, Json, messageOf, post, sleep } from "./api";
import { clearErrors, scenarioBody, showErrors } from "./form";
import { showViewer } from "./viewer";

const POLL_MS = 1000;
const FINAL = ["done", "failed", "stopped"];
let current: number | null = null; // the live run the status line follows

function statusText(r: Json): string {
  switch (r.status) {
    case "starting": return "building the world…";
    case "waiting": return "ready, waiting for the 3D view…";
    case "running": return `running (${r.frames} steps drawn)`;
    case "done": {
      const res = r.result ?? {};
      const travel = res.travel_time_s == null ? "" : `, travel time ${res.travel_time_s.toFixed(1)} s`;
      return `${res.outcome} after ${Number(res.time_s ?? 0).toFixed(1)} s${travel}`;
    }
    case "failed": return `failed: ${r.error}`;
    default: return r.status;
  }
}

function show(r: Json): void {
  $("#live-status").innerHTML = `live run #${r.id} (seed ${r.seed}): <span class="live-state" data-status="${esc(r.status)}">${esc(statusText(r))}</span>
    · <a id="live-link" href="${esc(r.url)}" target="_blank" rel="noopener">3D view in a new tab</a>`;
  $<HTMLButtonElement>("#live-stop").hidden = FINAL.includes(r.status);
}

async function poll(id: number): Promise<void> {
  while (current === id) {
    await sleep(POLL_MS);
    if (current !== id) return;
    try {
      const r = await api(`/api/live/${id}`);
      show(r);
      if (FINAL.includes(r.status)) return;
    } catch (e) {
      $("#live-status").textContent = `live run #${id}: ${messageOf(e)}`;
      return;
    }
  }
}

/** Read the run once more when the studio's tab comes back: a background tab's timers (the
 * poll) are throttled while the user watches the 3D view in a tab of its own. */
document.addEventListener("visibilitychange", () => {
  if (document.visibilityState !== "visible" || current == null) return;
  api(`/api/live/${current}`).then(show, () => undefined);
});

/** The request: the saved scenario, or the form's scenario inline (a live run stores nothing). */
function liveBody(scenarioId: number | null, policy: string): Json {
  const body: Json = scenarioId != null ? { scenario_id: scenarioId } : { scenario: scenarioBody() };
  body.policy = policy;
  const seed = $<HTMLInputElement>("#live-seed").value;
  if (seed !== "") body.seed = Number(seed);
  body.speed = Number($<HTMLSelectElement>("#live-speed").value);
  return body;
}

export async function startLive(scenarioId: number | null, policy: string): Promise<void> {
  clearErrors();
  const button = $<HTMLButtonElement>("#live");
  button.disabled = true;
  try {
    const r = await post("/api/live", liveBody(scenarioId, policy));
    current = r.id;
    showViewer(r.url, `Live run #${r.id}: ${r.scenario} (seed ${r.seed})`);
    show(r);
    void poll(r.id);
  } catch (e) {
    if (!(e instanceof ApiError && Array.isArray(e.detail))) {
      $("#live-status").textContent = `live run: ${messageOf(e)}`; // e.g. 429: too many running
    } else if (e.detail.some((d: Json) => ["seed", "speed"].includes(d.loc?.[1]))) {
      showErrors(e, { root: $("#live-panel"), general: $("#live-status") });
    } else {
      showErrors(e, { strip: ["body", "scenario"] }); // the scenario's own fields
    }
  } finally {
    button.disabled = false;
  }
}

export async function stopLive(): Promise<void> {
  if (current == null) return;
  try {
    show(await post(`/api/live/${current}/stop`));
  } catch (e) {
    $("#live-status").textContent = `cannot stop live run #${current}: ${messageOf(e)}`;
  }
}
