#!/usr/bin/env bash
# Rewrites requirements.lock from the current virtual environment.
set -euo pipefail
cd "$(dirname "$0")/.."
{
  echo "# Exact pins of every Python package Crossroads installs (make setup). Regenerate with"
  echo "# scripts/lock.sh after changing backend/pyproject.toml. torch is the CPU build (find-links /opt/wheels)."
  .venv/bin/pip freeze --exclude-editable | sed 's#^torch @ .*#torch==2.13.0#'
} > requirements.lock
