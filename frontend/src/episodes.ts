// A batch's episodes: a table sortable by any column and filtered by outcome, seed, travel time and
// closest gap; each row opens its 3D playback in the page or downloads its trace.
import { $, esc, Json, secs } from "./api";

export const TRAVEL_TIME = "from the ego crossing its stop line to its leaving the intersection, over the passed runs";
const CLOSEST_CENTRE = "closest distance between the ego's centre and any other road user's centre over the episode "
  + "(centre to centre, not a gap between outlines: a collision can happen at 3–5 m)";
const CLOSEST_GAP = "smallest gap between the ego's outline and that of a road user it was closing in on (0 or less: touching)";
const metres = (x: number | null | undefined): string => (x == null ? "–" : `${x.toFixed(2)} m`);

type Key = "run_index" | "seed" | "outcome" | "travel_time_s" | "min_gap_m" | "min_distance_m";
const COLUMNS: [Key, string, string][] = [
  ["run_index", "Run", ""], ["seed", "Seed", ""], ["outcome", "Outcome", ""],
  ["travel_time_s", "Travel time", TRAVEL_TIME], ["min_gap_m", "Closest gap", CLOSEST_GAP],
  ["min_distance_m", "Closest centre distance", CLOSEST_CENTRE],
];

let episodes: Json[] = [];
let sortKey: Key = "run_index";
let ascending = true;

function row(e: Json): string {
  const trace = `/api/episodes/${e.batch_id}/${e.run_index}/trace`;
  return `
    <tr class="${e.passed ? "passed" : "failed"}" data-run="${e.run_index}">
      <td>${e.run_index}</td><td>${e.seed}</td><td class="outcome">${esc(e.outcome)}</td><td>${secs(e.travel_time_s)}</td>
      <td class="gap">${metres(e.min_gap_m)}</td><td class="centre">${metres(e.min_distance_m)}</td>
      <td title="${esc(e.error_message ?? "")}">${esc(e.detail)}</td>
      <td>${e.has_trace
        ? `<a class="playback" target="_blank" rel="noopener" href="/api/playback/${e.batch_id}/${e.run_index}" data-batch="${e.batch_id}" data-run="${e.run_index}">3D playback</a>
           · <a class="trace" href="${trace}" download="batch${e.batch_id}-run${e.run_index}.trace.json">trace</a>`
        : '<span class="hint">no trace kept</span>'}</td>
    </tr>`;
}

function compare(a: Json, b: Json): number {
  const x = a[sortKey];
  const y = b[sortKey];
  if (x == null && y == null) return a.run_index - b.run_index;
  if (x == null) return 1; // missing values last, whichever the direction
  if (y == null) return -1;
  const order = typeof x === "string" ? String(x).localeCompare(String(y)) : x - y;
  return (ascending ? order : -order) || a.run_index - b.run_index;
}

const numberOf = (id: string): number | null => {
  const v = $<HTMLInputElement>(id).value.trim();
  return v === "" || Number.isNaN(Number(v)) ? null : Number(v);
};

function shown(): Json[] {
  const outcome = $<HTMLSelectElement>("#ep-outcome").value;
  const seed = $<HTMLInputElement>("#ep-seed").value.trim();
  const travelMax = numberOf("#ep-travel-max");
  const gapMax = numberOf("#ep-gap-max");
  return episodes.filter((e) => (!outcome || e.outcome === outcome)
    && (!seed || String(e.seed).includes(seed))
    && (travelMax == null || (e.travel_time_s != null && e.travel_time_s <= travelMax))
    && (gapMax == null || (e.min_gap_m != null && e.min_gap_m <= gapMax))).sort(compare);
}

function redraw(): void {
  const rows = shown();
  $("#episodes tbody").innerHTML = rows.map(row).join("");
  $("#ep-count").textContent = `${rows.length} of ${episodes.length} episodes`;
  for (const th of Array.from(document.querySelectorAll<HTMLElement>("#episodes th[data-sort]"))) {
    th.dataset.dir = th.dataset.sort === sortKey ? (ascending ? "asc" : "desc") : "";
    th.setAttribute("aria-sort", th.dataset.dir === "asc" ? "ascending" : th.dataset.dir === "desc" ? "descending" : "none");
  }
}

let shownBatch: number | null = null; // whose episodes the table holds now
let shows = 0; // how many times episodes were shown: #episodes' data-shown, for who waits on a refresh

function outcomeOptions(list: Json[]): string {
  const outcomes = [...new Set(list.map((e) => e.outcome as string))].sort();
  return `<option value="">all</option>${outcomes.map((o) => `<option>${esc(o)}</option>`).join("")}`;
}

/** Show ``list`` (the episodes of batch ``batchId``) in #episodes, with the filters and sorting.
 *  The same batch shown again (its end, a reload of its results) updates the rows in place: the
 *  header, a click on it, and the filters typed in are kept, not replaced under the user. */
export function showEpisodes(list: Json[], batchId: number | null = null): void {
  episodes = list;
  $("#episodes").dataset.shown = String(++shows);
  if (!list.length) {
    $("#episodes").innerHTML = '<p class="hint">No episodes recorded.</p>';
    shownBatch = null;
    return;
  }
  if (batchId != null && batchId === shownBatch) { // only this function writes #episodes
    const select = $<HTMLSelectElement>("#ep-outcome");
    const chosen = select.value;
    select.innerHTML = outcomeOptions(list);
    select.value = Array.from(select.options).some((o) => o.value === chosen) ? chosen : "";
    redraw();
    return;
  }
  shownBatch = batchId;
  $("#episodes").innerHTML = `
    <div class="actions filters">
      <label>Outcome <select id="ep-outcome">${outcomeOptions(list)}</select></label>
      <label>Seed <input id="ep-seed" inputmode="numeric" placeholder="any" /></label>
      <label>Travel time ≤ [s] <input id="ep-travel-max" type="number" min="0" step="any" placeholder="any" /></label>
      <label>Closest gap ≤ [m] <input id="ep-gap-max" type="number" step="any" placeholder="any" /></label>
      <span id="ep-count" class="hint"></span>
    </div>
    <table class="episodes"><thead><tr>${COLUMNS.map(([key, label, title]) =>
      `<th data-sort="${key}" title="${esc(title ? `${title}; click to sort` : "click to sort")}">${label}</th>`).join("")}<th>Detail</th><th></th></tr></thead>
      <tbody></tbody></table>
    <p class="hint" id="episode-hints">Travel time: ${esc(TRAVEL_TIME)}. Closest gap: ${esc(CLOSEST_GAP)}. Closest centre distance: ${esc(CLOSEST_CENTRE)}.
      Click a column's title to sort by it.</p>`;
  for (const id of ["#ep-outcome", "#ep-seed", "#ep-travel-max", "#ep-gap-max"]) $(id).addEventListener("input", redraw);
  $("#episodes thead").addEventListener("click", (ev) => {
    const key = (ev.target as HTMLElement).closest<HTMLElement>("th[data-sort]")?.dataset.sort as Key | undefined;
    if (!key) return;
    ascending = key === sortKey ? !ascending : true;
    sortKey = key;
    redraw();
  });
  redraw();
}
