// Batches: run one (progress over Server-Sent Events with elapsed time, rate and ETA; cancel; resume
// one the server stopped under), its results and episodes, the list of batches and the comparison.
import { $, api, esc, Json, messageOf, pct, post, secs, sleep } from "./api";
import { picked, pickedChanged } from "./compare";
import { TRAVEL_TIME, showEpisodes } from "./episodes";
import { clearErrors, showErrors } from "./form";

const FINISHED = ["done", "cancelled", "failed"];
const ENDED = [...FINISHED, "interrupted"]; // no runner goes on with these by itself
let following: number | null = null; // the batch whose progress the bar shows
let stream: EventSource | null = null; // its event stream (one at a time: a new follow closes it)
const FOLLOWED_KEY = "crossroads.followed-batch"; // sessionStorage: the batch this tab followed last
const LIST_POLL_MS = 3000; // the batch list is read again this often while a batch is unfinished
let listTimer: number | undefined;

/** A duration for people: "45 s", "3 min 05 s", "2 h 07 min". */
export function duration(seconds: number): string {
  const s = Math.max(0, Math.round(seconds));
  if (s < 60) return `${s} s`;
  if (s < 3600) return `${Math.floor(s / 60)} min ${String(s % 60).padStart(2, "0")} s`;
  return `${Math.floor(s / 3600)} h ${String(Math.floor((s % 3600) / 60)).padStart(2, "0")} min`;
}

/** Elapsed time, rate and ETA of a batch's progress (the API reads them from the store, so they
 *  are the same after a reload or a restart). */
export function timingText(p: Json): string {
  const parts: string[] = [];
  if (p.elapsed_s != null) parts.push(`${duration(p.elapsed_s)} elapsed`);
  if (p.rate_per_min != null) parts.push(`${Number(p.rate_per_min).toFixed(1)} runs/min`);
  if (p.eta_s != null) parts.push(`about ${duration(p.eta_s)} left`);
  else if (p.status === "running" && p.done < p.total) parts.push("ETA after the first run");
  return parts.join(" · ");
}

function progressLine(batchId: number, p: Json): string {
  if (p.status === "queued") {
    const place = p.queue_position ? ` (waiting for a free slot, ${p.queue_position === 1 ? "next" : `#${p.queue_position} in line`})` : "";
    return `batch #${batchId} queued${place}: ${p.done}/${p.total} runs`;
  }
  const timing = timingText(p);
  return `batch #${batchId} ${p.status}: ${p.done}/${p.total} runs, ${p.passed} passed, ${p.errors} errors${timing ? ` — ${timing}` : ""}`;
}

/** The Resume button beside the progress bar: shown for an interrupted batch. */
function showResume(batchId: number | null): void {
  const button = $<HTMLButtonElement>("#resume");
  button.hidden = batchId == null;
  button.disabled = false;
  button.dataset.batch = batchId == null ? "" : String(batchId);
}

/** What the bar says of a batch the server stopped under. */
function interruptedLine(batchId: number, error: string | null | undefined, p: Json | undefined): string {
  const done = p ? `: ${p.done}/${p.total} runs recorded` : "";
  return `batch #${batchId} interrupted${done} — ${error ?? "the server stopped while it ran"}`;
}

function showCancel(batchId: number | null): void {
  const button = $<HTMLButtonElement>("#cancel");
  button.hidden = batchId == null;
  button.disabled = false;
  button.dataset.batch = batchId == null ? "" : String(batchId);
}

/** The warnings of the batch being followed, beside its progress bar, from the 202 answer on: a
 *  network warning is worth seeing before the runs. */
function showProgressWarnings(warnings: string[] | undefined): void {
  const list = $("#progress-warnings");
  const items = warnings ?? [];
  list.hidden = !items.length;
  list.innerHTML = items.map((w) => `<li>Warning: ${esc(w)}</li>`).join("");
}

/** Start a batch of the saved scenario and follow it. */
export async function runBatch(scenarioId: number, policy: string): Promise<void> {
  clearErrors();
  const button = $<HTMLButtonElement>("#run");
  button.disabled = true;
  try {
    const b = await post("/api/batches", { scenario_id: scenarioId, policy, traces: "all" });
    follow(b.id, () => (button.disabled = false));
    showProgressWarnings(b.warnings);
    void refreshBatches();
  } catch (e) {
    showErrors(e);
    button.disabled = false;
  }
}

/** Show a batch's progress until it ends, then its results. */
export function follow(batchId: number, done: () => void): void {
  const bar = $<HTMLProgressElement>("#progress");
  const text = $("#progress-text");
  following = batchId;
  sessionStorage.setItem(FOLLOWED_KEY, String(batchId));
  bar.hidden = false;
  bar.value = 0;
  text.textContent = `batch #${batchId}: starting…`;
  showProgressWarnings([]);
  showCancel(batchId);
  showResume(null);
  delete text.dataset.status;
  stream?.close(); // the batch followed before (e.g. reattached after a reload) runs on unshown
  const source = new EventSource(`/api/batches/${batchId}/events`);
  stream = source;
  source.addEventListener("progress", (ev) => {
    const p = JSON.parse((ev as MessageEvent).data);
    bar.value = p.fraction;
    if ($("#cancel").dataset.state !== "cancelling" || FINISHED.includes(p.status)) text.textContent = progressLine(batchId, p);
  });
  source.addEventListener("end", async (ev) => {
    source.close();
    const e = JSON.parse((ev as MessageEvent).data);
    bar.value = e.status === "done" ? 1 : bar.value;
    text.textContent = `batch #${batchId} ${e.status}`;
    text.dataset.status = e.status;
    finish(batchId, done);
    if (e.status === "interrupted") {
      const b = await api(`/api/batches/${batchId}`);
      text.textContent = interruptedLine(batchId, b.error, b.progress);
      showResume(batchId);
    } else if (e.summary) {
      const b = await api(`/api/batches/${batchId}`);
      const timing = timingText({ ...b.progress, status: b.status });
      if (timing) text.textContent += ` — ${timing}`;
    }
    await showBatch(batchId);
    await refreshBatches();
  });
  source.onerror = () => {
    // The stream closes after `end`; any other error (the server stopped, the network went):
    // look for the batch again every few seconds and follow it once the server answers.
    if (source.readyState === EventSource.CLOSED) return;
    source.close();
    text.textContent = `batch #${batchId}: lost the progress stream; trying again…`;
    finish(batchId, done);
    void reconnect(batchId);
  };
}

const RECONNECT_MS = 2000;

/** After the stream was lost: once the API answers again, follow the batch (still running, or
 *  resumed by a restarted server) or show how it ended (e.g. interrupted, with Resume). */
async function reconnect(batchId: number): Promise<void> {
  while (following === batchId) {
    await sleep(RECONNECT_MS);
    if (following !== batchId) return;
    let b: Json;
    try {
      b = await api(`/api/batches/${batchId}`);
    } catch {
      continue; // not back yet
    }
    if (following !== batchId) return;
    const list = await refreshBatches().catch(() => [b]);
    await reattach(list.some((x: Json) => x.id === batchId) ? list : [b, ...list]);
    return;
  }
}

/** After a reload: follow again the batch this tab followed (or else the newest unfinished one),
 *  from its event stream; a batch that has ended meanwhile is shown finished, with its results. */
export async function reattach(list: Json[], done: () => void = () => undefined): Promise<void> {
  const stored = Number(sessionStorage.getItem(FOLLOWED_KEY));
  let batch: Json | undefined = list.find((b) => b.id === stored);
  if (!batch && stored > 0) batch = await api(`/api/batches/${stored}`).catch(() => undefined);
  const unfinished = list.find((b) => !ENDED.includes(b.status));
  if (!batch || (ENDED.includes(batch.status) && unfinished)) batch = unfinished;
  if (!batch) return;
  if (!ENDED.includes(batch.status)) {
    follow(batch.id, done);
    return;
  }
  const bar = $<HTMLProgressElement>("#progress");
  const text = $("#progress-text");
  bar.hidden = false;
  bar.value = batch.progress.total ? batch.progress.done / batch.progress.total : 1;
  const timing = timingText({ ...batch.progress, status: batch.status });
  text.textContent = batch.status === "interrupted"
    ? interruptedLine(batch.id, batch.error, batch.progress)
    : `batch #${batch.id} ${batch.status}${timing ? ` — ${timing}` : ""}`;
  text.dataset.status = batch.status;
  showCancel(null);
  showResume(batch.status === "interrupted" ? batch.id : null);
  await showBatch(batch.id);
}

/** Go on with an interrupted batch (the runs recorded are kept) and follow it. */
export async function resumeBatch(batchId: number): Promise<void> {
  const button = $<HTMLButtonElement>("#resume");
  button.disabled = true;
  try {
    await post(`/api/batches/${batchId}/resume`);
    follow(batchId, () => undefined);
  } catch (e) {
    $("#progress-text").textContent = `batch #${batchId}: cannot resume: ${messageOf(e)}`;
    button.disabled = false;
  }
  await refreshBatches();
}

function finish(batchId: number, done: () => void): void {
  if (following === batchId) {
    showCancel(null);
    $("#cancel").dataset.state = "";
  }
  done();
}

/** Ask the API to cancel a batch; the progress stream then reports it cancelled. */
export async function cancelBatch(batchId: number): Promise<void> {
  const text = $("#progress-text");
  const button = $<HTMLButtonElement>("#cancel");
  if (following === batchId) {
    button.disabled = true;
    button.dataset.state = "cancelling";
    text.textContent = `batch #${batchId}: cancelling…`;
  }
  try {
    const r = await post(`/api/batches/${batchId}/cancel`);
    if (following === batchId && r.status === "cancelled") text.textContent = `batch #${batchId} cancelled`;
  } catch (e) {
    if (following === batchId) {
      button.disabled = false;
      button.dataset.state = "";
    }
    text.textContent = `batch #${batchId}: cannot cancel: ${messageOf(e)}`;
  }
  await refreshBatches();
}

// --- results ---------------------------------------------------------------------------------------

/** The warnings stored with a batch when it was created (e.g. SUMO's internal lanes off the ego's
 *  paths): the batch ran, so they are said beside its figures, as the upload says them, not as errors. */
function warningsHtml(b: Json): string {
  const warnings: string[] = b.warnings ?? [];
  if (!warnings.length) return "";
  return `<ul id="batch-warnings" class="hint warning">${warnings.map((w) => `<li>Warning: ${esc(w)}</li>`).join("")}</ul>`;
}

function summaryHtml(b: Json): string {
  const s = b.summary;
  if (!s) return `<p>No results yet.</p>${warningsHtml(b)}`;
  const counts = Object.entries(s.outcome_counts as Record<string, number>)
    .map(([k, v]) => `<tr><td>${esc(k)}</td><td>${v}</td></tr>`).join("");
  const tt = s.travel_time_mean_s == null ? "–" : `${s.travel_time_mean_s.toFixed(2)} ± ${(s.travel_time_std_s ?? 0).toFixed(2)} s`;
  return `
    <p>Batch #${b.id}: <b>${esc(b.scenario)}</b> with policy <b>${esc(b.policy)}</b> — <span id="batch-status">${esc(b.status)}</span>
      (${s.recorded}/${b.runs} recorded, ${s.errors} errors)${b.error ? ` <span class="error">${esc(b.error)}</span>` : ""}</p>
    ${warningsHtml(b)}
    <dl class="figures">
      <div><dt>Pass rate</dt><dd id="pass-rate">${pct(s.pass_rate)}</dd></div>
      <div><dt>Wilson 95 %</dt><dd id="wilson">[${pct(s.wilson_low)}, ${pct(s.wilson_high)}]</dd></div>
      <div><dt title="${esc(TRAVEL_TIME)}">Travel time (passed)</dt><dd id="travel-time">${tt}</dd></div>
    </dl>
    <p class="hint" id="travel-time-hint">Travel time: ${esc(TRAVEL_TIME)}.</p>
    <p class="reports">Report of this batch: <a id="report-html" href="/api/reports?batch=${b.id}" target="_blank" rel="noopener">HTML</a>
      · <a id="report-csv" href="/api/reports?batch=${b.id}&amp;format=csv" download="batch${b.id}-report.csv">CSV</a></p>
    <table class="counts"><thead><tr><th>Outcome</th><th>Episodes</th></tr></thead><tbody>${counts}</tbody></table>`;
}

export async function showBatch(batchId: number): Promise<void> {
  const [b, episodes] = await Promise.all([api(`/api/batches/${batchId}`), api(`/api/batches/${batchId}/episodes`)]);
  $("#summary").innerHTML = summaryHtml(b);
  showEpisodes(episodes as Json[], batchId);
}

// --- the list and the comparison -----------------------------------------------------------------------

function batchRow(b: Json): string {
  const status = b.status === "queued" && b.queue_position ? `queued (#${b.queue_position})` : b.status;
  const resume = b.status === "interrupted" ? ` <button type="button" data-resume="${b.id}" title="${esc(b.error ?? "")}">Resume</button>` : "";
  const cancel = FINISHED.includes(b.status) ? "" : `${resume} <button type="button" data-cancel="${b.id}">Cancel</button>`;
  const warnings: string[] = b.warnings ?? [];
  const warned = warnings.length ? ` <span class="hint warning" title="${esc(warnings.join("\n"))}">(warning)</span>` : "";
  const pick = `<input type="checkbox" class="pick" data-pick="${b.id}" aria-label="pick batch #${b.id}"${picked.has(b.id) ? " checked" : ""} />`;
  return `<tr data-id="${b.id}"><td>${pick}</td><td>${b.id}</td><td>${esc(b.scenario)}${warned}</td><td>${esc(b.policy)}</td><td class="status">${esc(status)}</td>
    <td>${b.progress.done}/${b.progress.total}${b.status === "running" && b.progress.eta_s != null ? ` <span class="hint">(~${duration(b.progress.eta_s)} left)</span>` : ""}</td><td><button type="button" data-batch="${b.id}">Show</button>${cancel}</td></tr>`;
}

function compareCell(full: Json[], sid: number, pol: string): string {
  const b = full.find((x) => x.scenario_id === sid && x.policy === pol);
  if (!b?.summary) return "<td>–</td>";
  const s = b.summary;
  return `<td><b>${pct(s.pass_rate)}</b> [${pct(s.wilson_low)}, ${pct(s.wilson_high)}]<br>
    <span class="hint">${s.travel_time_mean_s == null ? "–" : `${s.travel_time_mean_s.toFixed(1)} ± ${(s.travel_time_std_s ?? 0).toFixed(1)} s`}
    · n=${s.judged} · #${b.id}</span></td>`;
}

/** The compare table: the latest finished batch per (scenario, policy). */
async function refreshCompare(list: Json[]): Promise<void> {
  const latest = new Map<string, Json>();
  for (const b of list) {
    if (b.status !== "done") continue;
    const key = `${b.scenario_id}\u0000${b.policy}`;
    if (!latest.has(key)) latest.set(key, b);
  }
  const full = await Promise.all([...latest.values()].map((b) => api(`/api/batches/${b.id}`)));
  if (!full.length) {
    $("#compare").innerHTML = '<p class="hint">No finished batches yet.</p>';
    return;
  }
  const scenarios = [...new Map(full.map((b) => [b.scenario_id, b.scenario])).entries()];
  const policies = [...new Set(full.map((b) => b.policy as string))].sort();
  $("#compare").innerHTML = `<table class="compare"><thead><tr><th>Scenario \\ policy</th>${policies.map((p) => `<th>${esc(p)}</th>`).join("")}</tr></thead>
    <tbody>${scenarios.map(([sid, name]) => `<tr><th>${esc(name)} <span class="hint">#${sid}</span></th>${policies.map((p) => compareCell(full, sid, p)).join("")}</tr>`).join("")}</tbody></table>`;
}

/** The batch list and the comparison; read again every few seconds while a batch in it is
 *  unfinished, so its status, progress and Cancel button keep up. Answers the list. */
export async function refreshBatches(): Promise<Json[]> {
  window.clearTimeout(listTimer);
  const list: Json[] = await api("/api/batches?limit=50");
  if (list.some((b) => !ENDED.includes(b.status))) {
    listTimer = window.setTimeout(() => void refreshBatches().catch(() => undefined), LIST_POLL_MS);
  }
  $("#batches").innerHTML = list.length
    ? `<table><thead><tr><th title="pick for the comparison and the report">Pick</th><th>#</th><th>Scenario</th><th>Policy</th><th>Status</th><th>Progress</th><th></th></tr></thead><tbody>${list.map(batchRow).join("")}</tbody></table>`
    : '<p class="hint">No batches yet.</p>';
  await refreshCompare(list);
  return list;
}
