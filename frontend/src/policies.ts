// Policies: the batch's driver choice, and your own ONNX policy uploaded with a name and a short card
// (the API checks it against the IDC state layout; docs/guide/own-driver.md). Uploaded ones are listed
// with their sha256 beside the shipped ones, and can be deleted.
import { $, api, esc, Json } from "./api";
import { showErrors } from "./form";

const KINDS: Record<string, string> = { checkpoint: "checkpoint", onnx: "uploaded ONNX" };

function optionLabel(p: Json): string {
  const kind = KINDS[p.kind as string];
  if (!kind) return esc(p.name);
  const hash = p.sha256 ? `, sha256 ${String(p.sha256).slice(0, 12)}` : "";
  return `${esc(p.name)} (${kind}${p.shield ? " + safety shield" : ""}${esc(hash)})`;
}

/** Fill the policy select (keeping the choice when it is still there) and the list of uploads. */
export function fillPolicies(policies: Json[], choose?: string): void {
  const select = $<HTMLSelectElement>("#policy");
  const keep = choose ?? select.value;
  select.innerHTML = policies.map((p) => `<option value="${esc(p.name)}">${optionLabel(p)}</option>`).join("");
  if (policies.some((p) => p.name === keep)) select.value = keep;
  const uploads = policies.filter((p) => p.kind === "onnx" && !p.shield);
  $("#policy-uploads").innerHTML = uploads.map((p) => `<li><b>${esc(p.name)}</b>
    <code title="sha256">${esc(String(p.sha256).slice(0, 16))}…</code> ${esc(p.card?.card ?? "")}
    <button type="button" data-delete-policy="${esc(p.name)}">Delete</button></li>`).join("");
}

async function refresh(choose?: string): Promise<void> {
  fillPolicies(await api("/api/policies"), choose);
}

async function upload(): Promise<void> {
  const panel = $("#policy-upload");
  const status = $("#policy-upload-status");
  panel.querySelectorAll(".field-error").forEach((e) => e.remove());
  panel.querySelectorAll(".invalid").forEach((e) => e.classList.remove("invalid"));
  const file = $<HTMLInputElement>("#policy-file").files?.[0];
  const body = new FormData();
  if (file) body.append("file", file, file.name);
  body.append("name", $<HTMLInputElement>("#policy-name").value);
  body.append("card", $<HTMLTextAreaElement>("#policy-card").value);
  const button = $<HTMLButtonElement>("#policy-upload-button");
  button.disabled = true;
  status.textContent = file ? `checking ${file.name}…` : "";
  try {
    const p = await api("/api/policies/upload", { method: "POST", body });
    await refresh(p.name); // offered (and chosen) by the time the status says it is stored
    status.textContent = `${p.name}: stored (sha256 ${String(p.sha256).slice(0, 12)}…, state of ${p.card.signature.state_width} values` +
      `${p.card.signature.value_output ? ", with a path value" : ""}); choose it as the policy of a batch`;
    $<HTMLInputElement>("#policy-file").value = "";
  } catch (e) {
    status.textContent = "";
    showErrors(e, { root: panel, general: status }); // 413/422 name "file", "name" or "card"
  } finally {
    button.disabled = false;
  }
}

async function remove(name: string): Promise<void> {
  const status = $("#policy-upload-status");
  try {
    await api(`/api/policies/uploads/${encodeURIComponent(name)}`, { method: "DELETE" });
    await refresh(); // the choice lists it no more by the time the status says so
    status.textContent = `${name}: deleted (the batches that ran it keep their results)`;
  } catch (e) {
    showErrors(e, { root: $("#policy-upload"), general: status });
  }
}

/** The upload panel, under the policy choice (outside what a scenario is: data-not-scenario). */
export function initPolicyUploads(): void {
  const anchor = $("#policy").closest(".actions") ?? $("#policy");
  const panel = document.createElement("div");
  panel.id = "policy-upload";
  panel.className = "upload";
  panel.dataset.notScenario = "";
  panel.innerHTML = `
    <label>Or upload your own ONNX policy: the IDC state (108 or 120 values) in, [Δδ, Δa] out
      <input type="file" id="policy-file" data-field="file" accept=".onnx" /></label>
    <label>Name <input id="policy-name" data-field="name" maxlength="64" placeholder="my-driver" /></label>
    <label>Card <textarea id="policy-card" data-field="card" maxlength="2000" rows="2"
      placeholder="what it is, how it was trained"></textarea></label>
    <button type="button" id="policy-upload-button">Upload policy</button>
    <span id="policy-upload-status" class="hint" role="status"></span>
    <ul id="policy-uploads" class="hint"></ul>`;
  anchor.after(panel);
  $("#policy-upload-button").addEventListener("click", () => void upload());
  panel.addEventListener("click", (ev) => {
    const name = (ev.target as HTMLElement).dataset.deletePolicy;
    if (name) void remove(name);
  });
}
