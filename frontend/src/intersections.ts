// Where a scenario happens: the catalogue and the uploaded SUMO networks, their geometry, and the
// choices that depend on it (approach, entrance lane, signal phase).
import { $, api, esc, Json } from "./api";

/** One choice of the intersection select: a catalogue name or an uploaded network. */
export interface Source {
  key: string; // the select's value
  label: string;
  description: string;
  base: string; // API path of its geometry; paths at `${base}/paths`
  ref: Json; // what a scenario's `intersection` says
}

const sources = new Map<string, Source>();
const geometries = new Map<string, Json>(); // by `${source key}|${junction id}` ("" for the default)
const select = () => $<HTMLSelectElement>("select[name=intersection]");
const junctionSelect = () => $<HTMLSelectElement>('select[name="intersection.junction"]');
const junctionField = () => $("#junction-field");

export const currentSource = (): Source | undefined => sources.get(select().value);

/** The picked junction's id, or "" for the network's default (a network with one junction, or a
 *  catalogue name: its ``intersection`` names no junction). */
export const chosenJunction = (): string => (junctionField().hidden ? "" : junctionSelect().value);

/** What the scenario's ``intersection`` says: the source's reference, with the picked junction. */
export function sourceRef(source: Source): Json {
  const junction = chosenJunction();
  return junction && typeof source.ref === "object" ? { ...source.ref, junction } : source.ref;
}

/** The select's value for a scenario's ``intersection`` (a catalogue name or ``{net}``), if offered. */
export function sourceKeyOf(ref: Json): string | undefined {
  if (typeof ref === "string") return sources.has(ref) ? ref : undefined;
  for (const s of sources.values()) if (typeof s.ref === "object" && s.ref?.net === ref?.net) return s.key;
  return undefined;
}

export function catalogueSource(i: Json): Source {
  return { key: i.name, label: i.name, description: i.description ?? "", base: `/api/intersections/${encodeURIComponent(i.name)}`, ref: i.name };
}

export function uploadSource(u: Json): Source {
  return {
    key: `upload:${u.id}`, label: `${u.name} (uploaded)`, description: `Uploaded SUMO network ${u.name}`,
    base: `/api/intersections/uploads/${u.id}`, ref: { net: u.net },
  };
}

/** Fill the intersection select: the catalogue, then the uploads in their own group. */
export function setSources(catalogue: Source[], uploads: Source[]): void {
  sources.clear();
  for (const s of [...catalogue, ...uploads]) sources.set(s.key, s);
  const option = (s: Source) => `<option value="${esc(s.key)}">${esc(s.label)}</option>`;
  select().innerHTML = catalogue.map(option).join("")
    + (uploads.length ? `<optgroup label="Uploaded" id="uploaded">${uploads.map(option).join("")}</optgroup>` : "");
}

/** Add (or reselect) an uploaded network and select it; its geometry is known already. */
export function addUpload(u: Json): Source {
  const source = uploadSource(u);
  if (!sources.has(source.key)) {
    sources.set(source.key, source);
    let group = select().querySelector<HTMLOptGroupElement>("#uploaded");
    if (!group) {
      group = document.createElement("optgroup");
      group.label = "Uploaded";
      group.id = "uploaded";
      select().append(group);
    }
    const opt = document.createElement("option");
    opt.value = source.key;
    opt.textContent = source.label;
    group.append(opt);
  }
  remember(source, "", u);
  select().value = source.key;
  return source;
}

/** Keep a geometry under the junction asked for and under its own id (the default's is both). */
function remember(source: Source, junction: string, geo: Json): void {
  geometries.set(`${source.key}|${junction}`, geo);
  if (geo.junction_id) geometries.set(`${source.key}|${geo.junction_id}`, geo);
}

const junctionQuery = (junction: string): string => (junction ? `?${new URLSearchParams({ junction })}` : "");

/** The geometry of the source's picked junction (``junction``: another one, "" the default). */
export async function geometryOf(source: Source, junction: string = chosenJunction()): Promise<Json> {
  let geo = geometries.get(`${source.key}|${junction}`);
  if (!geo) {
    geo = await api(source.base + junctionQuery(junction));
    remember(source, junction, geo);
  }
  return geo;
}

export function pathsUrl(source: Source, task: string, approach: string): string {
  const q = new URLSearchParams({ task });
  if (approach) q.set("approach", approach);
  const junction = chosenJunction();
  if (junction) q.set("junction", junction);
  return `${source.base}/paths?${q}`;
}

/** The junction picker: shown for an uploaded network with more than one signalised junction,
 *  each with its approaches; one the reader cannot use is listed, disabled, with the reason. */
export function fillJunctions(source: Source, geo: Json): void {
  const junctions = (geo.junctions ?? []) as Json[];
  const sel = junctionSelect();
  const before = sel.value;
  const shown = typeof source.ref === "object" && junctions.length > 1;
  junctionField().hidden = !shown;
  sel.innerHTML = junctions.map((j) => {
    const text = j.readable
      ? `${j.id}${j.default ? " (default)" : ""} · ${j.approaches} approaches${j.tl_id !== j.id ? ` · light ${j.tl_id}` : ""}`
      : `${j.id} · cannot be used`;
    return `<option value="${esc(j.id)}"${j.readable ? "" : " disabled"} title="${esc(j.reason ?? "")}">${esc(text)}</option>`;
  }).join("");
  const usable = junctions.filter((j) => j.readable).map((j) => j.id as string);
  sel.value = usable.includes(before) ? before : (junctions.find((j) => j.default)?.id ?? usable[0] ?? "");
  const more = Number(geo.junctions_not_listed ?? 0);
  const unusable = junctions.length - usable.length;
  $("#junction-hint").textContent = !shown ? ""
    : `${usable.length} signalised junction(s)`
      + (unusable ? `; ${unusable} traffic light(s) that are no intersection (hover for why)` : "")
      + (more ? `; ${more} further traffic light(s) not listed` : "");
}

// --- choices that depend on the network --------------------------------------------------------------

const fieldOf = (name: string) => $<HTMLSelectElement>(`select[name="${name}"]`);

function setOptions(sel: HTMLSelectElement, options: [string, string][], keep = true): void {
  const before = sel.value;
  sel.innerHTML = options.map(([v, label]) => `<option value="${esc(v)}">${esc(label)}</option>`).join("");
  if (keep && options.some(([v]) => v === before)) sel.value = before;
}

/** Per approach, the tasks with a candidate path (the API's ``tasks``). */
const tasksOf = (geo: Json, approach: string): string[] => (geo.tasks?.[approach] ?? ["left", "straight", "right"]) as string[];

/** The approach select: the default (from the south) and every approach of the junction; one
 *  without a candidate path for any task is listed disabled. */
export function fillApproaches(geo: Json): void {
  const sel = fieldOf("approach");
  const byDefault = geo.default_approach ? ` (${geo.default_approach})` : "";
  const none = (id: string) => tasksOf(geo, id).length === 0;
  const options: [string, string][] = [["", `from the south${byDefault}`],
    ...(geo.approaches as Json[]).map((a): [string, string] => [a.id, none(a.id) ? `${a.id} (no path)` : a.id])];
  setOptions(sel, options);
  for (const opt of Array.from(sel.options)) opt.disabled = none(opt.value || geo.default_approach);
  if (sel.selectedOptions[0]?.disabled) {
    const first = Array.from(sel.options).find((o) => !o.disabled);
    if (first) sel.value = first.value;
  }
}

/** The approach the form names, or the junction's default. */
export function chosenApproach(geo: Json): Json | undefined {
  const id = fieldOf("approach").value || geo.default_approach;
  return (geo.approaches as Json[]).find((a) => a.id === id);
}

/** The task select offers the tasks the chosen approach has a candidate path for; the others are
 *  listed disabled. When the task chosen has none there, the first that has is chosen and the
 *  hint beside the select says so. */
export function fillTasks(geo: Json): void {
  const sel = fieldOf("task");
  const approach = chosenApproach(geo)?.id ?? "";
  const tasks = tasksOf(geo, approach);
  for (const opt of Array.from(sel.options)) {
    opt.disabled = !tasks.includes(opt.value);
    opt.textContent = opt.disabled ? `${opt.value} (no path from ${approach})` : opt.value;
  }
  const before = sel.value;
  const hint = $("#task-hint");
  if (!tasks.includes(before) && tasks.length) {
    sel.value = tasks[0];
    hint.textContent = `No ${before} path from approach ${approach}: task set to ${tasks[0]}.`;
  } else {
    hint.textContent = tasks.length ? "" : `No path from approach ${approach}.`;
  }
}

/** The entrance-lane select: the default, then the lanes of the approach that lead the task. */
export function fillLanes(geo: Json, task: string): void {
  const lanes = (chosenApproach(geo)?.entrance_lanes ?? []) as Json[];
  setOptions(fieldOf("ego.entrance_lane"), [["", "the first candidate path's lane"],
    ...lanes.filter((l) => (l.turns as string[]).includes(task))
      .map((l): [string, string] => [l.id, `${l.id} (${(l.turns as string[]).join(", ")})`])]);
}

/** The tasks lane ``lane`` of ``approach`` leads that have a candidate path from there. */
export function tasksOfLane(geo: Json, approach: string, lane: string): string[] {
  const a = (geo.approaches as Json[]).find((x) => x.id === approach);
  const turns = ((a?.entrance_lanes as Json[] | undefined)?.find((l) => l.id === lane)?.turns ?? []) as string[];
  return turns.filter((t) => tasksOf(geo, approach).includes(t));
}

const LIGHTS: Record<string, string> = { G: "green", g: "green", y: "yellow", Y: "yellow", u: "yellow", r: "red", R: "red", s: "red" };

/** The ego's link in the signal program: its lane's connection for the task, else any of the
 * approach's (as the world picks it); the default lane is the first that leads the task. */
function egoLink(geo: Json, task: string): number | undefined {
  const approach = chosenApproach(geo);
  if (!approach) return undefined;
  const links = ((geo.signal_links?.[approach.id] ?? []) as Json[]).filter((l) => l.turn === task);
  const lane = fieldOf("ego.entrance_lane").value
    || (approach.entrance_lanes as Json[]).find((l) => (l.turns as string[]).includes(task))?.id;
  return (links.find((l) => l.lane === lane) ?? links[0])?.link;
}

/** The phase select from the signal program, each phase with its duration and the ego's light
 * in it; the elapsed field's upper bound follows the chosen phase. */
export function fillPhases(geo: Json, task: string): void {
  const phases = (geo.program?.phases ?? []) as Json[];
  const link = egoLink(geo, task);
  const light = (p: Json) => (link == null ? "" : ` · ego ${LIGHTS[p.state[link]] ?? "off"}`);
  const options: [string, string][] = phases.length
    ? phases.map((p, i): [string, string] => [String(i), `${i}: ${p.duration_s} s${light(p)}`])
    : [...Array(4).keys()].map((i): [string, string] => [String(i), String(i)]);
  setOptions(fieldOf("lights.phase"), options);
  limitElapsed(geo);
}

export function limitElapsed(geo: Json): void {
  const phase = geo.program?.phases?.[Number(fieldOf("lights.phase").value)];
  const elapsed = $<HTMLInputElement>('input[name="lights.elapsed_s"]');
  elapsed.max = phase ? String(phase.duration_s) : "";
  $("#phase-hint").textContent = phase ? `of ${phase.duration_s} s in this phase` : "";
}
