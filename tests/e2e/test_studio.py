"""The studio end to end in headless chromium: author a scenario with an over-speed injection in
the page, save it, run a small batch, see its pass rate, open an episode's 3D playback."""

from __future__ import annotations

import re
import urllib.request
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.slow

BATCH_TIMEOUT_MS = 100_000  # two short episodes on a loaded 2-core machine


def test_author_run_and_play_back(studio_url: str, browser: Any, artifacts: Path) -> None:
    page = browser.new_page(viewport={"width": 1400, "height": 1100})
    console_errors: list[str] = []
    page.on("pageerror", lambda exc: console_errors.append(str(exc)))
    page.goto(studio_url + "/")
    page.wait_for_selector("#preview polyline.candidate")  # intersections loaded, paths drawn

    page.select_option("select[name=intersection]", "a_single_lane")
    page.select_option("select[name=task]", "left")
    page.wait_for_function(
        "document.querySelector('#preview text')?.textContent.includes('a_single_lane · left')")
    assert page.locator("#preview polyline.candidate").count() >= 1
    page.screenshot(path=str(artifacts / "01-preview.png"), full_page=True)

    # A bad value first: the 422 is shown next to its field.
    page.fill("input[name=name]", "e2e-overspeed")
    page.check("input[name='overspeed.on']")
    page.fill("input[name='abnormal.overspeed.share']", "1.5")
    page.click("#save")
    error = page.locator(".field-error[data-for='abnormal.overspeed.share']")
    error.wait_for()
    assert "1" in error.inner_text()
    page.screenshot(path=str(artifacts / "02-field-error.png"), full_page=True)

    page.fill("input[name='abnormal.overspeed.share']", "0.5")
    page.fill("input[name='abnormal.overspeed.excess']", "50")
    page.fill("input[name=runs]", "2")
    page.fill("input[name=seed]", "7")
    page.fill("input[name=warmup_s]", "5")
    page.fill("input[name=timeout_s]", "20")
    page.click("#save")
    page.wait_for_selector("#saved:has-text('Saved as scenario')")
    assert page.locator(".field-error").count() == 0
    page.screenshot(path=str(artifacts / "03-saved.png"), full_page=True)

    # The stored scenario carries the injection authored in the page.
    scenario_id = int(re.search(r"#(\d+)", page.inner_text("#saved")).group(1))  # type: ignore[union-attr]
    stored = page.request.get(f"{studio_url}/api/scenarios/{scenario_id}").json()["spec"]
    assert stored["abnormal"]["overspeed"] == {"share": 0.5, "excess": 0.5}
    assert stored["runs"] == 2

    page.select_option("#policy", "rule")
    page.click("#run")
    page.wait_for_selector("#progress:not([hidden])")
    page.screenshot(path=str(artifacts / "04-running.png"), full_page=True)
    page.wait_for_selector("#pass-rate", timeout=BATCH_TIMEOUT_MS)
    assert re.fullmatch(r"\d+\.\d %", page.inner_text("#pass-rate"))
    assert page.inner_text("#wilson").startswith("[")
    assert page.locator("#episodes tbody tr").count() == 2
    page.wait_for_selector("#compare table.compare")
    page.screenshot(path=str(artifacts / "05-results.png"), full_page=True)

    link = page.locator("#episodes a.playback").first
    href = link.get_attribute("href")
    assert href and href.startswith("/api/playback/")
    with page.context.expect_page() as opened:
        link.click()
    viewer = opened.value
    viewer.wait_for_load_state("load", timeout=60_000)
    assert re.match(r"http://127\.0\.0\.1:\d+/", viewer.url)
    with urllib.request.urlopen(viewer.url, timeout=10) as res:
        assert res.status == 200
    viewer.wait_for_selector("canvas", state="attached", timeout=60_000)
    viewer.wait_for_timeout(3000)  # let the scene arrive over the websocket before the picture
    viewer.screenshot(path=str(artifacts / "06-playback.png"))
    viewer.close()
    assert not console_errors, console_errors
