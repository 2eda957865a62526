// Crossroads studio: the scenario editor, batch runner and results browser (plain TypeScript).
import "./style.css";

type Json = any; // eslint-disable-line @typescript-eslint/no-explicit-any

const $ = <T extends Element = HTMLElement>(sel: string): T => {
  const el = document.querySelector<T>(sel);
  if (!el) throw new Error(`missing element ${sel}`);
  return el;
};
const form = $<HTMLFormElement>("#scenario-form");
const field = (name: string) => form.elements.namedItem(name) as HTMLInputElement | HTMLSelectElement;

class ApiError extends Error {
  constructor(public status: number, public detail: Json) {
    super(typeof detail === "string" ? detail : `HTTP ${status}`);
  }
}

async function api(path: string, init?: RequestInit): Promise<Json> {
  const res = await fetch(path, {
    ...init,
    headers: init?.body ? { "Content-Type": "application/json" } : undefined,
  });
  const text = await res.text();
  const body = text ? JSON.parse(text) : null;
  if (!res.ok) throw new ApiError(res.status, body?.detail ?? body);
  return body;
}

const esc = (s: unknown) =>
  String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]!);
const pct = (x: number | null | undefined) => (x == null ? "–" : `${(100 * x).toFixed(1)} %`);
const secs = (x: number | null | undefined) => (x == null ? "–" : `${x.toFixed(2)} s`);

// --- preview -------------------------------------------------------------------------------------

const SVG = "http://www.w3.org/2000/svg";
const PATH_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];

function svgEl(tag: string, attrs: Record<string, string | number>): SVGElement {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  return el;
}
const pts = (xy: number[][]) => xy.map((p) => `${p[0]},${-p[1]}`).join(" "); // SVG y points down

let geometryCache: Record<string, Json> = {};

async function drawPreview(): Promise<void> {
  const svg = $<SVGSVGElement>("#preview");
  const name = field("intersection").value;
  const task = field("task").value;
  if (!name) return;
  try {
    const geo = geometryCache[name] ?? (geometryCache[name] = await api(`/api/intersections/${encodeURIComponent(name)}`));
    let paths: Json[] = [];
    let pathError = "";
    try {
      paths = await api(`/api/intersections/${encodeURIComponent(name)}/paths?task=${task}`);
    } catch (e) {
      pathError = e instanceof ApiError ? String(e.detail) : String(e);
    }
    svg.replaceChildren();
    const [cx, cy] = geo.center;
    const r = 45;
    svg.setAttribute("viewBox", `${cx - r} ${-cy - r} ${2 * r} ${2 * r}`);
    svg.append(svgEl("rect", { x: cx - r, y: -cy - r, width: 2 * r, height: 2 * r, fill: "#dfe8d8" }));
    const lane = (l: Json, colour: string) =>
      svg.append(svgEl("polyline", { points: pts(l.centerline), stroke: colour, "stroke-width": l.width_m, fill: "none" }));
    for (const s of geo.sidewalks ?? []) lane(s, "#c8c8c8");
    for (const s of geo.bike_lanes ?? []) lane(s, "#b07a7a");
    for (const a of geo.approaches) {
      for (const l of [...a.entrance_lanes, ...a.exit_lanes]) lane(l, "#6b6b6b");
      for (const ring of a.median ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#7bb06a" }));
    }
    for (const ring of geo.walking_areas ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#c8c8c8" }));
    for (const ring of geo.polygon ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#6b6b6b" }));
    for (const a of geo.approaches) {
      for (const l of a.entrance_lanes) {
        svg.append(svgEl("polyline", { points: pts(l.centerline), stroke: "#fff", "stroke-width": 0.15, "stroke-dasharray": "3 3", fill: "none" }));
      }
      if (a.stop_line?.length) svg.append(svgEl("polyline", { points: pts(a.stop_line), stroke: "#d62728", "stroke-width": 0.5, fill: "none" }));
    }
    for (const c of geo.crossings ?? []) {
      svg.append(svgEl("polyline", { points: pts(c.centerline), stroke: "#fff", "stroke-width": c.width_m, "stroke-dasharray": "0.5 0.5", fill: "none", opacity: 0.8 }));
    }
    paths.forEach((p, i) => {
      const colour = PATH_COLOURS[i % PATH_COLOURS.length];
      const line = svgEl("polyline", { points: pts(p.points), stroke: colour, "stroke-width": 0.6, fill: "none", "class": "candidate" });
      const title = svgEl("title", {});
      title.textContent = `${p.id}: ${p.entrance_lane} → ${p.exit_lane}`;
      line.append(title);
      svg.append(line);
      const end = p.points[p.points.length - 1];
      svg.append(svgEl("circle", { cx: end[0], cy: -end[1], r: 0.9, fill: colour }));
    });
    const caption = svgEl("text", { x: cx - r + 2, y: -cy - r + 5, "font-size": 3.5, fill: "#222" });
    caption.textContent = pathError ? `no ${task} path: ${pathError}` : `${name} · ${task}: ${paths.length} candidate path(s)`;
    svg.append(caption);
  } catch (e) {
    svg.replaceChildren();
    const t = svgEl("text", { x: -55, y: 0, "font-size": 4, fill: "#b00" });
    t.textContent = `cannot draw ${name}: ${e}`;
    svg.append(t);
  }
}

// --- the form --------------------------------------------------------------------------------------

const num = (name: string) => Number(field(name).value);

function scenarioBody(): Json {
  const abnormal: Json = {};
  if ((field("overspeed.on") as HTMLInputElement).checked) {
    abnormal.overspeed = { share: num("abnormal.overspeed.share"), excess: num("abnormal.overspeed.excess") / 100 };
  }
  if ((field("rounding.on") as HTMLInputElement).checked) {
    abnormal.rounding = { share: num("abnormal.rounding.share") };
  }
  const intOrRaw = (name: string) => {
    const v = field(name).value;
    return /^-?\d+$/.test(v) ? Number(v) : v === "" ? null : Number(v); // 2.5 stays 2.5: the API names it
  };
  return {
    version: 1,
    name: field("name").value,
    intersection: field("intersection").value,
    task: field("task").value,
    lights: { phase: intOrRaw("lights.phase"), elapsed_s: num("lights.elapsed_s") },
    traffic: {
      vehicles_per_hour: num("traffic.vehicles_per_hour"),
      cyclists_per_hour: num("traffic.cyclists_per_hour"),
      pedestrians_per_hour: num("traffic.pedestrians_per_hour"),
    },
    abnormal,
    runs: intOrRaw("runs"),
    seed: intOrRaw("seed"),
    warmup_s: num("warmup_s"),
    timeout_s: num("timeout_s"),
  };
}

function clearErrors(): void {
  form.querySelectorAll(".field-error").forEach((e) => e.remove());
  form.querySelectorAll(".invalid").forEach((e) => e.classList.remove("invalid"));
  $("#form-error").textContent = "";
}

function showErrors(err: unknown): void {
  const general: string[] = [];
  if (err instanceof ApiError && Array.isArray(err.detail)) {
    for (const d of err.detail) {
      const loc: string = (d.loc ?? []).filter((p: unknown) => p !== "body").join(".");
      const target = form.querySelector<HTMLElement>(`[data-field="${CSS.escape(loc)}"]`)
        ?? form.querySelector<HTMLElement>(`[data-field^="${CSS.escape(loc)}."]`);
      if (target) {
        target.classList.add("invalid");
        const msg = document.createElement("span");
        msg.className = "field-error";
        msg.dataset.for = loc;
        msg.textContent = d.msg;
        target.closest("label")?.append(msg);
      } else {
        general.push(`${loc || "scenario"}: ${d.msg}`);
      }
    }
  } else {
    general.push(err instanceof ApiError ? String(err.detail) : String(err));
  }
  $("#form-error").textContent = general.join("; ");
}

let scenarioId: number | null = null;

async function save(ev: Event): Promise<void> {
  ev.preventDefault();
  clearErrors();
  try {
    const s = await api("/api/scenarios", { method: "POST", body: JSON.stringify(scenarioBody()) });
    scenarioId = s.id;
    $("#saved").textContent = `Saved as scenario #${s.id} (${s.name})`;
    $<HTMLButtonElement>("#run").disabled = false;
  } catch (e) {
    scenarioId = null;
    $("#saved").textContent = "";
    $<HTMLButtonElement>("#run").disabled = true;
    showErrors(e);
  }
}

// --- batches ---------------------------------------------------------------------------------------

async function runBatch(): Promise<void> {
  if (scenarioId == null) return;
  clearErrors();
  const button = $<HTMLButtonElement>("#run");
  button.disabled = true;
  try {
    const b = await api("/api/batches", {
      method: "POST",
      body: JSON.stringify({ scenario_id: scenarioId, policy: $<HTMLSelectElement>("#policy").value, traces: "all" }),
    });
    follow(b.id, () => (button.disabled = false));
  } catch (e) {
    showErrors(e);
    button.disabled = false;
  }
}

function follow(batchId: number, done: () => void): void {
  const bar = $<HTMLProgressElement>("#progress");
  const text = $("#progress-text");
  bar.hidden = false;
  bar.value = 0;
  text.textContent = `batch #${batchId}: starting…`;
  const source = new EventSource(`/api/batches/${batchId}/events`);
  source.addEventListener("progress", (ev) => {
    const p = JSON.parse((ev as MessageEvent).data);
    bar.value = p.fraction;
    text.textContent = `batch #${batchId} ${p.status}: ${p.done}/${p.total} runs, ${p.passed} passed, ${p.errors} errors`;
  });
  source.addEventListener("end", async (ev) => {
    source.close();
    const e = JSON.parse((ev as MessageEvent).data);
    bar.value = 1;
    text.textContent = `batch #${batchId} ${e.status}`;
    done();
    await showBatch(batchId);
    await refreshBatches();
  });
  source.onerror = () => {
    // The stream closes after `end`; any other error: fall back to reading the batch once.
    if (source.readyState === EventSource.CLOSED) return;
    source.close();
    text.textContent = `batch #${batchId}: lost the progress stream`;
    done();
    void showBatch(batchId);
  };
}

function summaryHtml(b: Json): string {
  const s = b.summary;
  if (!s) return "<p>No results yet.</p>";
  const counts = Object.entries(s.outcome_counts as Record<string, number>)
    .map(([k, v]) => `<tr><td>${esc(k)}</td><td>${v}</td></tr>`).join("");
  const tt = s.travel_time_mean_s == null ? "–" : `${s.travel_time_mean_s.toFixed(2)} ± ${(s.travel_time_std_s ?? 0).toFixed(2)} s`;
  return `
    <p>Batch #${b.id}: <b>${esc(b.scenario)}</b> with policy <b>${esc(b.policy)}</b> — ${esc(b.status)}
      (${s.recorded}/${b.runs} recorded, ${s.errors} errors)${b.error ? ` <span class="error">${esc(b.error)}</span>` : ""}</p>
    <dl class="figures">
      <div><dt>Pass rate</dt><dd id="pass-rate">${pct(s.pass_rate)}</dd></div>
      <div><dt>Wilson 95 %</dt><dd id="wilson">[${pct(s.wilson_low)}, ${pct(s.wilson_high)}]</dd></div>
      <div><dt>Travel time (passed)</dt><dd id="travel-time">${tt}</dd></div>
    </dl>
    <table class="counts"><thead><tr><th>Outcome</th><th>Episodes</th></tr></thead><tbody>${counts}</tbody></table>`;
}

async function showBatch(batchId: number): Promise<void> {
  const [b, episodes] = await Promise.all([api(`/api/batches/${batchId}`), api(`/api/batches/${batchId}/episodes`)]);
  $("#summary").innerHTML = summaryHtml(b);
  const rows = (episodes as Json[]).map((e) => `
    <tr class="${e.passed ? "passed" : "failed"}">
      <td>${e.run_index}</td><td>${e.seed}</td><td>${esc(e.outcome)}</td><td>${secs(e.travel_time_s)}</td>
      <td>${e.min_distance_m == null ? "–" : e.min_distance_m.toFixed(2) + " m"}</td>
      <td title="${esc(e.error_message ?? "")}">${esc(e.detail)}</td>
      <td>${e.has_trace
        ? `<a class="playback" target="_blank" rel="noopener" href="/api/playback/${e.batch_id}/${e.run_index}">3D playback</a>`
        : '<span class="hint">no trace kept</span>'}</td>
    </tr>`).join("");
  $("#episodes").innerHTML = episodes.length
    ? `<table><thead><tr><th>Run</th><th>Seed</th><th>Outcome</th><th>Travel time</th><th>Min. distance</th><th>Detail</th><th></th></tr></thead><tbody>${rows}</tbody></table>`
    : '<p class="hint">No episodes recorded.</p>';
}

async function refreshBatches(): Promise<void> {
  const list: Json[] = await api("/api/batches?limit=50");
  $("#batches").innerHTML = list.length
    ? `<table><thead><tr><th>#</th><th>Scenario</th><th>Policy</th><th>Status</th><th>Progress</th><th></th></tr></thead><tbody>${list.map((b) => `
        <tr><td>${b.id}</td><td>${esc(b.scenario)}</td><td>${esc(b.policy)}</td><td>${esc(b.status)}</td>
          <td>${b.progress.done}/${b.progress.total}</td><td><button type="button" data-batch="${b.id}">Show</button></td></tr>`).join("")}</tbody></table>`
    : '<p class="hint">No batches yet.</p>';
  // The compare table: the latest finished batch per (scenario, policy).
  const latest = new Map<string, Json>();
  for (const b of list) {
    if (b.status !== "done") continue;
    const key = `${b.scenario_id}\u0000${b.policy}`;
    if (!latest.has(key)) latest.set(key, b);
  }
  const full = await Promise.all([...latest.values()].map((b) => api(`/api/batches/${b.id}`)));
  const scenarios = [...new Map(full.map((b) => [b.scenario_id, b.scenario])).entries()];
  const policies = [...new Set(full.map((b) => b.policy as string))].sort();
  if (!full.length) {
    $("#compare").innerHTML = '<p class="hint">No finished batches yet.</p>';
    return;
  }
  const cell = (sid: number, pol: string) => {
    const b = full.find((x) => x.scenario_id === sid && x.policy === pol);
    if (!b?.summary) return "<td>–</td>";
    const s = b.summary;
    return `<td><b>${pct(s.pass_rate)}</b> [${pct(s.wilson_low)}, ${pct(s.wilson_high)}]<br>
      <span class="hint">${s.travel_time_mean_s == null ? "–" : `${s.travel_time_mean_s.toFixed(1)} ± ${(s.travel_time_std_s ?? 0).toFixed(1)} s`}
      · n=${s.judged} · #${b.id}</span></td>`;
  };
  $("#compare").innerHTML = `<table class="compare"><thead><tr><th>Scenario \\ policy</th>${policies.map((p) => `<th>${esc(p)}</th>`).join("")}</tr></thead>
    <tbody>${scenarios.map(([sid, name]) => `<tr><th>${esc(name)} <span class="hint">#${sid}</span></th>${policies.map((p) => cell(sid, p)).join("")}</tr>`).join("")}</tbody></table>`;
}

// --- start -------------------------------------------------------------------------------------------

async function init(): Promise<void> {
  const [intersections, policies] = await Promise.all([api("/api/intersections"), api("/api/policies")]);
  const select = field("intersection") as HTMLSelectElement;
  select.innerHTML = (intersections as Json[]).map((i) => `<option value="${esc(i.name)}">${esc(i.name)}</option>`).join("");
  const describe = () => {
    const i = (intersections as Json[]).find((x) => x.name === select.value);
    $("#intersection-description").textContent = i?.description ?? "";
  };
  $<HTMLSelectElement>("#policy").innerHTML = (policies as Json[])
    .map((p) => `<option value="${esc(p.name)}">${esc(p.name)}${p.kind === "checkpoint" ? " (checkpoint)" : ""}</option>`).join("");
  select.addEventListener("change", () => { describe(); void drawPreview(); });
  field("task").addEventListener("change", () => void drawPreview());
  const edited = (ev: Event) => { // a changed scenario must be saved again before it runs
    if ((ev.target as HTMLElement).id === "policy") return;
    scenarioId = null;
    $<HTMLButtonElement>("#run").disabled = true;
    $("#saved").textContent = "";
  };
  form.addEventListener("input", edited);
  form.addEventListener("change", edited);
  form.addEventListener("submit", (ev) => void save(ev));
  $("#run").addEventListener("click", () => void runBatch());
  $("#refresh").addEventListener("click", () => void refreshBatches());
  $("#batches").addEventListener("click", (ev) => {
    const id = (ev.target as HTMLElement).dataset.batch;
    if (id) void showBatch(Number(id));
  });
  describe();
  await Promise.all([drawPreview(), refreshBatches()]);
}

init().catch((e) => { $("#form-error").textContent = `cannot reach the API: ${e}`; });
