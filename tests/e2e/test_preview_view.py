"""The preview's view and the click that places the ego: zoom with the wheel (about the pointer)
and the +/- buttons, pan by dragging, reset; a click on an entrance lane sets the approach, the
lane and the start distance from where it falls (the task too when the lane does not lead the
one chosen), and the page says what it set; a drag that starts on a lane sets nothing."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from e2e.test_studio import _choose, _open, _save

pytestmark = pytest.mark.slow

EGO_LENGTH_M = 4.8  # the preview's drawn ego (frontend/src/preview.ts): a click is its centre
START_STEP_M = 0.5  # a clicked start distance is rounded to this

# The map's point under a client position, in the network's frame (SVG y is the network's −y).
MAP_POINT = """([x, y]) => {
  const p = new DOMPoint(x, y).matrixTransform(document.querySelector('#preview-map').getScreenCTM().inverse());
  return [p.x, -p.y]; }"""
# The client position of the point ``back`` metres before the end of an entrance lane.
LANE_POINT = """([lane, back]) => {
  const el = document.querySelector(`#preview .lane-target[data-lane="${lane}"]`);
  const pts = el.getAttribute('points').trim().split(/\\s+/).map(p => p.split(',').map(Number));
  let left = back;
  for (let i = pts.length - 1; i > 0; i--) {
    const [x1, y1] = pts[i], [x0, y0] = pts[i - 1];
    const seg = Math.hypot(x1 - x0, y1 - y0);
    if (left <= seg || i === 1) {
      const f = Math.min(left / seg, 1);
      const q = new DOMPoint(x1 - f * (x1 - x0), y1 - f * (y1 - y0)).matrixTransform(el.getScreenCTM());
      return [q.x, q.y];
    }
    left -= seg;
  }
}"""


def _scale(page: Any) -> float:
    transform = page.get_attribute("#preview-map", "transform")
    return float(re.search(r"scale\(([-\d.e]+)\)", transform).group(1))  # type: ignore[union-attr]


def _centre(page: Any) -> tuple[float, float]:
    """The client position of the map area's centre (below the caption strip)."""
    box = page.evaluate("""() => { const r = document.querySelector('#preview rect.ground').getBoundingClientRect();
        return [r.x + r.width / 2, r.y + r.height / 2]; }""")
    return float(box[0]), float(box[1])


def test_zoom_pan_and_click_to_place_the_ego(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, console_errors = _open(browser, studio_url)
    _choose(page, "b_two_lane", "left")
    page.locator("#preview rect.ego-start").wait_for()
    assert _scale(page) == 1 and page.inner_text("#preview-zoom") == "100 %"
    assert page.locator("#preview-reset").is_disabled()

    # the buttons zoom about the middle of the picture
    page.click("#preview-zoom-in")
    assert _scale(page) == pytest.approx(1.5) and page.inner_text("#preview-zoom") == "150 %"
    page.click("#preview-zoom-out")
    assert _scale(page) == pytest.approx(1.0)

    # the wheel zooms about the pointer: the map's point under it stays under it
    cx, cy = _centre(page)
    pointer = (cx + 60, cy - 40)
    page.mouse.move(*pointer)
    before = page.evaluate(MAP_POINT, list(pointer))
    page.mouse.wheel(0, -250)
    page.wait_for_function("document.querySelector('#preview-zoom').textContent !== '100 %'")
    assert _scale(page) > 1.5
    assert page.evaluate(MAP_POINT, list(pointer)) == pytest.approx(before, abs=0.05)
    assert page.locator("#preview-reset").is_enabled()

    # a drag pans: the point grabbed moves with the pointer
    grabbed = page.evaluate(MAP_POINT, [cx, cy])
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 40, cy + 30, steps=5)
    page.mouse.up()
    assert page.evaluate(MAP_POINT, [cx + 40, cy + 30]) == pytest.approx(grabbed, abs=0.05)
    assert page.input_value("input[name='ego.start_distance_m']") == "", "a drag places nothing"
    page.screenshot(path=str(artifacts / "33-preview-zoomed.png"), full_page=True)

    # reset: the whole intersection again
    page.click("#preview-reset")
    page.wait_for_function("document.querySelector('#preview-zoom').textContent === '100 %'")
    assert _scale(page) == 1 and page.locator("#preview-reset").is_disabled()

    # a click where a candidate path is drawn over the lane still reaches the lane
    x, y = page.evaluate(LANE_POINT, ["south_in_2", 8.0])
    assert page.evaluate("([x, y]) => document.elementFromPoint(x, y).classList.contains('candidate')", [x, y])
    page.mouse.click(x, y)
    page.wait_for_function("document.querySelector('#preview-status').textContent.includes('entrance lane south_in_2, start 5.5 m')")
    assert page.input_value("select[name=approach]") == "", "the default approach stays the default"
    assert page.input_value("select[name='ego.entrance_lane']") == "south_in_2"

    # zoomed in, a click 12 m before the stop line of a lane of another approach that leads left
    page.click("#preview-zoom-in")
    back = 12.0
    x, y = page.evaluate(LANE_POINT, ["east_in_2", back])
    page.mouse.click(x, y)
    expected = round((back - EGO_LENGTH_M / 2) / START_STEP_M) * START_STEP_M
    page.wait_for_function(f"document.querySelector('input[name=\"ego.start_distance_m\"]').value === '{expected:g}'")
    assert page.input_value("select[name=approach]") == "east_in"
    assert page.input_value("select[name=task]") == "left", "the lane leads left: the task stays"
    assert page.input_value("select[name='ego.entrance_lane']") == "east_in_2"
    status = page.inner_text("#preview-status")
    assert f"approach east_in, entrance lane east_in_2, start {expected:g} m before the stop line" in status
    assert "task" not in status
    ego = page.locator("#preview rect.ego-start title")
    page.wait_for_function(
        f"document.querySelector('#preview rect.ego-start title')?.textContent.includes('east_in_2, {expected:g} m')")
    assert _scale(page) == pytest.approx(1.5), "the view stays as the user set it"
    # the ego is drawn where the click fell
    box = page.locator("#preview rect.ego-start").bounding_box()
    assert box is not None and abs(box["x"] + box["width"] / 2 - x) < 4 and abs(box["y"] + box["height"] / 2 - y) < 4, (box, x, y)
    page.screenshot(path=str(artifacts / "34-preview-click-placed.png"), full_page=True)

    # a lane that does not lead left: the task follows the lane, and the page says so
    x, y = page.evaluate(LANE_POINT, ["north_in_1", 14.0])
    page.mouse.click(x, y)
    page.wait_for_function("document.querySelector('#preview-status').textContent.includes('north_in_1')")
    task = page.input_value("select[name=task]")
    assert task in ("right", "straight")
    assert f"task {task} (the lane leads right, straight)" in page.inner_text("#preview-status")
    assert page.input_value("select[name=approach]") == "north_in"
    assert page.input_value("input[name='ego.start_distance_m']") == f"{round((14 - EGO_LENGTH_M / 2) / START_STEP_M) * START_STEP_M:g}"
    assert ego.count() == 1

    # what the click set is what is saved
    page.fill("input[name=name]", "e2e-clicked-start")
    scenario_id = _save(page)
    spec = page.evaluate(f"fetch('/api/scenarios/{scenario_id}').then(r => r.json()).then(s => s.spec)")
    assert spec["approach"] == "north_in" and spec["task"] == task
    assert spec["ego"]["entrance_lane"] == "north_in_1" and spec["ego"]["start_distance_m"] == pytest.approx(11.5)
    assert not console_errors, console_errors
