"""Reloading the studio during a batch: the page reattaches to the running batch (progress bar,
Cancel), gives the form back as it was, and after the batch has ended shows it finished."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from e2e.test_studio import START_TIMEOUT_MS, _choose, _open, _save

pytestmark = pytest.mark.slow


def _row(page: Any, name: str) -> str:
    return f"[...document.querySelectorAll('#batches tr')].find(tr => tr.innerText.includes('{name}'))"


def test_reload_mid_batch_reattaches(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, console_errors = _open(browser, studio_url)
    _choose(page, "a_single_lane", "straight")
    page.fill("input[name=name]", "e2e-reload")
    for name, value in (("runs", "30"), ("warmup_s", "5"), ("timeout_s", "20")):
        page.fill(f"input[name={name}]", value)
    _save(page)
    page.click("#run")
    page.wait_for_function("document.querySelector('#progress-text').textContent.includes(' running')",
                           timeout=START_TIMEOUT_MS)
    batch_id = int(re.search(r"batch #(\d+)", page.inner_text("#progress-text")).group(1))  # type: ignore[union-attr]

    page.reload()
    page.wait_for_selector("#preview polyline.candidate", state="attached")  # straight: zero-width box
    # the running batch followed again: its bar, its progress and its Cancel button
    page.wait_for_function(
        f"document.querySelector('#progress-text').textContent.startsWith('batch #{batch_id} ')",
        timeout=START_TIMEOUT_MS)
    assert page.locator("#progress").is_visible()
    # the form as it was left (restored before the batch is followed again), not its defaults
    assert page.input_value("input[name=name]") == "e2e-reload"
    assert page.input_value("input[name=runs]") == "30"
    assert page.input_value("select[name=task]") == "straight"
    assert page.inner_text("#saved").startswith("Saved as scenario #")  # unedited since: still saved
    assert page.locator("#run").is_enabled()
    cancel = page.locator("#cancel")
    assert cancel.is_visible() and cancel.get_attribute("data-batch") == str(batch_id)
    page.screenshot(path=str(artifacts / "14-reloaded-running.png"), full_page=True)

    cancel.click()
    page.wait_for_selector("#progress-text[data-status=cancelled]", timeout=START_TIMEOUT_MS)
    # the list follows on its own: the row says cancelled and offers no Cancel any more
    page.wait_for_function(f"{_row(page, 'e2e-reload')}?.innerText.includes('cancelled')",
                           timeout=START_TIMEOUT_MS)
    assert page.evaluate(f"{_row(page, 'e2e-reload')}.querySelector('[data-cancel]')") is None

    # a reload after the end: shown finished, with its results, and nothing to cancel
    page.reload()
    page.wait_for_selector("#progress-text[data-status=cancelled]")
    assert page.inner_text("#progress-text").startswith(f"batch #{batch_id} cancelled — ")  # with its times
    assert cancel.is_hidden()
    page.wait_for_selector("#batch-status:has-text('cancelled')")
    page.screenshot(path=str(artifacts / "15-reloaded-finished.png"), full_page=True)
    assert not console_errors, console_errors
