// The scenario library: the stored scenarios, each opened in the form, duplicated, downloaded as a
// YAML file or deleted; a YAML file imported as a new one.
import { $, api, esc, Json, messageOf } from "./api";

export type Opener = (row: Json, editable: boolean) => Promise<void>;
let open: Opener = async () => undefined;
const PAGE = 200; // scenarios listed (the newest)

function intersectionName(spec: Json): string {
  const i = spec.intersection;
  return typeof i === "string" ? i : `${String(i?.net ?? "?").split("/").pop()} (uploaded)`;
}

function row(s: Json): string {
  const locked = s.batches > 0;
  return `<tr data-id="${s.id}"><td>${s.id}</td><td class="name">${esc(s.name)}</td><td>${esc(intersectionName(s.spec))}</td>
    <td>${esc(s.spec.task)}</td><td>${s.spec.runs}</td><td>${s.batches}</td>
    <td class="row-actions"><button type="button" data-open="${s.id}">Open</button>
      <button type="button" data-duplicate="${s.id}">Duplicate</button>
      <a href="/api/scenarios/${s.id}/scenario.yaml" download>YAML</a>
      <button type="button" data-delete="${s.id}" ${locked ? `disabled title="batches ran it: it is kept with their results"` : ""}>Delete</button></td></tr>`;
}

/** Read the stored scenarios again and list them, newest first. */
export async function refreshLibrary(): Promise<Json[]> {
  const first = await fetch(`/api/scenarios?limit=1`);
  const total = Number(first.headers.get("x-total-count") ?? 0);
  const offset = Math.max(total - PAGE, 0);
  const list: Json[] = total ? await api(`/api/scenarios?limit=${PAGE}&offset=${offset}`) : [];
  list.reverse();
  $("#library").innerHTML = list.length
    ? `<table class="library"><thead><tr><th>#</th><th>Name</th><th>Intersection</th><th>Task</th><th>Runs</th><th>Batches</th><th></th></tr></thead>
       <tbody>${list.map(row).join("")}</tbody></table>${total > PAGE ? `<p class="hint">The newest ${PAGE} of ${total}.</p>` : ""}`
    : '<p class="hint">No stored scenarios yet: save the form, or import a YAML file.</p>';
  return list;
}

const say = (text: string, error = false): void => {
  const status = $("#library-status");
  status.textContent = text;
  status.classList.toggle("error", error);
};

/** Open a stored scenario in the form; one no batch has run is edited in place. */
export async function openStored(id: number): Promise<void> {
  const s = await api(`/api/scenarios/${id}`);
  await open(s, s.batches === 0);
  say(`Opened scenario #${s.id} (${s.name}).`);
}

async function duplicate(id: number): Promise<void> {
  const s = await api(`/api/scenarios/${id}`);
  const names = new Set(Array.from(document.querySelectorAll("#library td.name"), (td) => td.textContent));
  let name = `${s.name}-copy`;
  for (let k = 2; names.has(name); k++) name = `${s.name}-copy${k}`;
  const copy = await api("/api/scenarios", { method: "POST", body: JSON.stringify({ ...s.spec, name }) });
  await refreshLibrary();
  await open(copy, true);
  say(`Duplicated #${id} as #${copy.id} (${copy.name}), opened in the form.`);
}

async function remove(button: HTMLButtonElement, id: number): Promise<void> {
  if (button.dataset.armed !== "1") { // a second click deletes
    button.dataset.armed = "1";
    button.textContent = "Really delete?";
    return;
  }
  await api(`/api/scenarios/${id}`, { method: "DELETE" });
  await refreshLibrary();
  say(`Deleted scenario #${id}.`);
}

/** Import the chosen YAML file as a stored scenario and open it in the form. */
async function importFile(): Promise<void> {
  const file = $<HTMLInputElement>("#library-file").files?.[0];
  if (!file) {
    say("Choose a scenario file (.yaml) first.", true);
    return;
  }
  try {
    const s = await api("/api/scenarios/import", { method: "POST", body: new Blob([await file.text()], { type: "application/yaml" }) });
    await refreshLibrary();
    await open(s, s.batches === 0);
    say(`Imported ${file.name} as scenario #${s.id} (${s.name}), opened in the form.`);
  } catch (e) {
    const detail = (e as Json)?.detail;
    const text = Array.isArray(detail)
      ? detail.map((d: Json) => `${(d.loc ?? []).slice(1).join(".") || "file"}: ${d.msg}`).join("; ")
      : messageOf(e);
    say(`Not imported: ${text}`, true);
  }
}

export function initLibrary(opener: Opener): void {
  open = opener;
  $("#library-import").addEventListener("click", () => void importFile());
  $("#library-refresh").addEventListener("click", () => void refreshLibrary());
  $("#library").addEventListener("click", (ev) => {
    const button = (ev.target as HTMLElement).closest<HTMLButtonElement>("button");
    if (!button) return;
    const d = button.dataset;
    const run = (p: Promise<void>) => p.catch((e) => say(messageOf(e), true));
    if (d.open) void run(openStored(Number(d.open)));
    if (d.duplicate) void run(duplicate(Number(d.duplicate)));
    if (d.delete) void run(remove(button, Number(d.delete)));
  });
}
