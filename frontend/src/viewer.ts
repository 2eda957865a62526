// The 3D view inside the page: an episode's playback or a live run, in an iframe of the studio.
// Its page and WebSocket come through the API's own port (/api/playback/…/view/, /api/live/…/view/),
// so it works wherever the studio does (a reverse proxy, an SSH tunnel), and the page can drive the
// player from the keyboard (space, arrows, + and −).
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

// Keyboard control of the player in the panel: each key presses one of the player's own buttons
// (its page comes from the studio's origin, so the page can reach into the frame).
const KEYS: Record<string, string[]> = {
  " ": ["Play", "Pause"],
  ArrowRight: ["+1 ▶"],
  ArrowLeft: ["◀ −1"],
  "+": ["faster +"], "=": ["faster +"],
  "-": ["slower −"], "_": ["slower −"],
};
let pointerInPanel = false;

/** Press the player's button labelled one of ``labels`` in the viewer frame; whether one was found. */
export function pressViewerButton(labels: string[]): boolean {
  const doc = $<HTMLIFrameElement>("#viewer-frame").contentDocument;
  const button = doc && [...doc.querySelectorAll<HTMLButtonElement>("button")]
    .find((b) => labels.includes((b.textContent ?? "").trim()));
  if (!button) return false;
  button.click();
  return true;
}

function typing(target: EventTarget | null): boolean {
  const el = target as HTMLElement | null;
  return !!el && (el.isContentEditable || ["INPUT", "SELECT", "TEXTAREA"].includes(el.tagName));
}

/** Space plays or pauses, the arrows step, + and − change the speed: while the viewer has the
 *  focus (a click in it) or the pointer is over its panel, and no field is being typed in. */
function onKey(ev: KeyboardEvent, fromFrame: boolean): void {
  const panel = $("#viewer-panel");
  if (panel.hidden || ev.ctrlKey || ev.metaKey || ev.altKey || typing(ev.target)) return;
  if (!fromFrame && !pointerInPanel && document.activeElement !== $("#viewer-frame")) return;
  const labels = KEYS[ev.key];
  if (!labels) return;
  if (pressViewerButton(labels)) {
    ev.preventDefault();
    $("#viewer-frame").dataset.lastKey = ev.key;
  }
}

/** A click on any ``a.playback[data-batch][data-run]`` opens it here (a middle click or a
 *  modifier key still opens the link in a new tab). */
export function initViewer(): void {
  $("#viewer-close").addEventListener("click", closeViewer);
  const panel = $("#viewer-panel");
  panel.addEventListener("mouseenter", () => (pointerInPanel = true));
  panel.addEventListener("mouseleave", () => (pointerInPanel = false));
  document.addEventListener("keydown", (ev) => onKey(ev, false));
  const frame = $<HTMLIFrameElement>("#viewer-frame");
  frame.addEventListener("load", () => {
    try {
      frame.contentWindow?.addEventListener("keydown", (ev) => onKey(ev, true));
    } catch {
      // another origin (never the studio's own viewer): its keys stay its own
    }
  });
  document.addEventListener("click", (ev) => {
    const link = (ev.target as HTMLElement).closest<HTMLAnchorElement>("a.playback[data-batch][data-run]");
    if (!link || ev.button !== 0 || ev.ctrlKey || ev.metaKey || ev.shiftKey || ev.altKey) return;
    ev.preventDefault();
    void openPlayback(Number(link.dataset.batch), Number(link.dataset.run));
  });
}
