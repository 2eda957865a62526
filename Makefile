# The two commands of the README. Both set up what they need first (scripts/setup.sh).
#   make serve [ARGS="--port 9000 --db postgresql://..."]   the studio on http://127.0.0.1:8000
#   make test  [PYTEST_ARGS="-k junction"]                   the whole test suite
#   make models [ITERATIONS=8000]                            train and export models/apg.pt, models/dpg.pt
#   make measure                                             measure them (docs/measurements/)
.PHONY: serve test setup bench models measure

serve:
	@bash scripts/setup.sh
	.venv/bin/crossroads serve $(ARGS)

test:
	@bash scripts/setup.sh --test
	.venv/bin/ruff check --quiet .
	.venv/bin/python -m pytest $(PYTEST_ARGS)

setup:
	@bash scripts/setup.sh --test

models:
	@bash scripts/setup.sh
	bash scripts/train_models.sh $(ITERATIONS)

measure:
	@bash scripts/setup.sh
	bash scripts/measure_models.sh
