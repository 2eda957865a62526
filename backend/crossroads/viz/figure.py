"""Static figures of an intersection and its candidate paths, like the paper's Fig. 2.

Drawn with matplotlib's object API on the Agg canvas (no pyplot, no display, no global state), so
it is safe inside the API's worker threads. Coordinates are SUMO's network frame [m], equal aspect.

Layers, bottom to top: sidewalks and walking areas (grey), road surface (car lanes, bike lanes,
junction polygon), medians (green), crossings (zebra stripes), lane markings (white: dashed between
lanes of one edge, solid at the edge borders), stop lines, then each candidate path in its own
colour with its control points X0..X5 as dots joined by dotted lines.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch
from matplotlib.path import Path as MplPath
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from crossroads.geometry import polygons_of, arc_lengths, point_at
from crossroads.network.road import Junction, Lane
from crossroads.planning.routes import CandidatePath

ASPHALT = "#5b5b5b"
SIDEWALK = "#c9c9c9"
BIKE_LANE = "#9c6b5a"
MEDIAN = "#5fa346"
MARKING = "#f4f4f4"
BACKGROUND = "#eef0e8"
PATH_COLOURS = ("#ff7f0e", "#1f9bff", "#e6194b", "#ffe119", "#3cb44b", "#f032e6", "#42d4f4", "#bfef45")
VIEW_MARGIN_M = 8.0  # [m] around the candidates (or the junction) in the default view
JUNCTION_VIEW_RADIUS_M = 45.0  # [m] view half-size around the junction when no candidates are drawn




def _add_area(ax: Axes, geometry: BaseGeometry | None, **style: object) -> None:
    """Fill a (multi)polygon, holes included."""
    for poly in polygons_of(geometry):
        rings = [np.asarray(poly.exterior.coords)] + [np.asarray(r.coords) for r in poly.interiors]
        verts = np.concatenate([r[:, :2] for r in rings])
        codes = np.concatenate([[MplPath.MOVETO] + [MplPath.LINETO] * (len(r) - 2) + [MplPath.CLOSEPOLY]
                                for r in rings])
        ax.add_patch(PathPatch(MplPath(verts, codes), **style))


def _offset(line: np.ndarray, distance_m: float) -> np.ndarray | None:
    """The line shifted ``distance_m`` to its left (negative: right), or None if it collapses."""
    if len(line) < 2:
        return None
    shifted = LineString(line).offset_curve(distance_m)
    if shifted.is_empty or shifted.geom_type != "LineString":
        return None
    return np.asarray(shifted.coords)


def _draw_markings(ax: Axes, lanes: Iterable[Lane]) -> None:
    """White lane borders: dashed between the lanes of one edge, solid at the edge's outer borders."""
    by_edge: dict[str, list[Lane]] = {}
    for lane in lanes:
        by_edge.setdefault(lane.edge_id, []).append(lane)
    for edge_lanes in by_edge.values():
        edge_lanes.sort(key=lambda la: la.index)
        for k, lane in enumerate(edge_lanes):
            right = _offset(lane.centerline, -lane.width_m / 2.0)
            if right is not None:
                ax.plot(*right.T, color=MARKING, lw=1.0 if k == 0 else 0.8,
                        ls="-" if k == 0 else (0, (4, 4)), zorder=4, solid_capstyle="butt")
            if k == len(edge_lanes) - 1:
                left = _offset(lane.centerline, lane.width_m / 2.0)
                if left is not None:
                    ax.plot(*left.T, color="#f2c200", lw=1.0, zorder=4)


def _draw_crossing(ax: Axes, centerline: np.ndarray, width_m: float) -> None:
    """Zebra stripes: 0.5 m bars across the crossing every 1 m, parallel to the traffic."""
    cum = arc_lengths(centerline)
    total = float(cum[-1])
    if total <= 0.0:
        return
    for s in np.arange(0.5, total - 0.25, 1.0):
        a, b = point_at(centerline, s - 0.25), point_at(centerline, s + 0.25)
        d = (b - a) / max(np.hypot(*(b - a)), 1e-9)
        n = np.array([-d[1], d[0]]) * (width_m / 2.0 * 0.9)
        bar = Polygon([a - n, b - n, b + n, a + n])
        _add_area(ax, bar, facecolor=MARKING, edgecolor="none", zorder=3.5)


def _draw_candidates(ax: Axes, candidates: Sequence[CandidatePath]) -> None:
    for k, cand in enumerate(candidates):
        colour = PATH_COLOURS[k % len(PATH_COLOURS)]
        ax.plot(*cand.points.T, color=colour, lw=2.0, zorder=6, label=cand.id, solid_capstyle="round")
        cp = cand.control_points
        ax.plot(*cp.T, ls=":", lw=1.0, color=colour, zorder=7)
        ax.plot(*cp.T, ls="none", marker="o", ms=3.5, mfc=colour, mec="black", mew=0.5, zorder=8)


def _view(junction: Junction, candidates: Sequence[CandidatePath]) -> tuple[float, float, float, float]:
    if candidates:
        pts = np.vstack([c.points for c in candidates] + [c.control_points for c in candidates])
        minx, miny = pts.min(axis=0) - VIEW_MARGIN_M
        maxx, maxy = pts.max(axis=0) + VIEW_MARGIN_M
        jx0, jy0, jx1, jy1 = junction.polygon.bounds
        minx, miny = min(minx, jx0 - VIEW_MARGIN_M), min(miny, jy0 - VIEW_MARGIN_M)
        maxx, maxy = max(maxx, jx1 + VIEW_MARGIN_M), max(maxy, jy1 + VIEW_MARGIN_M)
    else:
        cx, cy = junction.center
        r = JUNCTION_VIEW_RADIUS_M
        minx, miny, maxx, maxy = cx - r, cy - r, cx + r, cy + r
    # square view around the middle, so the figure's aspect stays 1
    half = max(maxx - minx, maxy - miny) / 2.0
    mx, my = (minx + maxx) / 2.0, (miny + maxy) / 2.0
    return mx - half, mx + half, my - half, my + half


def plot_intersection(
    junction: Junction,
    candidates: Sequence[CandidatePath] = (),
    ax: Axes | None = None,
    title: str | None = None,
    legend: bool = True,
) -> Axes:
    """Draw the intersection and the candidate paths on ``ax`` (a new Agg figure if None)."""
    if ax is None:
        fig = Figure(figsize=(7.0, 7.0), dpi=150)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
    ax.set_facecolor(BACKGROUND)

    for sw in junction.sidewalks:
        _add_area(ax, sw.polygon(), facecolor=SIDEWALK, edgecolor="none", zorder=1)
    for area in junction.walking_areas:
        _add_area(ax, area, facecolor=SIDEWALK, edgecolor="none", zorder=1)
    car_lanes = list(junction.lanes.values())
    road = [junction.polygon] + [lane.polygon() for lane in car_lanes]
    for geom in road:
        _add_area(ax, geom, facecolor=ASPHALT, edgecolor=ASPHALT, lw=0.3, zorder=2)
    for bike in junction.bike_lanes:
        _add_area(ax, bike.polygon(), facecolor=BIKE_LANE, edgecolor="none", zorder=2.5)
    for approach in junction.approaches:
        _add_area(ax, approach.median, facecolor=MEDIAN, edgecolor="#3d7a2c", lw=0.5, zorder=3)
    for crossing in junction.crossings:
        _draw_crossing(ax, np.asarray(crossing.centerline, float), crossing.width_m)
    _draw_markings(ax, car_lanes)
    for approach in junction.approaches:
        ax.plot(*np.asarray(approach.stop_line).T, color=MARKING, lw=2.5, zorder=5, solid_capstyle="butt")

    _draw_candidates(ax, candidates)
    x0, x1, y0, y1 = _view(junction, candidates)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title)
    if legend and candidates:
        ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    return ax


def save_intersection_figure(
    junction: Junction,
    candidates: Sequence[CandidatePath],
    path: str | Path,
    title: str | None = None,
    dpi: int = 150,
) -> Path:
    """Draw the intersection and the candidates and write the figure (PNG, SVG, PDF by suffix)."""
    ax = plot_intersection(junction, candidates, title=title)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig = ax.get_figure()
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    return out


def plot_speed_profiles(candidate: CandidatePath, path: str | Path | None = None) -> Figure:
    """The pass and stop speed references [km/h] against arc length, the stop line and exit marked.

    Writes the figure to ``path`` when given; returns it either way.
    """
    fig = Figure(figsize=(7.0, 3.2), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(candidate.s, candidate.v_pass * 3.6, label="pass mode", lw=1.8)
    ax.plot(candidate.s, candidate.v_stop * 3.6, label="stop mode", lw=1.8, ls="--")
    ax.set_ylim(bottom=0.0, top=max(math.ceil(float(candidate.v_pass.max()) * 3.6 / 5.0) * 5.0 + 5.0, 10.0))
    for s, name in ((candidate.s_stop_line, "stop line (X1)"), (candidate.s_exit, "exit (X4)")):
        ax.axvline(s, color="grey", lw=0.8, ls=":")
        ax.text(s, 1.0, f" {name}", rotation=90, va="bottom", fontsize=7)
    ax.set_xlabel("arc length s [m]")
    ax.set_ylabel("speed [km/h]")
    ax.set_title(f"{candidate.id}: {candidate.entrance_lane} → {candidate.exit_lane}")
    ax.legend(loc="lower left", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    if path is not None:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out)
    return fig
