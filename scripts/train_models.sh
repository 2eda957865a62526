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
# A run this short cannot use the paper's learning rates (1e-4 → 2e-6 policy, 3e-4 → 1e-6 value):
# measured on a fixed set of 824 rule-driven states of c_three_lane, 300 policy steps at 1e-4 reached
# J_π 20.2, at 1e-3 15.3 after 100 steps (zero action: 25.3). So short runs use 1e-3 → 1e-5 for
# all three networks, gradients clipped to norm 10, and half the sampling rounds driven by the rule
# controller (keeps states near the paths while the policy is poor). Set PAPER=1 for the paper's values.
#
# Warm starts: WARM=1 starts both runs from the shipped models/apg.pt and models/dpg.pt
# (INIT_DIR=DIR: from DIR/apg.pt, DIR/dpg.pt), copied to OUT/init/ first since the export
# overwrites them; the new cards carry the earlier runs in their `lineage` and count all iterations
# in `iterations_total`. A warm start does not need the high learning rate: LR sets the policy,
# value and adversary schedules (default 1e-3,1e-5), RULE_SHARE the share of rule-driven rounds (0.5).
#   WARM=1 LR=3e-4,1e-5 RULE_SHARE=0.25 make models ITERATIONS=6000
# APG_FROM=dpg (with WARM=1) starts APG's driving policy and value network from the DPG model
# instead, with a fresh adversary (for an APG policy that learned against an adversary model that
# has since changed). ADV_LR sets the adversary's schedule apart from LR (default: LR), e.g. ten
# times slower than the policy:
#   WARM=1 APG_FROM=dpg LR=3e-4,1e-5 ADV_LR=3e-5,1e-6 RULE_SHARE=0.25 make models ITERATIONS=3200
# ALGOS picks the runs (default "apg dpg"); ALGOS=apg trains and exports APG alone. EXTRA sets any
# further config fields ("name=value ..."). The recipe of the shipped APG, from the model before it:
#   WARM=1 ALGOS=apg LR=1e-4,1e-5 ADV_LR=3e-5,1e-6 RULE_SHARE=0.25 THREADS=1 \
#     EXTRA="braking_floor=true empty_share=0.2 standing_car_share=0.25 policy_loss=log path_preview=true" \
#     make models ITERATIONS=6000
# Going on from an experimental model kept in models/ (models/README.md):
#   WARM=1 ALGOS=apg INIT_DIR=models/standing-car LR=1e-4,1e-5 ADV_LR=3e-5,1e-6 RULE_SHARE=0.25 \
#     EXTRA="standing_car_share=0.4 empty_share=0.2" make models ITERATIONS=4000
set -euo pipefail
cd "$(dirname "$0")/.."

ITERATIONS="${1:-${ITERATIONS:-8000}}"
OUT="${2:-${OUT:-var/train}}"
WORKERS="${WORKERS:-1}"
LR="${LR:-1e-3,1e-5}"
ADV_LR="${ADV_LR:-$LR}"
SHORT_RUN=(--set "policy_lr=$LR" --set "value_lr=$LR" --set "adversary_lr=$ADV_LR"
           --set max_grad_norm=10 --set "rule_share=${RULE_SHARE:-0.5}")
[ "${PAPER:-0}" = 1 ] && SHORT_RUN=()
read -r -a EXTRA_PAIRS <<< "${EXTRA:-}"  # further config fields, "name=value name=value"
for pair in "${EXTRA_PAIRS[@]}"; do SHORT_RUN+=(--set "$pair"); done
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
        --set torch_threads="$THREADS" --set samples_per_iteration=64 --set progress=false "${SHORT_RUN[@]}" "${warm[@]}" \
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
