"""A batch across a server restart, end to end: its progress says elapsed time, rate and ETA; the
server is stopped mid-batch and started again (resuming turned off, as when another process shares
the store); the reloaded page shows the batch ``interrupted`` (not running forever) with a Resume
button (the open page notices by itself once the server answers again), and Resume goes on from
the runs already recorded, with its progress and ETA again."""

from __future__ import annotations

import json
import re
import shutil
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from e2e.conftest import ARTIFACTS, free_port, launch_studio, stop_studio
from e2e.test_studio import START_TIMEOUT_MS, _choose, _open, _save

pytestmark = pytest.mark.slow

ETA_RE = r"runs, \d+ passed, \d+ errors — (\d+ s|\d+ min \d+ s) elapsed · [\d.]+ runs/min · about .+ left"


def _progress_matches(page: Any, pattern: str, timeout_ms: int = START_TIMEOUT_MS) -> None:
    """Wait until the progress line matches the regular expression ``pattern``."""
    page.wait_for_function(
        f"new RegExp({json.dumps(pattern)}).test(document.querySelector('#progress-text').textContent)",
        timeout=timeout_ms)


def _batch(url: str, batch_id: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"{url}/api/batches/{batch_id}", timeout=10) as res:
        return json.loads(res.read())  # type: ignore[no-any-return]


def test_progress_survives_a_restart_and_an_interrupted_batch_resumes(
        browser: Any, tmp_path: Path, artifacts: Path) -> None:
    data_dir, port = tmp_path / "data", free_port()
    data_dir.mkdir()
    url = f"http://127.0.0.1:{port}"
    server = launch_studio(data_dir, port, "--no-resume-batches", log_name="serve-restart.log")
    try:
        page, console_errors = _open(browser, url)
        _choose(page, "a_single_lane", "straight")
        page.fill("input[name=name]", "e2e-restart")
        for name, value in (("runs", "200"), ("warmup_s", "30"), ("timeout_s", "20")):
            page.fill(f"input[name={name}]", value)
        _save(page)
        page.click("#run")
        # elapsed time, rate and ETA once the first runs are recorded
        _progress_matches(page, ETA_RE, START_TIMEOUT_MS * 2)
        text = page.inner_text("#progress-text")
        batch_id = int(re.search(r"batch #(\d+)", text).group(1))  # type: ignore[union-attr]
        page.wait_for_function("document.querySelector('#batches')?.innerText.includes('left)')")
        page.screenshot(path=str(artifacts / "40-progress-eta.png"), full_page=True)

        # a reload reattaches with the same figures (they come from the store)
        page.reload()
        _progress_matches(page, f"batch #{batch_id} running: .*{ETA_RE}")

        # uvicorn runs the app's shutdown, then re-raises SIGTERM: -15 is a clean stop too
        assert stop_studio(server) in (0, -15)
        assert "Application shutdown complete" in (data_dir / "serve-restart.log").read_text()
        before = _batch_stopped(data_dir, batch_id)
        server = launch_studio(data_dir, port, "--no-resume-batches", log_name="serve-restart.log")
        body = _batch(url, batch_id)
        assert body["status"] == "interrupted" and body["progress"]["done"] == before, body
        assert "server stopped" in body["error"]

        # the open page finds the server again by itself and says what became of the batch
        page.wait_for_selector("#progress-text[data-status=interrupted]", timeout=START_TIMEOUT_MS)
        assert page.locator("#resume").is_visible()
        page.reload()  # and so does a reloaded one
        page.wait_for_selector("#progress-text[data-status=interrupted]", timeout=START_TIMEOUT_MS)
        line = page.inner_text("#progress-text")
        assert line.startswith(f"batch #{batch_id} interrupted: {before}/200 runs recorded — interrupted:"), line
        resume = page.locator("#resume")
        assert resume.is_visible() and page.locator("#cancel").is_hidden()
        row = f"[...document.querySelectorAll('#batches tr')].find(tr => tr.dataset.id === '{batch_id}')"
        assert page.evaluate(f"{row}.querySelector('.status').innerText") == "interrupted"
        assert page.evaluate(f"!!{row}.querySelector('[data-resume]')")
        page.screenshot(path=str(artifacts / "41-interrupted.png"), full_page=True)

        resume.click()
        _progress_matches(page, f"batch #{batch_id} running: \\d+/200 runs")
        _progress_matches(page, ETA_RE, START_TIMEOUT_MS * 2)
        done = int(re.search(r"running: (\d+)/200", page.inner_text("#progress-text")).group(1))  # type: ignore[union-attr]
        assert done > before, "resumed from the runs recorded, and going on"
        assert resume.is_hidden() and page.locator("#cancel").is_visible()
        page.screenshot(path=str(artifacts / "42-resumed.png"), full_page=True)
        page.click("#cancel")
        page.wait_for_selector("#progress-text[data-status=cancelled]", timeout=START_TIMEOUT_MS)
        assert not console_errors, console_errors
    finally:
        stop_studio(server)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(data_dir / "serve-restart.log", ARTIFACTS / "serve-restart.log")


def _batch_stopped(data_dir: Path, batch_id: int) -> int:
    """The runs of the batch recorded when the server stopped (read from the store directly)."""
    from crossroads.settings import Settings
    from crossroads.store import crud, open_store

    with open_store(Settings(data_dir=data_dir).database_url) as store, store.session() as session:
        batch = crud.get_batch(session=session, batch_id=batch_id)
        assert batch is not None and batch.status == "interrupted", batch and batch.status
        return sum(crud.outcome_counts(session=session, batch_id=batch_id).values())
