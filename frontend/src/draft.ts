// The form's draft: what the user typed, kept in sessionStorage so a reload (e.g. during a batch)
// gives the form back as it was instead of its defaults.
import { field, form } from "./form";

const DRAFT_KEY = "crossroads.form-draft";
export type Draft = Record<string, string | boolean>;

/** Every named scenario field, as the form shows it now. */
function current(): Draft {
  const draft: Draft = {};
  for (const el of Array.from(form.elements)) {
    const input = el as HTMLInputElement;
    if (!input.name || input.type === "file" || input.closest("[data-not-scenario]")) continue;
    draft[input.name] = input.type === "checkbox" ? input.checked : input.value;
  }
  return draft;
}

export function saveDraft(): void {
  sessionStorage.setItem(DRAFT_KEY, JSON.stringify(current()));
}

export function loadDraft(): Draft | null {
  try {
    return JSON.parse(sessionStorage.getItem(DRAFT_KEY) ?? "null");
  } catch {
    return null;
  }
}

/** Put the draft's values of ``names`` (all of them when omitted) back into the form; a select
 *  keeps its value when the draft's is no longer one of its options (e.g. a deleted upload), or
 *  one it offers disabled (a task without a path from the approach). */
export function applyDraft(draft: Draft, names?: string[]): void {
  for (const [name, value] of Object.entries(draft)) {
    if (names && !names.includes(name)) continue;
    const el = field(name) as HTMLInputElement | HTMLSelectElement | null;
    if (!el) continue;
    if (el instanceof HTMLSelectElement) {
      if (Array.from(el.options).some((o) => o.value === value && !o.disabled)) el.value = String(value);
    } else if (el.type === "checkbox") {
      el.checked = Boolean(value);
    } else {
      el.value = String(value);
    }
  }
}

const text = (v: unknown): string => (v == null ? "" : String(v));

/** A stored scenario's spec as the form's values (``source``: the intersection select's value). */
export function specToDraft(spec: Record<string, any>, source: string): Draft { // eslint-disable-line @typescript-eslint/no-explicit-any
  const over = spec.abnormal?.overspeed;
  const round = spec.abnormal?.rounding;
  const injected = spec.abnormal?.injection;
  const draft: Draft = {
    name: text(spec.name), intersection: source, "intersection.junction": text(spec.intersection?.junction),
    task: text(spec.task), approach: text(spec.approach),
    "ego.entrance_lane": text(spec.ego?.entrance_lane), "ego.start_distance_m": text(spec.ego?.start_distance_m),
    "ego.start_speed_mps": text(spec.ego?.start_speed_mps),
    "lights.phase": text(spec.lights?.phase), "lights.elapsed_s": text(spec.lights?.elapsed_s ?? 0),
    "traffic.vehicles_per_hour": text(spec.traffic?.vehicles_per_hour),
    "traffic.cyclists_per_hour": text(spec.traffic?.cyclists_per_hour),
    "traffic.pedestrians_per_hour": text(spec.traffic?.pedestrians_per_hour),
    "overspeed.on": over != null, "rounding.on": round != null, "injection.on": injected != null,
    runs: text(spec.runs), seed: text(spec.seed), warmup_s: text(spec.warmup_s), timeout_s: text(spec.timeout_s),
  };
  if (over) {
    draft["abnormal.overspeed.share"] = text(over.share);
    draft["abnormal.overspeed.excess"] = text(Math.round(Number(over.excess) * 1e6) / 1e4); // percent
  }
  if (round) draft["abnormal.rounding.share"] = text(round.share);
  if (injected) {
    draft["abnormal.injection.count"] = text(injected.count);
    draft["abnormal.injection.arrive_s"] = text(injected.arrive_s);
    draft["abnormal.injection.excess"] = text(Math.round(Number(injected.excess) * 1e6) / 1e4); // percent
    draft["abnormal.injection.headway_s"] = text(injected.headway_s);
  }
  return draft;
}
