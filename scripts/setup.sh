#!/usr/bin/env bash
# Everything a fresh machine needs to run Crossroads and its tests. Idempotent and quick when
# nothing changed: each step checks before it installs.
#   scripts/setup.sh            Python environment (.venv) + the crossroads package
#   scripts/setup.sh --test     also the system tools the tests use (docker-compose for checking
#                               the compose file) and a running PostgreSQL
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
want_test_tools=0
[ "${1:-}" = "--test" ] && want_test_tools=1

log() { printf '\033[1m[setup]\033[0m %s\n' "$*"; }

# --- Debian packages --------------------------------------------------------------------------
apt_packages=()
if [ "$want_test_tools" = 1 ]; then
  command -v docker-compose >/dev/null 2>&1 || apt_packages+=(docker-compose)
  [ -x /usr/bin/chromium ] || apt_packages+=(chromium)  # the end-to-end tests (Playwright)
fi
if [ ${#apt_packages[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    log "installing Debian packages: ${apt_packages[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq --no-install-recommends "${apt_packages[@]}" >/dev/null
  else
    log "missing Debian packages (install them as root): ${apt_packages[*]}"
  fi
fi

# --- Python environment -----------------------------------------------------------------------
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  log "creating .venv"
  "$PY" -m venv .venv
fi
stamp=.venv/.crossroads-lock.sha256
lock_hash=$(cat requirements.lock backend/pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$lock_hash" ]; then
  log "installing pinned Python packages (requirements.lock)"
  .venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.lock
  .venv/bin/python -m pip install -q --disable-pip-version-check --no-deps -e backend
  echo "$lock_hash" > "$stamp"
fi

PLAYWRIGHT_VERSION=1.65.2  # drives the Debian chromium in tests/e2e (no `playwright install`)
if [ "$want_test_tools" = 1 ] && ! .venv/bin/python -c "import playwright.sync_api" 2>/dev/null; then
  log "installing playwright $PLAYWRIGHT_VERSION (end-to-end tests)"
  .venv/bin/python -m pip install -q --disable-pip-version-check "playwright==$PLAYWRIGHT_VERSION"
fi

# --- The studio page (frontend/ -> frontend/dist, served at /) ----------------------------------
if command -v npm >/dev/null 2>&1; then
  front_stamp=frontend/node_modules/.crossroads-build.sha256
  front_hash=$(cd frontend && find package.json package-lock.json index.html vite.config.js src -type f \
                 -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)
  if [ ! -f frontend/dist/index.html ] || [ ! -f "$front_stamp" ] || [ "$(cat "$front_stamp")" != "$front_hash" ]; then
    log "building the studio page (npm ci && npm run build)"
    (cd frontend && npm ci --no-audit --no-fund --loglevel=error && npm run build --silent)
    echo "$front_hash" > "$front_stamp"
  fi
else
  log "npm not found: the studio page is not built (the API still runs; install Node.js 20+)"
fi

# --- Services for the tests -------------------------------------------------------------------
if [ "$want_test_tools" = 1 ]; then
  if command -v pg_lsclusters >/dev/null 2>&1; then
    if ! pg_isready -h 127.0.0.1 -p 5432 -q 2>/dev/null; then
      log "starting PostgreSQL"
      pg_ctlcluster --skip-systemctl-redirect "$(ls /etc/postgresql | head -n1)" main start || true
    fi
  fi
fi
log "ready ($ROOT)"
