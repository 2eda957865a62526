// The form's draft: what the user typed, kept in sessionStorage so a reload (e.g. during a batch)
// gives the form back as it was instead of its defaults.
import { field, form } from "./form";

const DRAFT_KEY = "crossroads.form-draft";
type Draft = Record<string, string | boolean>;

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
 *  keeps its value when the draft's is no longer one of its options (e.g. a deleted upload). */
export function applyDraft(draft: Draft, names?: string[]): void {
  for (const [name, value] of Object.entries(draft)) {
    if (names && !names.includes(name)) continue;
    const el = field(name) as HTMLInputElement | HTMLSelectElement | null;
    if (!el) continue;
    if (el instanceof HTMLSelectElement) {
      if (Array.from(el.options).some((o) => o.value === value)) el.value = String(value);
    } else if (el.type === "checkbox") {
      el.checked = Boolean(value);
    } else {
      el.value = String(value);
    }
  }
}
