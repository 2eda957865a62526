// The 3D view inside the page: an episode's playback or a live run, in an iframe of the studio.
// Its page and WebSocket come through the API's own port (/api/playback/…/view/, /api/live/…/view/),
// so it works wherever the studio does (a reverse proxy, an SSH tunnel).
import { $, messageOf, post } from "./api";

/** Show the viewer page at ``url`` in the panel, titled ``title``, and bring it into view. */
export function showViewer(url: string, title: string): void {
  const panel = $("#viewer-panel");
  const frame = $<HTMLIFrameElement>("#viewer-frame");
  panel.hidden = false;
  $("#viewer-title").textContent = title;
  $<HTMLAnchorElement>("#viewer-tab").href = url;
  frame.dataset.url = url;
  frame.src = url; // a fresh page, even for the same episode: a new tab in the player's eyes
  panel.scrollIntoView({ block: "start" });
}

/** Close the panel (the player is shut down by the server once no tab has it open). */
export function closeViewer(): void {
  const frame = $<HTMLIFrameElement>("#viewer-frame");
  frame.src = "about:blank";
  frame.dataset.url = "";
  $("#viewer-panel").hidden = true;
}

/** Open the 3D playback of one episode in the panel. */
export async function openPlayback(batchId: number, runIndex: number): Promise<void> {
  $("#viewer-status").textContent = "";
  try {
    const opened = await post(`/api/playback/${batchId}/${runIndex}`);
    showViewer(opened.url, `Playback: batch #${batchId}, episode ${runIndex}`);
  } catch (e) {
    $("#viewer-panel").hidden = false;
    $("#viewer-status").textContent = `cannot open the playback of batch #${batchId}, episode ${runIndex}: ${messageOf(e)}`;
  }
}

/** A click on any ``a.playback[data-batch][data-run]`` opens it here (a middle click or a
 *  modifier key still opens the link in a new tab). */
export function initViewer(): void {
  $("#viewer-close").addEventListener("click", closeViewer);
  document.addEventListener("click", (ev) => {
    const link = (ev.target as HTMLElement).closest<HTMLAnchorElement>("a.playback[data-batch][data-run]");
    if (!link || ev.button !== 0 || ev.ctrlKey || ev.metaKey || ev.shiftKey || ev.altKey) return;
    ev.preventDefault();
    void openPlayback(Number(link.dataset.batch), Number(link.dataset.run));
  });
}
