// Comparison of the batches the user picks (checkboxes in the batch list): their pass rates with
// Wilson 95 % intervals as a chart, and each pair on the seeds both ran: the paired table, the exact
// McNemar p and the per-seed differences. Also the HTML/CSV report of the picked batches.
import { $, api, esc, Json, messageOf, pct } from "./api";

export const picked = new Set<number>(); // batch ids, kept across the list's redraws

/** Enable the comparison and point the report links at the picked batches. */
export function pickedChanged(): void {
  const ids = [...picked].sort((a, b) => a - b);
  const query = ids.map((id) => `batch=${id}`).join("&");
  $<HTMLButtonElement>("#compare-picked").disabled = ids.length < 2;
  const html = $<HTMLAnchorElement>("#picked-report-html");
  const csv = $<HTMLAnchorElement>("#picked-report-csv");
  $("#picked-reports").hidden = ids.length === 0;
  html.href = `/api/reports?${query}`;
  csv.href = `/api/reports?${query}&format=csv`;
  $("#picked-count").textContent = ids.length ? `${ids.length} picked: #${ids.join(", #")}` : "pick batches to compare them";
}

const W = 640;
const ROW = 30;
const LEFT = 220;

/** Pass rate per batch, a dot with its Wilson 95 % interval as a bar, on 0–100 %. */
function chart(batches: Json[]): string {
  const x = (p: number) => LEFT + p * (W - LEFT - 20);
  const h = 30 + batches.length * ROW;
  const grid = [0, 0.25, 0.5, 0.75, 1].map((p) => `<line class="grid" x1="${x(p)}" x2="${x(p)}" y1="18" y2="${h - 4}"/>
    <text class="tick" x="${x(p)}" y="12" text-anchor="middle">${p * 100} %</text>`).join("");
  const rows = batches.map((b, k) => {
    const y = 30 + k * ROW;
    const label = `<text class="label" x="${LEFT - 8}" y="${y + 4}" text-anchor="end">#${b.id} ${esc(b.policy)} · ${esc(b.scenario).slice(0, 18)}</text>`;
    if (b.pass_rate == null) return `${label}<text class="tick" x="${x(0)}" y="${y + 4}">no judged episodes</text>`;
    return `${label}<line class="interval" x1="${x(b.wilson_low)}" x2="${x(b.wilson_high)}" y1="${y}" y2="${y}"/>
      <line class="interval" x1="${x(b.wilson_low)}" x2="${x(b.wilson_low)}" y1="${y - 6}" y2="${y + 6}"/>
      <line class="interval" x1="${x(b.wilson_high)}" x2="${x(b.wilson_high)}" y1="${y - 6}" y2="${y + 6}"/>
      <circle class="rate" cx="${x(b.pass_rate)}" cy="${y}" r="5"><title>#${b.id}: ${pct(b.pass_rate)} [${pct(b.wilson_low)}, ${pct(b.wilson_high)}], n=${b.judged}</title></circle>`;
  }).join("");
  return `<svg id="compare-chart" class="chart" viewBox="0 0 ${W} ${h}" width="100%" style="max-width:${W}px" role="img"
    aria-label="pass rate with Wilson 95 % interval per batch">${grid}${rows}</svg>`;
}

const secs = (x: number | null | undefined, signed = false): string =>
  x == null ? "–" : `${signed && x > 0 ? "+" : ""}${x.toFixed(2)} s`;

function pairHtml(p: Json, byId: Map<number, Json>): string {
  const a = byId.get(p.a);
  const b = byId.get(p.b);
  const name = (x: Json) => `#${x.id} ${esc(x.policy)} (${esc(x.scenario)})`;
  const seeds = p.seeds.map((s: Json) => `<tr class="${s.difference.replace(/[^a-z]+/g, "-")}"><td>${s.seed}</td>
    <td>${esc(s.a_outcome)}</td><td>${esc(s.b_outcome)}</td><td>${esc(s.difference)}</td>
    <td>${secs(s.a_travel_time_s)}</td><td>${secs(s.b_travel_time_s)}</td><td>${secs(s.travel_time_diff_s, true)}</td></tr>`).join("");
  return `<div class="pair" data-a="${p.a}" data-b="${p.b}">
    <h4>A = ${name(a)} · B = ${name(b)}</h4>
    ${p.pairs ? "" : '<p class="hint warning">No shared seeds (neither errored): nothing to pair. Run both with the same seeds (the same scenario seed and runs).</p>'}
    <table class="paired"><thead><tr><th>Pairs (shared seeds)</th><th>A pass</th><th>B pass</th><th>Both pass</th>
      <th>Only A passes</th><th>Only B passes</th><th>Both fail</th><th>McNemar exact p</th></tr></thead>
      <tbody><tr><td>${p.pairs}</td><td>${pct(p.a_pass_rate)}</td><td>${pct(p.b_pass_rate)}</td><td>${p.both_passed}</td>
      <td>${p.b10}</td><td>${p.b01}</td><td>${p.both_failed}</td><td class="p-value${p.p_value < 0.05 ? " sig" : ""}">${p.p_value.toPrecision(3)}</td></tr></tbody></table>
    <details${p.seeds.length <= 30 ? " open" : ""}><summary>Per seed (${p.seeds.length})</summary>
      <table class="seeds"><thead><tr><th>Seed</th><th>A</th><th>B</th><th>Difference</th><th>A travel time</th><th>B travel time</th><th>B − A</th></tr></thead>
      <tbody>${seeds}</tbody></table></details></div>`;
}

/** Compare the picked batches (two or more) below the batch list. */
export async function comparePicked(): Promise<void> {
  const ids = [...picked].sort((a, b) => a - b);
  const out = $("#picked-compare");
  if (ids.length < 2) return;
  out.innerHTML = '<p class="hint">Comparing…</p>';
  try {
    const c = await api(`/api/reports/comparison?${ids.map((id) => `batch=${id}`).join("&")}`);
    const byId = new Map<number, Json>(c.batches.map((b: Json) => [b.id, b]));
    out.innerHTML = `<h3>Comparison of #${ids.join(", #")}</h3>
      <p class="hint">Dots: pass rate over the judged (not errored) episodes; bars: Wilson 95 % interval. Pairs: the seeds both batches ran,
        tested with the exact two-sided McNemar test (p &lt; 0.05 in bold: the pass rates differ beyond chance).</p>
      ${chart(c.batches)}${c.pairs.map((p: Json) => pairHtml(p, byId)).join("")}`;
  } catch (e) {
    out.innerHTML = `<p class="error">Cannot compare: ${esc(messageOf(e))}</p>`;
  }
}
