# The two commands of the README. Both set up what they need first (scripts/setup.sh).
#   make serve [ARGS="--port 9000 --db postgresql://..."]   the studio on http://127.0.0.1:8000
#   make test  [PYTEST_ARGS="-k junction"]                   the whole test suite
.PHONY: serve test setup bench

serve:
	@bash scripts/setup.sh
	.venv/bin/crossroads serve $(ARGS)

test:
	@bash scripts/setup.sh --test
	.venv/bin/ruff check --quiet .
	.venv/bin/python -m pytest $(PYTEST_ARGS)

setup:
	@bash scripts/setup.sh --test
