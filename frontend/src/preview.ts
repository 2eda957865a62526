// The top-down preview: roads, crossings, stop lines, the candidate paths of the task and the
// ego's start on its entrance lane. It zooms (wheel, +/-) and pans (drag) over the drawing, and a
// click on an entrance lane places the ego's start there (the handler main.ts gives sets the form).
import { $, api, Json, messageOf } from "./api";
import { field, numOrDefault } from "./form";
import { chosenApproach, chosenJunction, currentSource, geometryOf, pathsUrl } from "./intersections";

const SVG = "http://www.w3.org/2000/svg";
const PATH_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
const EGO_LENGTH_M = 4.8; // drawn size of the ego marker (the simulation's own is in constants.py)
const EGO_WIDTH_M = 2.0;
const VIEW_RADIUS_M = 45; // [m] around the junction's centre, more when the ego starts further out
const EGO_MARGIN_M = 8;
const CAPTION_BAND = 6; // [m at the default view] height of the caption's strip above the map
const ZOOM_MIN = 0.5;
const ZOOM_MAX = 24;
const ZOOM_STEP = 1.5; // one press of + or −
const WHEEL_RATE = 0.002; // zoom factor per wheel pixel: exp(-deltaY · rate)
const CLICK_SLOP_PX = 4; // a press that moves less than this is a click, not a drag
const START_STEP_M = 0.5; // a clicked start distance is rounded to this

/** An error of the preview, in full (wrapped) under the picture; "" hides it. */
function showPreviewError(text: string): void {
  const el = $("#preview-error");
  el.textContent = text;
  el.hidden = !text;
}

/** What a click on the preview set (or why it set nothing), under the picture. */
export function showPreviewStatus(text: string): void {
  $("#preview-status").textContent = text;
}

function svgEl(tag: string, attrs: Record<string, string | number>): SVGElement {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  return el;
}
const pts = (xy: number[][]) => xy.map((p) => `${p[0]},${-p[1]}`).join(" "); // SVG y points down

/** The point ``back`` metres before the end of a polyline, and the heading there [rad]. */
function pointBeforeEnd(line: number[][], back: number): { x: number; y: number; heading: number } {
  let left = back;
  for (let i = line.length - 1; i > 0; i--) {
    const [x1, y1] = line[i];
    const [x0, y0] = line[i - 1];
    const seg = Math.hypot(x1 - x0, y1 - y0);
    const heading = Math.atan2(y1 - y0, x1 - x0);
    if (left <= seg || i === 1) {
      const f = seg > 0 ? Math.min(left / seg, 1) : 0;
      return { x: x1 - f * (x1 - x0), y: y1 - f * (y1 - y0), heading };
    }
    left -= seg;
  }
  const [x, y] = line[0];
  return { x, y, heading: 0 };
}

function drawRoads(svg: SVGElement, geo: Json): void {
  const lane = (l: Json, colour: string) =>
    svg.append(svgEl("polyline", { points: pts(l.centerline), stroke: colour, "stroke-width": l.width_m, fill: "none" }));
  for (const s of geo.sidewalks ?? []) lane(s, "#c8c8c8");
  for (const s of geo.bike_lanes ?? []) lane(s, "#b07a7a");
  for (const a of geo.approaches) {
    for (const l of [...a.entrance_lanes, ...a.exit_lanes]) lane(l, "#6b6b6b");
    for (const ring of a.median ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#7bb06a" }));
  }
  for (const ring of geo.walking_areas ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#c8c8c8" }));
  for (const ring of geo.polygon ?? []) svg.append(svgEl("polygon", { points: pts(ring), fill: "#6b6b6b" }));
  for (const a of geo.approaches) {
    for (const l of a.entrance_lanes) {
      svg.append(svgEl("polyline", { points: pts(l.centerline), stroke: "#fff", "stroke-width": 0.15, "stroke-dasharray": "3 3", fill: "none" }));
    }
    if (a.stop_line?.length) svg.append(svgEl("polyline", { points: pts(a.stop_line), stroke: "#d62728", "stroke-width": 0.5, fill: "none" }));
  }
  for (const c of geo.crossings ?? []) {
    svg.append(svgEl("polyline", { points: pts(c.centerline), stroke: "#fff", "stroke-width": c.width_m, "stroke-dasharray": "0.5 0.5", fill: "none", opacity: 0.8 }));
  }
}

/** SUMO's internal lane of each candidate's movement, dashed under it: where SUMO's vehicles
 *  drive and where SUMO puts the ego. On a user's net netconvert's lanes can run metres off. */
function drawSumoLanes(svg: SVGElement, paths: Json[]): void {
  paths.forEach((p, i) => {
    if (!p.sumo_internal_lane) return;
    const colour = PATH_COLOURS[i % PATH_COLOURS.length];
    const line = svgEl("polyline", { points: pts(p.sumo_internal_lane), stroke: colour, "stroke-width": 0.35,
      "stroke-dasharray": "1.2 0.8", fill: "none", opacity: 0.9, "class": "sumo-lane" });
    const title = svgEl("title", {});
    title.textContent = `SUMO's internal lane of ${p.id}: up to ${Number(p.sumo_offset_m).toFixed(2)} m from the path`;
    line.append(title);
    svg.append(line);
  });
}

function drawPaths(svg: SVGElement, paths: Json[]): void {
  paths.forEach((p, i) => {
    const colour = PATH_COLOURS[i % PATH_COLOURS.length];
    const line = svgEl("polyline", { points: pts(p.points), stroke: colour, "stroke-width": 0.6, fill: "none", "class": "candidate" });
    const title = svgEl("title", {});
    title.textContent = `${p.id}: ${p.entrance_lane} → ${p.exit_lane}`;
    line.append(title);
    svg.append(line);
    const end = p.points[p.points.length - 1];
    svg.append(svgEl("circle", { cx: end[0], cy: -end[1], r: 0.9, fill: colour }));
  });
}

interface EgoStart { x: number; y: number; heading: number; lane: string; distance: number }

/** Where the ego starts: ``start_distance_m`` of its front bumper before the stop line. */
function egoStart(geo: Json, paths: Json[]): EgoStart | null {
  const laneId = field("ego.entrance_lane").value || paths[0]?.entrance_lane;
  const lane = (chosenApproach(geo)?.entrance_lanes ?? []).find((l: Json) => l.id === laneId);
  const distance = numOrDefault("ego.start_distance_m");
  if (!lane || !(distance > 0)) return null;
  return { ...pointBeforeEnd(lane.centerline, distance + EGO_LENGTH_M / 2), lane: lane.id, distance };
}

function drawEgo(svg: SVGElement, ego: EgoStart): void {
  const { x, y } = ego;
  const deg = (-ego.heading * 180) / Math.PI; // SVG rotates clockwise, y down
  const box = svgEl("rect", {
    x: x - EGO_LENGTH_M / 2, y: -y - EGO_WIDTH_M / 2, width: EGO_LENGTH_M, height: EGO_WIDTH_M,
    fill: "#28c878", stroke: "#0b5d36", "stroke-width": 0.2, transform: `rotate(${deg} ${x} ${-y})`, "class": "ego-start",
  });
  const title = svgEl("title", {});
  title.textContent = `ego start: ${ego.lane}, ${ego.distance} m before the stop line`;
  box.append(title);
  svg.append(box);
}

/** Every entrance lane as a wide, invisible target: a click on it places the ego's start. */
function drawLaneTargets(svg: SVGElement, geo: Json): void {
  for (const a of geo.approaches) {
    for (const l of a.entrance_lanes) {
      const target = svgEl("polyline", { points: pts(l.centerline), stroke: "transparent", "stroke-width": l.width_m,
        fill: "none", "class": "lane-target", "data-approach": a.id, "data-lane": l.id });
      const title = svgEl("title", {});
      title.textContent = `${l.id} (approach ${a.id}, leads ${(l.turns as string[]).join(", ")}): click to start the ego here`;
      target.append(title);
      svg.append(target);
    }
  }
}

// --- the view: zoom and pan over the drawing -------------------------------------------------------

/** The drawing's default frame (SVG coordinates: y points down) and the user's zoom and pan over
 *  it. The map group is drawn at ``translate(b + pan) scale(zoom) translate(-b)``, b the frame's
 *  centre: zoom 1 and no pan is the default view. */
interface Frame { x: number; y: number; r: number; key: string }
let frame: Frame | null = null;
let zoom = 1;
let panX = 0;
let panY = 0;
let lanes = new Map<string, { approach: string; centerline: number[][]; turns: string[] }>();

const moved = (): boolean => zoom !== 1 || panX !== 0 || panY !== 0;

function applyView(): void {
  const map = document.querySelector<SVGGElement>("#preview-map");
  if (map && frame) {
    map.setAttribute("transform",
      `translate(${frame.x + panX} ${frame.y + panY}) scale(${zoom}) translate(${-frame.x} ${-frame.y})`);
  }
  $("#preview-zoom").textContent = `${Math.round(zoom * 100)} %`;
  $<HTMLButtonElement>("#preview-reset").disabled = !moved();
}

/** Zoom by ``factor`` keeping the point ``(sx, sy)`` (SVG coordinates) where it is. */
function zoomAt(sx: number, sy: number, factor: number): void {
  if (!frame) return;
  const next = Math.min(ZOOM_MAX, Math.max(ZOOM_MIN, zoom * factor));
  const px = frame.x + (sx - frame.x - panX) / zoom; // the map's point under (sx, sy)
  const py = frame.y + (sy - frame.y - panY) / zoom;
  panX = sx - frame.x - next * (px - frame.x);
  panY = sy - frame.y - next * (py - frame.y);
  zoom = next;
  applyView();
}

/** Back to the default view (its frame recomputed at the next draw, around the ego's start). */
export function resetView(): void {
  zoom = 1;
  panX = 0;
  panY = 0;
  frame = null;
}

/** A pointer's position in the coordinates of ``el`` (the SVG's, or the map's own). */
function pointIn(el: SVGGraphicsElement, ev: MouseEvent): DOMPoint {
  const ctm = el.getScreenCTM();
  const p = new DOMPoint(ev.clientX, ev.clientY);
  return ctm ? p.matrixTransform(ctm.inverse()) : p;
}

/** A click on an entrance lane: the lane, its approach and the start distance (front bumper
 *  before the stop line) that puts the ego's centre where the click fell along the lane. */
export interface LanePick { approach: string; lane: string; distance: number; turns: string[] }

/** Where along ``line`` the point (x, y) falls, as the length from there to the line's end. */
function lengthToEnd(line: number[][], x: number, y: number): number {
  let best = Infinity;
  let along = 0;
  let at = 0;
  for (let i = 1; i < line.length; i++) {
    const [x0, y0] = line[i - 1];
    const [x1, y1] = line[i];
    const seg = Math.hypot(x1 - x0, y1 - y0);
    const t = seg > 0 ? Math.max(0, Math.min(1, ((x - x0) * (x1 - x0) + (y - y0) * (y1 - y0)) / (seg * seg))) : 0;
    const d = Math.hypot(x0 + t * (x1 - x0) - x, y0 + t * (y1 - y0) - y);
    if (d < best) {
      best = d;
      at = along + t * seg;
    }
    along += seg;
  }
  return along - at;
}

function pickOf(target: Element, ev: MouseEvent): LanePick | null {
  const id = (target as SVGElement).dataset.lane;
  const lane = id ? lanes.get(id) : undefined;
  const map = document.querySelector<SVGGElement>("#preview-map");
  if (!id || !lane || !map) return null;
  const p = pointIn(map, ev);
  const toEnd = lengthToEnd(lane.centerline, p.x, -p.y); // SVG y is the network's −y
  const distance = Math.max(0, Math.round((toEnd - EGO_LENGTH_M / 2) / START_STEP_M) * START_STEP_M);
  return { approach: lane.approach, lane: id, distance, turns: lane.turns };
}

/** The entrance lane under the pointer, also where a candidate path or the ego is drawn over it. */
function laneUnder(ev: MouseEvent): Element | null {
  return document.elementsFromPoint(ev.clientX, ev.clientY).find((el) => el.classList.contains("lane-target")) ?? null;
}

/** Wheel and the +/− buttons zoom, a drag pans, a click on an entrance lane calls ``onPick``. */
export function initPreview(onPick: (pick: LanePick) => void): void {
  const svg = $<SVGSVGElement>("#preview");
  svg.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    const p = pointIn(svg, ev);
    zoomAt(p.x, p.y, Math.exp(-ev.deltaY * WHEEL_RATE));
  }, { passive: false });
  const atCentre = (factor: number) => () => { if (frame) zoomAt(frame.x + panX, frame.y + panY, factor); };
  $("#preview-zoom-in").addEventListener("click", atCentre(ZOOM_STEP));
  $("#preview-zoom-out").addEventListener("click", atCentre(1 / ZOOM_STEP));
  $("#preview-reset").addEventListener("click", () => {
    resetView();
    void drawPreview();
  });
  let press: { x: number; y: number; panX: number; panY: number; scale: number; target: Element | null; dragged: boolean } | null = null;
  svg.addEventListener("pointerdown", (ev) => {
    if (ev.button !== 0) return;
    const ctm = svg.getScreenCTM();
    press = { x: ev.clientX, y: ev.clientY, panX, panY, scale: ctm ? ctm.a : 1,
      target: laneUnder(ev), dragged: false };
    svg.setPointerCapture(ev.pointerId);
  });
  svg.addEventListener("pointermove", (ev) => {
    if (!press) return;
    const dx = ev.clientX - press.x;
    const dy = ev.clientY - press.y;
    if (!press.dragged && Math.hypot(dx, dy) < CLICK_SLOP_PX) return;
    press.dragged = true;
    svg.classList.add("panning");
    panX = press.panX + dx / press.scale;
    panY = press.panY + dy / press.scale;
    applyView();
  });
  const release = (ev: PointerEvent) => {
    if (!press) return;
    const { target, dragged } = press;
    press = null;
    svg.classList.remove("panning");
    if (svg.hasPointerCapture(ev.pointerId)) svg.releasePointerCapture(ev.pointerId);
    if (ev.type === "pointerup" && !dragged && target) {
      const pick = pickOf(target, ev);
      if (pick) onPick(pick);
    }
  };
  svg.addEventListener("pointerup", release);
  svg.addEventListener("pointercancel", release);
}

/** Shrink a caption's font until it fits ``width`` (a long network or junction name). */
function fitText(text: SVGElement, width: number, size: number): void {
  const length = (text as SVGTextElement).getComputedTextLength();
  if (length > width) text.setAttribute("font-size", String((size * width) / length));
}

// Draws are asynchronous (geometry and paths come from the API) and several can be in flight
// when choices change quickly: only the latest one may touch the picture, or an older answer
// arriving last would show a stale intersection or task.
let latestDraw = 0;

export async function drawPreview(): Promise<void> {
  const draw = ++latestDraw;
  const svg = $<SVGSVGElement>("#preview");
  const source = currentSource();
  const task = field("task").value;
  if (!source) return;
  const junction = chosenJunction();
  const name = source.label + (junction ? ` · junction ${junction}` : "");
  try {
    const geo = await geometryOf(source);
    let paths: Json[] = [];
    let pathError = "";
    try {
      paths = await api(pathsUrl(source, task, field("approach").value));
    } catch (e) {
      pathError = messageOf(e);
    }
    if (draw !== latestDraw) return;
    svg.replaceChildren();
    lanes = new Map((geo.approaches as Json[]).flatMap((a) => (a.entrance_lanes as Json[]).map(
      (l): [string, { approach: string; centerline: number[][]; turns: string[] }] =>
        [l.id, { approach: a.id, centerline: l.centerline, turns: l.turns }])));
    const [cx, cy] = geo.center;
    const ego = egoStart(geo, paths);
    const key = `${source.key}|${geo.junction_id}`;
    if (!frame || frame.key !== key || !moved()) { // a zoomed or panned view stays where the user put it
      if (frame?.key !== key) resetView();
      const r = Math.max(VIEW_RADIUS_M, ego ? Math.hypot(ego.x - cx, ego.y - cy) + EGO_MARGIN_M : 0); // the ego in view
      frame = { x: cx, y: -cy, r, key };
    }
    const { r } = frame;
    const [fx, fy] = [frame.x, frame.y];
    const k = r / VIEW_RADIUS_M; // text scales with the view, so it reads the same size
    const band = CAPTION_BAND * k; // the caption's own strip above the map: it never covers a road
    svg.setAttribute("viewBox", `${fx - r} ${fy - r - band} ${2 * r} ${2 * r + band}`);
    svg.style.aspectRatio = `${2 * r} / ${2 * r + band}`;
    const defs = svgEl("defs", {});
    const clip = svgEl("clipPath", { id: "preview-clip" });
    clip.append(svgEl("rect", { x: fx - r, y: fy - r, width: 2 * r, height: 2 * r }));
    defs.append(clip);
    svg.append(defs);
    const clipped = svgEl("g", { "clip-path": "url(#preview-clip)" });
    clipped.append(svgEl("rect", { x: fx - r, y: fy - r, width: 2 * r, height: 2 * r, fill: "#dfe8d8", "class": "ground" }));
    const map = svgEl("g", { id: "preview-map" });
    clipped.append(map);
    svg.append(clipped);
    drawRoads(map, geo);
    drawLaneTargets(map, geo);
    drawSumoLanes(map, paths);
    drawPaths(map, paths);
    if (ego) drawEgo(map, ego);
    // the strip last, over the ends of the roads that reach beyond the map
    svg.append(svgEl("rect", { x: fx - r, y: fy - r - band, width: 2 * r, height: band, fill: "#fff" }));
    const caption = svgEl("text", { x: fx - r + 2 * k, y: fy - r - band * 0.35, "font-size": 3 * k, fill: pathError ? "#b00020" : "#222" });
    caption.textContent = pathError ? `${name} · no ${task} path (the reason is below)` : `${name} · ${task}: ${paths.length} candidate path(s)`;
    svg.append(caption);
    fitText(caption, 2 * r - 4 * k, 3 * k);
    applyView();
    showPreviewError(pathError ? `No ${task} path: ${pathError}` : "");
  } catch (e) {
    if (draw !== latestDraw) return;
    svg.replaceChildren();
    const t = svgEl("text", { x: -55, y: 0, "font-size": 4, fill: "#b00" });
    t.textContent = `cannot draw ${name} (the reason is below)`;
    svg.append(t);
    showPreviewError(`Cannot draw ${name}: ${messageOf(e)}`);
  }
}
