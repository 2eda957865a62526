#!/usr/bin/env bash
# Train and export models/apg.pt and models/dpg.pt in one command.
#
#   bash scripts/train_models.sh [ITERATIONS] [OUT]        (defaults: 8000 iterations, var/train)
#   make models ITERATIONS=8000
#
# APG and DPG train side by side, one sampling worker each and the machine's cores shared out as
# torch threads (one each on a 2-core machine; set WORKERS=K THREADS=T to choose). Runs resume from
# their newest checkpoint when started again, so an interrupted run goes on where it stopped.
# When both have finished, each run's networks are exported with their model cards (config,
# iterations, wall time, hardware, final losses, TAR) and the training curves are drawn beside them.
#
# The cosine annealing runs over ITERATIONS (the paper: 200 000, ~22 h per run on 2 CPU cores).
# A run this short cannot use the paper's learning rates (1e-4 → 2e-6 policy, 3e-4 → 1e-6 value),
# so every run here applies the named experiment `short-run` (crossroads train experiments;
# docs/tried/training.md): 1e-3 → 1e-5 for all three networks, gradients clipped to norm 10, and
# half the sampling rounds driven by the rule controller. PAPER=1: the paper's configuration
# instead (no experiment, and LR, ADV_LR, RULE_SHARE and EXPERIMENTS are ignored; EXTRA still applies).
#
# EXPERIMENTS="NAME ..." applies further named experiments after short-run, in order; LR sets the
# policy, value and adversary schedules ("start,end"), ADV_LR the adversary's apart from LR,
# RULE_SHARE the share of rule-driven rounds: each, when set, over what the experiments set.
#
# Warm starts: WARM=1 starts both runs from the shipped models/apg.pt and models/dpg.pt
# (INIT_DIR=DIR: from DIR/apg.pt, DIR/dpg.pt), copied to OUT/init/ first since the export
# overwrites them; the new cards carry the earlier runs in their `lineage` and count all iterations
# in `iterations_total`. A warm start does not need the high learning rate:
#   WARM=1 LR=3e-4,1e-5 RULE_SHARE=0.25 make models ITERATIONS=6000
# APG_FROM=dpg (with WARM=1) starts APG's driving policy and value network from the DPG model
# instead, with a fresh adversary (for an APG policy that learned against an adversary model that
# has since changed), here with an adversary ten times slower than the policy:
#   WARM=1 APG_FROM=dpg LR=3e-4,1e-5 ADV_LR=3e-5,1e-6 RULE_SHARE=0.25 make models ITERATIONS=3200
# ALGOS picks the runs (default "apg dpg"); ALGOS=apg trains and exports APG alone. EXTRA sets any
# further config fields ("name=value ...", last). The last run of the shipped APG, from the model
# before it (the experiment shipped-apg; the shipped weights are its checkpoint at 500 iterations,
# exported with `crossroads train export OUT/apg-seed0/checkpoints/ckpt_00000500.pt -o models/apg.pt`):
#   WARM=1 ALGOS=apg INIT_DIR=models/pooled EXPERIMENTS=shipped-apg THREADS=1 make models ITERATIONS=3000
# Going on from an experimental model kept in models/ (models/README.md):
#   WARM=1 ALGOS=apg INIT_DIR=models/standing-car LR=1e-4,1e-5 ADV_LR=3e-5,1e-6 RULE_SHARE=0.25 \
#     EXTRA="standing_car_share=0.4 empty_share=0.2" make models ITERATIONS=4000
set -euo pipefail
cd "$(dirname "$0")/.."

ITERATIONS="${1:-${ITERATIONS:-8000}}"
OUT="${2:-${OUT:-var/train}}"
WORKERS="${WORKERS:-1}"
RECIPE=(--experiment short-run)  # the run's configuration beyond the paper's (crossroads train experiments)
read -r -a MORE_EXPERIMENTS <<< "${EXPERIMENTS:-}"
for name in "${MORE_EXPERIMENTS[@]}"; do RECIPE+=(--experiment "$name"); done
[ -n "${LR:-}" ] && RECIPE+=(--set "policy_lr=$LR" --set "value_lr=$LR")
ADV_LR="${ADV_LR:-${LR:-}}"
[ -n "$ADV_LR" ] && RECIPE+=(--set "adversary_lr=$ADV_LR")
[ -n "${RULE_SHARE:-}" ] && RECIPE+=(--set "rule_share=$RULE_SHARE")
[ "${PAPER:-0}" = 1 ] && RECIPE=()
read -r -a EXTRA_PAIRS <<< "${EXTRA:-}"  # further config fields, "name=value name=value"
for pair in "${EXTRA_PAIRS[@]}"; do RECIPE+=(--set "$pair"); done
read -r -a ALGOS <<< "${ALGOS:-apg dpg}"
# the learner is the bottleneck (measured: 94 % of a core against the sampling worker's 12 %), so
# a run alone gets every core: with 2 torch threads APG's 250-iteration windows ran at a median 1.86
# it/s against 1.45 with one (some windows of both shared the CPU with measurements)
THREADS="${THREADS:-$(( $(nproc) / ${#ALGOS[@]} ))}"
(( THREADS > 0 )) || THREADS=1
for algo in "${ALGOS[@]}"; do
    [ "$algo" = apg ] || [ "$algo" = dpg ] || { echo "ALGOS: unknown algorithm '$algo' (apg, dpg)" >&2; exit 2; }
done
CROSSROADS=.venv/bin/crossroads
[ -x "$CROSSROADS" ] || bash scripts/setup.sh
mkdir -p "$OUT"

init_source() {  # algo → the model file its warm start loads
    local algo="$1"
    [ "$algo" = apg ] && [ -n "${APG_FROM:-}" ] && algo="$APG_FROM"
    echo "${INIT_DIR:-models}/$algo.pt"
}

if [ "${WARM:-0}" = 1 ]; then  # copied first: the export at the end overwrites models/
    mkdir -p "$OUT/init"
    for algo in "${ALGOS[@]}"; do
        [ -f "$OUT/$algo-seed0/checkpoints/last.pt" ] && continue  # resumed: its init is in place
        src="$(init_source "$algo")"
        cp "$src" "${src%.pt}.card.json" "$OUT/init/"
    done
fi

train() {  # algo
    local algo="$1" resume=() warm=()
    if [ -f "$OUT/$algo-seed0/checkpoints/last.pt" ]; then
        resume=(--resume)
    elif [ "${WARM:-0}" = 1 ]; then
        warm=(--set "init_from=$OUT/init/$(basename "$(init_source "$algo")")")
    fi
    "$CROSSROADS" train --algo "$algo" --iterations "$ITERATIONS" --workers "$WORKERS" --out "$OUT" \
        --seed 0 "${resume[@]}" --set log_every=250 --set checkpoint_every=500 \
        --set torch_threads="$THREADS" --set samples_per_iteration=64 --set progress=false "${RECIPE[@]}" "${warm[@]}" \
        >> "$OUT/$algo.log" 2>&1
}

pids=()
for algo in "${ALGOS[@]}"; do
    train "$algo" & pids+=($!)
done
for pid in "${pids[@]}"; do
    wait "$pid"
done

for algo in "${ALGOS[@]}"; do
    "$CROSSROADS" train export "$OUT/$algo-seed0" -o "models/$algo.pt"
    "$CROSSROADS" train plot "$OUT/$algo-seed0" -o "models/$algo.curves.png"
    cp "$OUT/$algo-seed0/metrics.csv" "models/$algo.metrics.csv"
done
echo "models written: ${ALGOS[*]} (cards: models/*.card.json)"
