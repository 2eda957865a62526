#!/usr/bin/env bash
# Measure the shipped models/apg.pt and models/dpg.pt the way models/README.md reports them.
#
#   bash scripts/measure_models.sh            (about 6 min on 2 cores; 12 min on a slower host)
#   make measure
#
# Writes into var/measurements/ (OUT=DIR to change):
#   nominal-left-200.json      APG, DPG and the rule controller, 200 seeded nominal left turns on
#                              c_three_lane, Wilson intervals
#   tracking-{apg,dpg}.txt     no traffic, every candidate path of the six intersections
#   failure-modes-{apg,dpg}.txt  50 of those runs: collisions classified, the model's view before them
#   adversary-strength-apg.txt whether APG's adversary leaves the driving policy a safe plan
#   value-ordering-{apg,dpg}.txt whether the value network picks the path the model rates best
#   queue-response.txt         whether each model stops for a single car standing ahead (no traffic)
# The batches go to a scratch SQLite store (DB=URL to keep them elsewhere). MODELS="apg" re-measures
# the per-model files of APG alone (after retraining one model); the 200-run batch always runs all three.
set -euo pipefail
cd "$(dirname "$0")/.."

OUT="${OUT:-var/measurements}"
DB="${DB:-sqlite:///var/measure.db}"
WORKERS="${WORKERS:-2}"
MODELS="${MODELS:-apg dpg}"
SCENARIO=scenarios/nominal/c_three_lane-left.yaml
PY=.venv/bin/python
CROSSROADS=.venv/bin/crossroads
[ -x "$CROSSROADS" ] || bash scripts/setup.sh
mkdir -p var "$OUT"

"$CROSSROADS" evaluate "$SCENARIO" --policy models/apg.pt --policy models/dpg.pt --policy rule --runs 200 \
    --workers "$WORKERS" --db "$DB" --traces none --json > "$OUT/nominal-left-200.json"
for algo in $MODELS; do
    "$PY" benchmarks/tracking.py --policy "models/$algo.pt" > "$OUT/tracking-$algo.txt"
    "$PY" benchmarks/research/failure_modes.py "$SCENARIO" --policy "models/$algo.pt" --runs 50 > "$OUT/failure-modes-$algo.txt"
    "$PY" benchmarks/research/value_ordering.py "$SCENARIO" --policy "models/$algo.pt" > "$OUT/value-ordering-$algo.txt"
done
if [[ " $MODELS " == *" apg "* ]]; then
    "$PY" benchmarks/research/adversary_strength.py "$SCENARIO" --policy models/apg.pt > "$OUT/adversary-strength-apg.txt"
fi
"$PY" benchmarks/research/queue_response.py --policy models/apg.pt --policy models/dpg.pt > "$OUT/queue-response.txt"
echo "measurements written to $OUT/"
