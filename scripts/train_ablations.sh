#!/usr/bin/env bash
# Train every Table 4 row of model/ablations.py (the full model, its ablations and
# the DECOR-GAN* baseline) at one reduced budget, two runs at a time on one
# thread each (measured on 2 cores: ~1.25x the throughput of one run on two threads).
#
#   bash scripts/train_ablations.sh [OUT=out/ablations] [STEPS=150] [RES=128]
#
# Each row lands in OUT/<row>/ (last.pt, model.pt, log.jsonl) and is copied to
# OUT/<row>.pt, which `python benchmarks/eval_ablations.py OUT` evaluates and
# tabulates (and `decollage eval --checkpoint OUT/<row>.pt` names by its row).
# Measured: ~5.3 s an iteration per row (pyramid rows) with the pair sharing the
# 2 cores, so 150 iterations of all 8 rows at R = 128 took 55 min.
# Resumable: a rerun continues each row from its last.pt.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/ablations}; STEPS=${2:-150}; RES=${3:-128}
ROWS=(full no_down no_up no_adaptive_alpha paper_losses no_part_labels no_pyramid decor_gan)
mkdir -p "$OUT"
train_row() {
  OMP_NUM_THREADS=1 .venv/bin/decollage train --set things --out "$OUT/$1" --steps "$STEPS" \
    --resolution "$RES" --seed 0 --ablation "$1" --checkpoint-every 25 --preview-every 0 --quiet
  cp "$OUT/$1/model.pt" "$OUT/$1.pt"
  echo "$(date -u +%H:%M:%S) trained $1"
}
for ((i = 0; i < ${#ROWS[@]}; i += 2)); do
  train_row "${ROWS[i]}" & first=$!
  train_row "${ROWS[i+1]}" & second=$!
  wait "$first"; wait "$second"  # each wait returns its row's status: a failed row stops the script
done
