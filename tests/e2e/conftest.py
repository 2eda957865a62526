"""End-to-end fixtures: a real `crossroads serve` in a subprocess (temp data dir, free port) and a
headless Debian chromium driven by Playwright. Skipped where chromium, Playwright or the built
page are missing."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import REPO_ROOT

CHROMIUM = os.environ.get("CROSSROADS_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ARTIFACTS = REPO_ROOT / "test-artifacts" / "e2e"
START_TIMEOUT_S = 60.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="session")
def artifacts() -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS


def free_port() -> int:
    return _free_port()


def launch_studio(data_dir: Path, port: int, *args: str, log_name: str = "serve.log") -> subprocess.Popen[bytes]:
    """Start `crossroads serve` on ``port`` over ``data_dir`` (extra CLI ``args``) and wait until it
    answers /api/health; its output goes to ``data_dir / log_name``."""
    if not (REPO_ROOT / "frontend" / "dist" / "index.html").is_file():
        # a failure, not a skip: `make test` builds it, so a missing build is a broken set-up
        pytest.fail("frontend/dist is not built (scripts/setup.sh builds it)")
    env = {**os.environ, "CROSSROADS_DATA_DIR": str(data_dir)}
    with (data_dir / log_name).open("ab") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "crossroads.cli", "serve", "--host", "127.0.0.1", "--port", str(port), *args],
            env=env, stdout=log, stderr=subprocess.STDOUT, cwd=REPO_ROOT)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        if proc.poll() is not None:
            pytest.fail(f"crossroads serve exited ({proc.returncode}):\n"
                        + (data_dir / log_name).read_text(errors="replace"))
        try:
            with urllib.request.urlopen(f"{url}/api/health", timeout=2) as res:
                if res.status == 200:
                    return proc
        except OSError:
            pass
        if time.monotonic() > deadline:
            stop_studio(proc)
            pytest.fail("crossroads serve did not answer /api/health in time")
        time.sleep(0.3)


def stop_studio(proc: subprocess.Popen[bytes]) -> int:
    """Stop a studio as a service manager does (SIGTERM: its shutdown runs), killing it only if it
    hangs; its exit status."""
    proc.terminate()
    try:
        return proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


@pytest.fixture(scope="session")
def studio_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Base URL of a running studio with an empty temp data directory."""
    data_dir = tmp_path_factory.mktemp("studio-data")
    port = _free_port()
    proc = launch_studio(data_dir, port)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        stop_studio(proc)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(data_dir / "serve.log", ARTIFACTS / "serve.log")  # kept for a failed run


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    try:
        from playwright import sync_api
    except ImportError:
        pytest.fail("playwright is not installed (scripts/setup.sh --test installs it)")
    if not Path(CHROMIUM).is_file():
        pytest.fail(f"no chromium at {CHROMIUM} (scripts/setup.sh --test installs Debian's chromium)")
    with sync_api.sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            yield chromium
        finally:
            chromium.close()
