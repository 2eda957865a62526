// The scenario form: its fields, the scenario it describes, and errors shown next to their fields.
import { $, ApiError, Json } from "./api";
import { currentSource, sourceRef } from "./intersections";

export const form = $<HTMLFormElement>("#scenario-form");
export const field = (name: string) => form.elements.namedItem(name) as HTMLInputElement | HTMLSelectElement;
export const num = (name: string): number => Number(field(name).value);
/** A number field's value, or its placeholder (the default) when empty. */
export const numOrDefault = (name: string): number => {
  const el = field(name) as HTMLInputElement;
  return Number(el.value !== "" ? el.value : el.placeholder);
};
export const checked = (name: string): boolean => (field(name) as HTMLInputElement).checked;

/** An integer field as a number; a fraction stays a fraction (the API names it), empty is null. */
function intOrRaw(name: string): number | null {
  const v = field(name).value;
  return v === "" ? null : Number(v);
}

export function scenarioBody(): Json {
  const abnormal: Json = {};
  if (checked("overspeed.on")) {
    abnormal.overspeed = { share: num("abnormal.overspeed.share"), excess: num("abnormal.overspeed.excess") / 100 };
  }
  if (checked("rounding.on")) abnormal.rounding = { share: num("abnormal.rounding.share") };
  if (checked("injection.on")) {
    abnormal.injection = {
      count: intOrRaw("abnormal.injection.count"), arrive_s: num("abnormal.injection.arrive_s"),
      excess: num("abnormal.injection.excess") / 100, headway_s: num("abnormal.injection.headway_s"),
    };
  }
  const ego: Json = {}; // an empty field is the format's default (its placeholder shows it)
  for (const key of ["entrance_lane", "start_distance_m", "start_speed_mps"]) {
    const v = field(`ego.${key}`).value;
    if (v !== "") ego[key] = key === "entrance_lane" ? v : Number(v);
  }
  const source = currentSource();
  const body: Json = {
    version: 1,
    name: field("name").value,
    intersection: source ? sourceRef(source) : field("intersection").value,
    task: field("task").value,
    ego,
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
  if (field("approach").value) body.approach = field("approach").value; // absent: from the south
  return body;
}

// --- errors next to their fields -------------------------------------------------------------------

export function clearErrors(root: ParentNode = form, general = $("#form-error")): void {
  root.querySelectorAll(".field-error").forEach((e) => e.remove());
  root.querySelectorAll(".invalid").forEach((e) => e.classList.remove("invalid"));
  general.textContent = "";
}

/** Remove the errors shown for ``locs`` (and inside them): fields whose choices were refilled. */
export function clearFieldErrors(locs: string[]): void {
  for (const loc of locs) {
    form.querySelectorAll<HTMLElement>(".field-error").forEach((e) => {
      if (e.dataset.for === loc || e.dataset.for?.startsWith(`${loc}.`)) e.remove();
    });
    form.querySelectorAll(`[data-field="${CSS.escape(loc)}"], [data-field^="${CSS.escape(loc)}."]`)
      .forEach((e) => e.classList.remove("invalid"));
  }
}

/** The field an error location names: itself, else its nearest named parent
 * (``intersection.net`` → the intersection select), else its first named child. */
function fieldFor(root: ParentNode, loc: string): HTMLElement | null {
  const parts = loc.split(".");
  for (let n = parts.length; n > 0; n--) {
    const found = root.querySelector<HTMLElement>(`[data-field="${CSS.escape(parts.slice(0, n).join("."))}"]`);
    if (found) return found;
  }
  return loc ? root.querySelector<HTMLElement>(`[data-field^="${CSS.escape(loc)}."]`) : null;
}

function markField(root: ParentNode, loc: string, msg: string): boolean {
  const target = fieldFor(root, loc);
  if (!target) return false;
  target.classList.add("invalid");
  const span = document.createElement("span");
  span.className = "field-error";
  span.dataset.for = loc;
  span.textContent = msg;
  (target.closest("label") ?? target.parentElement)?.append(span);
  return true;
}

/** Fields the page shows in percent while the API takes a fraction: their errors' numbers are
 *  said in percent too ("-50 %", not "-0.5"). */
const PERCENT_FIELDS = new Set(["abnormal.overspeed.excess", "abnormal.injection.excess"]);

function inFieldUnits(loc: string, msg: string): string {
  if (!PERCENT_FIELDS.has(loc)) return msg;
  return msg.replace(/-?\d+(\.\d+)?(e-?\d+)?/gi, (n) => `${Math.round(Number(n) * 1e6) / 1e4} %`);
}

/** Show an API error: each 422 item next to the field it names (``loc`` without the leading
 * ``strip`` parts, e.g. body.scenario for an inline scenario); the rest in ``general``. */
export function showErrors(err: unknown, { root = form as ParentNode, general = $("#form-error"),
  strip = ["body"] } = {}): void {
  const rest: string[] = [];
  if (err instanceof ApiError && Array.isArray(err.detail)) {
    for (const d of err.detail) {
      const parts: unknown[] = [...(d.loc ?? [])];
      for (const s of strip) if (parts[0] === s) parts.shift();
      const loc = parts.join(".");
      const msg = inFieldUnits(loc, d.msg);
      if (!markField(root, loc, msg)) rest.push(`${loc || "scenario"}: ${msg}`);
    }
  } else {
    rest.push(err instanceof ApiError ? String(err.detail) : String(err));
  }
  general.textContent = rest.join("; ");
}
