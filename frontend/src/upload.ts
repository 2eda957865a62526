// Uploading a SUMO network (.net.xml): the API checks it and reads its junction; a good one
// becomes a choice of the intersection select, a bad one gets its reason next to the field.
import { $, api, ApiError, Json } from "./api";
import { clearErrors, showErrors } from "./form";
import { addUpload } from "./intersections";

/** Upload the chosen file; the network's source once stored, or null (errors are shown). */
export async function uploadNetwork(): Promise<Json | null> {
  const input = $<HTMLInputElement>("#net-file");
  const panel = $("#upload-panel");
  const status = $("#upload-status");
  clearErrors(panel, status);
  const file = input.files?.[0];
  if (!file) {
    showErrors(new ApiError(422, [{ loc: ["body", "file"], msg: "choose a .net.xml file first" }]), { root: panel, general: status });
    return null;
  }
  const body = new FormData();
  body.append("file", file, file.name);
  const button = $<HTMLButtonElement>("#upload");
  button.disabled = true;
  status.textContent = `uploading ${file.name}…`;
  try {
    const uploaded = await api("/api/intersections/upload", { method: "POST", body });
    // A net whose internal lanes run off the candidate paths still runs, but SUMO sees the ego
    // elsewhere than it drives there: said once, here, where the net comes in.
    const warning: string | null = uploaded.internal_lanes?.warning ?? null;
    status.textContent = `${uploaded.name}: junction ${uploaded.junction}, ${uploaded.approaches.length} approaches`
      + (warning ? `. Warning: ${warning}` : "");
    status.classList.toggle("warning", warning !== null);
    input.value = "";
    return addUpload(uploaded);
  } catch (e) {
    status.textContent = "";
    showErrors(e, { root: panel, general: status }); // 413 and 422 name the field "file"
    return null;
  } finally {
    button.disabled = false;
  }
}
