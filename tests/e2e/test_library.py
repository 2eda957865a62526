"""The scenario library in headless chromium: a saved scenario listed, opened in the form and edited
in place, duplicated, downloaded and imported as YAML (a bad file refused with the field named),
deleted; "Show" on a batch loads its scenario into the form, read-only."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from e2e.test_studio import START_TIMEOUT_MS, _choose, _open, _save

pytestmark = pytest.mark.slow


def _row(page: Any, name: str) -> Any:
    return page.locator("#library tbody tr").filter(has=page.locator("td.name", has_text=re.compile(f"^{name}$")))


def test_scenario_library(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, console_errors = _open(browser, studio_url)
    _choose(page, "a_single_lane", "left")
    page.fill("input[name=name]", "e2e-lib")
    page.fill("input[name='traffic.vehicles_per_hour']", "123")
    page.check("input[name='overspeed.on']")
    page.fill("input[name='abnormal.overspeed.excess']", "30")
    page.check("input[name='injection.on']")
    page.fill("input[name='abnormal.injection.count']", "2")
    page.fill("input[name='abnormal.injection.arrive_s']", "6.5")
    page.fill("input[name='abnormal.injection.excess']", "40")
    page.fill("input[name=runs]", "3")
    sid = _save(page)
    _row(page, "e2e-lib").wait_for()
    assert page.request.get(f"{studio_url}/api/scenarios/{sid}").json()["spec"]["abnormal"]["injection"] == {
        "count": 2, "arrive_s": 6.5, "excess": 0.4, "headway_s": 2.0}

    # the form elsewhere, then the stored scenario opened in it again
    _choose(page, "a_single_lane", "straight")
    page.fill("input[name=name]", "something-else")
    page.fill("input[name='traffic.vehicles_per_hour']", "999")
    _row(page, "e2e-lib").locator("button[data-open]").click()
    page.wait_for_selector(f"#editing:has-text('Editing stored scenario #{sid}')")  # set once the form is filled
    assert page.input_value("input[name=name]") == "e2e-lib"
    assert page.input_value("select[name=task]") == "left"
    assert page.input_value("input[name='traffic.vehicles_per_hour']") == "123"
    assert page.is_checked("input[name='overspeed.on']")
    assert page.input_value("input[name='abnormal.overspeed.excess']") == "30"
    assert page.is_checked("input[name='injection.on']")
    assert (page.input_value("input[name='abnormal.injection.count']"),
            page.input_value("input[name='abnormal.injection.arrive_s']"),
            page.input_value("input[name='abnormal.injection.excess']")) == ("2", "6.5", "40")
    assert not page.locator("#run").is_disabled(), "the stored scenario, unedited: it can run"
    page.screenshot(path=str(artifacts / "20-library-opened.png"), full_page=True)

    # edited in place: the same id, the new value stored
    page.fill("input[name=runs]", "4")
    assert _save(page) == sid
    assert page.request.get(f"{studio_url}/api/scenarios/{sid}").json()["spec"]["runs"] == 4
    page.wait_for_function(
        "[...document.querySelectorAll('#library tbody tr')].some(tr => tr.cells[1].textContent === 'e2e-lib'"
        " && tr.cells[4].textContent === '4')")

    # duplicated: a new row, opened in the form
    _row(page, "e2e-lib").locator("button[data-duplicate]").click()
    _row(page, "e2e-lib-copy").wait_for()
    page.wait_for_function("document.querySelector('input[name=name]').value === 'e2e-lib-copy'")

    # downloaded as YAML, imported again under another name
    with page.expect_download() as download:
        _row(page, "e2e-lib").locator("a", has_text="YAML").click()
    text = Path(download.value.path()).read_text()
    spec = yaml.safe_load(text)
    assert spec["name"] == "e2e-lib" and spec["traffic"]["vehicles_per_hour"] == 123 and spec["runs"] == 4
    spec["name"] = "e2e-lib-imported"
    page.set_input_files("#library-file", {"name": "imported.yaml", "mimeType": "application/yaml",
                                           "buffer": yaml.safe_dump(spec).encode()})
    page.click("#library-import")
    page.wait_for_selector("#library-status:has-text('Imported imported.yaml')")
    _row(page, "e2e-lib-imported").wait_for()
    assert page.input_value("input[name=name]") == "e2e-lib-imported"
    spec["runs"] = 0
    page.set_input_files("#library-file", {"name": "bad.yaml", "mimeType": "application/yaml",
                                           "buffer": yaml.safe_dump(spec).encode()})
    page.click("#library-import")
    page.wait_for_selector("#library-status.error:has-text('Not imported')")
    assert "runs:" in page.inner_text("#library-status")

    # deleted (a second click confirms)
    delete = _row(page, "e2e-lib-copy").locator("button[data-delete]")
    delete.click()
    assert delete.inner_text() == "Really delete?"
    delete.click()
    page.wait_for_selector("#library-status:has-text('Deleted scenario')")
    assert _row(page, "e2e-lib-copy").count() == 0
    page.screenshot(path=str(artifacts / "21-library.png"), full_page=True)

    # "Show" on a batch: its scenario in the form, read-only (batches ran it)
    batch = page.request.post(f"{studio_url}/api/batches", data={"scenario_id": sid, "policy": "rule", "runs": 1})
    assert batch.status == 202, batch.text()
    batch_id = batch.json()["id"]
    page.request.post(f"{studio_url}/api/batches/{batch_id}/cancel")
    page.fill("input[name=name]", "unrelated")
    page.click("#refresh")
    page.locator(f"#batches button[data-batch='{batch_id}']").click()
    page.wait_for_selector(f"#editing:has-text('From stored scenario #{sid} (e2e-lib)')", timeout=START_TIMEOUT_MS)
    assert page.input_value("input[name=name]") == "e2e-lib"
    page.click("#library-refresh")
    page.wait_for_function(
        "[...document.querySelectorAll('#library tbody tr')].find(tr => tr.cells[1].textContent === 'e2e-lib')"
        "?.querySelector('button[data-delete]').disabled")
    assert not console_errors, console_errors
