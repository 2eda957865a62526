// The top-down preview: roads, crossings, stop lines, the candidate paths of the task and the
// ego's start on its entrance lane.
import { $, api, ApiError, Json } from "./api";
import { field, numOrDefault } from "./form";
import { chosenApproach, currentSource, geometryOf, pathsUrl } from "./intersections";

const SVG = "http://www.w3.org/2000/svg";
const PATH_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
const EGO_LENGTH_M = 4.8; // drawn size of the ego marker (the simulation's own is in constants.py)
const EGO_WIDTH_M = 2.0;
const VIEW_RADIUS_M = 45; // [m] around the junction's centre, more when the ego starts further out
const EGO_MARGIN_M = 8;
const CAPTION_BAND = 6; // [m at the default view] height of the caption's strip above the map

/** An error of the preview, in full (wrapped) under the picture; "" hides it. */
function showPreviewError(text: string): void {
  const el = $("#preview-error");
  el.textContent = text;
  el.hidden = !text;
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

function drawRoads(svg: SVGSVGElement, geo: Json): void {
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
function drawSumoLanes(svg: SVGSVGElement, paths: Json[]): void {
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

function drawPaths(svg: SVGSVGElement, paths: Json[]): void {
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

function drawEgo(svg: SVGSVGElement, ego: EgoStart): void {
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
  try {
    const geo = await geometryOf(source);
    let paths: Json[] = [];
    let pathError = "";
    try {
      paths = await api(pathsUrl(source, task, field("approach").value));
    } catch (e) {
      pathError = e instanceof ApiError ? String(e.detail) : String(e);
    }
    if (draw !== latestDraw) return;
    svg.replaceChildren();
    const [cx, cy] = geo.center;
    const ego = egoStart(geo, paths);
    const r = Math.max(VIEW_RADIUS_M, ego ? Math.hypot(ego.x - cx, ego.y - cy) + EGO_MARGIN_M : 0); // the ego in view
    const k = r / VIEW_RADIUS_M; // text scales with the view, so it reads the same size
    const band = CAPTION_BAND * k; // the caption's own strip above the map: it never covers a road
    svg.setAttribute("viewBox", `${cx - r} ${-cy - r - band} ${2 * r} ${2 * r + band}`);
    svg.style.aspectRatio = `${2 * r} / ${2 * r + band}`;
    svg.append(svgEl("rect", { x: cx - r, y: -cy - r, width: 2 * r, height: 2 * r, fill: "#dfe8d8" }));
    drawRoads(svg, geo);
    drawSumoLanes(svg, paths);
    drawPaths(svg, paths);
    if (ego) drawEgo(svg, ego);
    // the strip last, over the ends of the roads that reach beyond the map
    svg.append(svgEl("rect", { x: cx - r, y: -cy - r - band, width: 2 * r, height: band, fill: "#fff" }));
    const caption = svgEl("text", { x: cx - r + 2 * k, y: -cy - r - band * 0.35, "font-size": 3 * k, fill: pathError ? "#b00020" : "#222" });
    caption.textContent = pathError ? `${source.label} · no ${task} path (the reason is below)` : `${source.label} · ${task}: ${paths.length} candidate path(s)`;
    svg.append(caption);
    showPreviewError(pathError ? `No ${task} path: ${pathError}` : "");
  } catch (e) {
    if (draw !== latestDraw) return;
    svg.replaceChildren();
    const t = svgEl("text", { x: -55, y: 0, "font-size": 4, fill: "#b00" });
    t.textContent = `cannot draw ${source.label} (the reason is below)`;
    svg.append(t);
    showPreviewError(`Cannot draw ${source.label}: ${e instanceof ApiError ? String(e.detail) : String(e)}`);
  }
}
