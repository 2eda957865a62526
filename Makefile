# The two commands of the README. Both set up what they need first (scripts/setup.sh).
#   make serve [ARGS="--port 9000 --db postgresql://..."]   the studio on http://127.0.0.1:8000
#   make test  [PYTEST_ARGS="-k junction"]                   the whole test suite (what CI runs)
#   make test-fast                                           the suite without the tests marked slow
#   make docs                                                the user's guide, served on http://127.0.0.1:8001
#   make models [ITERATIONS=8000]                            train and export models/apg.pt, models/dpg.pt
#   make measure                                             measure them (var/measurements/)
.PHONY: serve test test-fast docs setup bench models measure

serve:
	@bash scripts/setup.sh
	.venv/bin/crossroads serve $(ARGS)

test:
	@bash scripts/setup.sh --test
	.venv/bin/ruff check --quiet .
	.venv/bin/python -m pytest $(PYTEST_ARGS)

test-fast:
	@bash scripts/setup.sh --test
	.venv/bin/ruff check --quiet .
	.venv/bin/python -m pytest -m "not slow" $(PYTEST_ARGS)

docs:
	@bash scripts/setup.sh
	NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs serve -a 127.0.0.1:8001

setup:
	@bash scripts/setup.sh --test

models:
	@bash scripts/setup.sh
	bash scripts/train_models.sh $(ITERATIONS)

measure:
	@bash scripts/setup.sh
	bash scripts/measure_models.sh
