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
const geometries = new Map<string, Json>();
const select = () => $<HTMLSelectElement>("select[name=intersection]");

export const currentSource = (): Source | undefined => sources.get(select().value);

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
  geometries.set(source.key, u);
  select().value = source.key;
  return source;
}

export async function geometryOf(source: Source): Promise<Json> {
  let geo = geometries.get(source.key);
  if (!geo) {
    geo = await api(source.base);
    geometries.set(source.key, geo);
  }
  return geo;
}

export function pathsUrl(source: Source, task: string, approach: string): string {
  const q = new URLSearchParams({ task });
  if (approach) q.set("approach", approach);
  return `${source.base}/paths?${q}`;
}

// --- choices that depend on the network --------------------------------------------------------------

const fieldOf = (name: string) => $<HTMLSelectElement>(`select[name="${name}"]`);

function setOptions(sel: HTMLSelectElement, options: [string, string][], keep = true): void {
  const before = sel.value;
  sel.innerHTML = options.map(([v, label]) => `<option value="${esc(v)}">${esc(label)}</option>`).join("");
  if (keep && options.some(([v]) => v === before)) sel.value = before;
}

/** The approach select: the default (from the south) and every approach of the junction. */
export function fillApproaches(geo: Json): void {
  const byDefault = geo.default_approach ? ` (${geo.default_approach})` : "";
  setOptions(fieldOf("approach"), [["", `from the south${byDefault}`],
    ...(geo.approaches as Json[]).map((a): [string, string] => [a.id, a.id])]);
}

/** The approach the form names, or the junction's default. */
export function chosenApproach(geo: Json): Json | undefined {
  const id = fieldOf("approach").value || geo.default_approach;
  return (geo.approaches as Json[]).find((a) => a.id === id);
}

/** The entrance-lane select: the default, then the lanes of the approach that lead the task. */
export function fillLanes(geo: Json, task: string): void {
  const lanes = (chosenApproach(geo)?.entrance_lanes ?? []) as Json[];
  setOptions(fieldOf("ego.entrance_lane"), [["", "the first candidate path's lane"],
    ...lanes.filter((l) => (l.turns as string[]).includes(task))
      .map((l): [string, string] => [l.id, `${l.id} (${(l.turns as string[]).join(", ")})`])]);
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
