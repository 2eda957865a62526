"""docker-compose.yml is accepted by docker-compose's offline check (no engine needed)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from support import REPO_ROOT


def test_compose_file_is_valid() -> None:
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.fail("docker-compose is not installed: scripts/setup.sh --test installs it")
    result = subprocess.run(
        [exe, "-f", str(REPO_ROOT / "docker-compose.yml"), "config", "-q"],
        capture_output=True, text=True, cwd=REPO_ROOT,
    )
    assert result.returncode == 0, result.stderr


def test_compose_has_the_agreed_services() -> None:
    import yaml

    services = yaml.safe_load((REPO_ROOT / "docker-compose.yml").read_text())["services"]
    assert {"api", "db", "ray-head", "ray-worker"} <= set(services)
