"""The intersection figure (Agg, no display) writes real PNGs."""

from __future__ import annotations

from pathlib import Path

from crossroads.planning import plan_candidates
from crossroads.viz.figure import plot_intersection, plot_speed_profiles, save_intersection_figure
from planning.factories import four_way_junction

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_save_intersection_figure(tmp_path: Path) -> None:
    j = four_way_junction(n_lanes=3, median_m=2.0)
    cands = [c for task in ("left", "straight", "right") for c in plan_candidates(j, task)]
    out = save_intersection_figure(j, cands, tmp_path / "sub" / "fig.png", title="three lanes")
    data = out.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 20_000


def test_plot_without_candidates_and_on_given_axes(tmp_path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1)
    j = four_way_junction(n_lanes=1, leg_angles_deg=(-95.0, 5.0, 80.0, 185.0))
    assert plot_intersection(j, ax=ax, title="empty") is ax
    assert ax.get_aspect() == 1.0
    fig.savefig(tmp_path / "empty.png")
    assert (tmp_path / "empty.png").stat().st_size > 0


def test_speed_profiles(tmp_path: Path) -> None:
    (c,) = plan_candidates(four_way_junction(n_lanes=1), "right")
    plot_speed_profiles(c, tmp_path / "v.png")
    assert (tmp_path / "v.png").read_bytes().startswith(PNG_MAGIC)
