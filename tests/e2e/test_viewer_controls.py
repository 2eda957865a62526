"""The 3D view's controls in the studio page, in headless chromium: keyboard (space play/pause,
arrows step, + and − speed), the View folder (camera modes, layer toggles, legend) and the
jump-to-event list, on an episode's playback served through the studio's own port."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from e2e.test_studio import CHARTS_JS, START_TIMEOUT_MS, _open, _viewer_frame

pytestmark = pytest.mark.slow

BATCH_TIMEOUT_S = 150.0
SCENARIO = {
    "version": 1, "name": "e2e-viewer-keys", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 300, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 12.0, "runs": 1, "seed": 5,
}
SPEED_MARKER = "(c) => c.label.startsWith('speed [')"


def _episode(page: Any, studio_url: str) -> int:
    sid = page.request.post(f"{studio_url}/api/scenarios", data=SCENARIO).json()["id"]
    made = page.request.post(f"{studio_url}/api/batches",
                             data={"scenario_id": sid, "policy": "rule", "workers": 1, "traces": "all"})
    assert made.status == 202, made.text()
    batch_id = int(made.json()["id"])
    deadline = time.monotonic() + BATCH_TIMEOUT_S
    while (status := page.request.get(f"{studio_url}/api/batches/{batch_id}").json()["status"]) != "done":
        assert status not in ("failed", "cancelled") and time.monotonic() < deadline, status
        time.sleep(1.0)
    return batch_id


def _now(viewer: Any) -> int:
    return int(viewer.evaluate(f"({CHARTS_JS})().find({SPEED_MARKER}).now"))


def test_keyboard_view_controls_and_events(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, console_errors = _open(browser, studio_url)
    batch_id = _episode(page, studio_url)
    page.reload()
    page.wait_for_selector(f"#batches button[data-batch='{batch_id}']")
    page.click(f"#batches button[data-batch='{batch_id}']")
    page.locator("#episodes a.playback").first.click()
    viewer = _viewer_frame(page, studio_url, "playback")
    viewer.wait_for_function(f"({CHARTS_JS})().length === 4", timeout=START_TIMEOUT_MS)
    assert _now(viewer) == 0

    # the keys act while the pointer is over the view
    page.hover("#viewer-title")
    for frame in (1, 2, 3):  # at a person's pace: each step shown before the next key
        page.keyboard.press("ArrowRight")
        viewer.wait_for_function(f"({CHARTS_JS})().find({SPEED_MARKER}).now === {frame}", timeout=20_000)
    page.keyboard.press("ArrowLeft")
    viewer.wait_for_function(f"({CHARTS_JS})().find({SPEED_MARKER}).now === 2", timeout=20_000)
    page.keyboard.press("+")
    viewer.wait_for_selector("text=/paused 2×/", timeout=20_000)
    page.keyboard.press("-")
    page.keyboard.press("-")
    viewer.wait_for_selector("text=/paused 0.5×/", timeout=20_000)
    page.keyboard.press(" ")
    viewer.wait_for_selector("button:has-text('Pause')", timeout=20_000)
    viewer.wait_for_function(f"({CHARTS_JS})().find({SPEED_MARKER}).now > 2", timeout=20_000)
    page.keyboard.press(" ")
    viewer.wait_for_selector("button:has-text('Play')", timeout=20_000)
    assert page.get_attribute("#viewer-frame", "data-last-key") == " "
    # typing in a field of the page is not a key for the player
    page.hover("#editor")
    page.focus("input[name=name]")
    before = _now(viewer)
    page.keyboard.press("ArrowRight")
    time.sleep(0.5)
    assert _now(viewer) == before

    # the View folder: camera modes, layers, legend; the events to jump to
    for text in ("Camera", "Sensors", "Candidate paths", "Traffic", "Labels", "hit by the ego",
                 "where the ego collided", "Jump to event", "Speed ±"):
        assert viewer.get_by_text(text, exact=False).count() >= 1, text
    page.locator("#viewer-panel").screenshot(path=str(artifacts / "43-viewer-controls.png"))
    assert not console_errors, console_errors
