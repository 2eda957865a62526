"""Two chosen batches compared in headless chromium (pass-rate chart with intervals, the paired
table with McNemar, the per-seed differences), their reports linked from the page, a batch's
episodes sorted and filtered with a trace downloaded; the dark theme and the layout from a laptop
to a wide screen."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from e2e.test_studio import _open

pytestmark = pytest.mark.slow

BATCH_TIMEOUT_S = 150.0
SCENARIO = {
    "version": 1, "name": "e2e-compare", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 300, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 15.0, "runs": 3, "seed": 11,
}


def _finished_batches(page: Any, studio_url: str) -> tuple[int, int]:
    """Two batches of one scenario on the same seeds, by the rule policy and SUMO's own driver."""
    sid = page.request.post(f"{studio_url}/api/scenarios", data=SCENARIO).json()["id"]
    ids = []
    for policy in ("rule", "sumo"):
        made = page.request.post(f"{studio_url}/api/batches",
                                 data={"scenario_id": sid, "policy": policy, "workers": 1, "traces": "all"})
        assert made.status == 202, made.text()
        ids.append(made.json()["id"])
    deadline = time.monotonic() + BATCH_TIMEOUT_S
    for batch_id in ids:
        while (status := page.request.get(f"{studio_url}/api/batches/{batch_id}").json()["status"]) != "done":
            assert status not in ("failed", "cancelled") and time.monotonic() < deadline, (batch_id, status)
            time.sleep(1.0)
    return ids[0], ids[1]


def test_compare_two_chosen_batches_and_their_reports(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, console_errors = _open(browser, studio_url)
    a, b = _finished_batches(page, studio_url)
    page.click("#refresh")
    page.locator(f"#batches input[data-pick='{a}']").wait_for()
    assert page.locator("#compare-picked").is_disabled()
    page.check(f"#batches input[data-pick='{a}']")
    page.check(f"#batches input[data-pick='{b}']")
    assert page.inner_text("#picked-count") == f"2 picked: #{a}, #{b}"
    page.click("#compare-picked")
    page.wait_for_selector("#compare-chart circle.rate")
    assert page.locator("#compare-chart circle.rate").count() == 2
    assert page.locator("#compare-chart line.interval").count() == 6  # a bar and its two ends, each
    pair = page.locator(f".pair[data-a='{a}'][data-b='{b}']")
    cells = pair.locator("table.paired tbody td").all_inner_texts()
    assert cells[0] == "3", cells  # three shared seeds
    assert int(cells[3]) + int(cells[4]) + int(cells[5]) + int(cells[6]) == 3
    assert 0.0 < float(cells[7]) <= 1.0, "the exact McNemar p"
    assert pair.locator("table.seeds tbody tr").count() == 3
    page.locator("#picked-compare").screenshot(path=str(artifacts / "30-comparison.png"))

    # the report of the picked batches, HTML and CSV, from the links the page gives
    html = page.request.get(studio_url + page.get_attribute("#picked-report-html", "href"))
    assert html.status == 200 and "e2e-compare" in html.text() and "McNemar" in html.text()
    csv = page.request.get(studio_url + page.get_attribute("#picked-report-csv", "href"))
    assert csv.status == 200 and csv.headers["content-type"].startswith("text/csv")
    assert csv.text().count("e2e-compare") == 2

    # one batch shown: its own report links, its episodes sorted and filtered, a trace downloaded
    page.locator(f"#batches button[data-batch='{a}']").click()
    page.wait_for_selector("#report-html")
    assert page.get_attribute("#report-html", "href") == f"/api/reports?batch={a}"
    assert page.request.get(studio_url + page.get_attribute("#report-csv", "href")).status == 200
    page.wait_for_selector("#episodes tbody tr")
    seeds = lambda: [int(t) for t in page.locator("#episodes tbody tr td:nth-child(2)").all_inner_texts()]  # noqa: E731
    sort_by_seed(page, "ascending")
    assert seeds() == sorted(seeds())
    sort_by_seed(page, "descending")
    assert seeds() == sorted(seeds(), reverse=True) and len(seeds()) == 3
    assert page.get_attribute("#episodes th[data-sort=seed]", "aria-sort") == "descending"
    first_seed = seeds()[0]
    page.fill("#ep-seed", str(first_seed))
    assert seeds() == [first_seed] and page.inner_text("#ep-count") == "1 of 3 episodes"
    # the same batch shown again (as at its end, or its Show clicked): rows updated in place, the
    # filter typed in and the sorting kept, the header not replaced under a click
    shown_before = page.get_attribute("#episodes", "data-shown")
    page.locator(f"#batches button[data-batch='{a}']").click()
    page.wait_for_function(f"document.querySelector('#episodes').dataset.shown !== '{shown_before}'")
    assert page.input_value("#ep-seed") == str(first_seed) and seeds() == [first_seed]
    assert page.get_attribute("#episodes th[data-sort=seed]", "aria-sort") == "descending"
    page.fill("#ep-seed", "")
    outcome = page.locator("#episodes tbody tr td.outcome").first.inner_text()
    page.select_option("#ep-outcome", outcome)
    shown = page.locator("#episodes tbody tr td.outcome").all_inner_texts()
    assert shown and set(shown) == {outcome}
    page.select_option("#ep-outcome", "")
    page.fill("#ep-gap-max", "-1000")  # nobody is that close: nothing left
    assert page.locator("#episodes tbody tr").count() == 0
    page.fill("#ep-gap-max", "")
    page.click("#episodes th[data-sort=min_gap_m]")
    assert page.locator("#episodes tbody tr").count() == 3
    trace = page.request.get(studio_url + page.get_attribute("#episodes a.trace", "href"))
    assert trace.status == 200 and "frames" in trace.json()
    page.locator("#results").screenshot(path=str(artifacts / "31-episodes-sorted.png"))
    assert not console_errors, console_errors


@pytest.mark.parametrize(("scheme", "width", "height"), [("dark", 1280, 800), ("light", 2560, 1300), ("dark", 820, 1000)])
def test_theme_and_layout(studio_url: str, browser: Any, artifacts: Path, scheme: str, width: int, height: int) -> None:
    page = browser.new_page(viewport={"width": width, "height": height}, color_scheme=scheme)
    page.goto(studio_url + "/")
    page.wait_for_selector("#preview polyline.candidate")
    background = page.evaluate("getComputedStyle(document.body).backgroundColor")
    channels = [int(c) for c in background[background.index("(") + 1:background.index(")")].split(",")[:3]]
    assert (sum(channels) / 3 < 60) == (scheme == "dark"), background
    overflow = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
    assert overflow <= 0, f"the page is {overflow} px wider than a {width} px window"
    editor, preview = page.locator("#editor").bounding_box(), page.locator("#preview-panel").bounding_box()
    side_by_side = preview["x"] > editor["x"] + editor["width"] - 1
    assert side_by_side == (width > 900), (editor, preview)
    page.screenshot(path=str(artifacts / f"32-{scheme}-{width}.png"))
    page.close()


def sort_by_seed(page: Any, direction: str) -> None:
    """Click the seed column's title once; the table says it is sorted ``direction``."""
    header = "#episodes th[data-sort=seed]"
    page.click(header)
    page.wait_for_function(
        f"document.querySelector('{header}')?.getAttribute('aria-sort') === '{direction}'", timeout=5000)
