#!/usr/bin/env bash
# The detail evaluation of docs/benchmarks.md: upsample, quilt and the shipped decollage model on the
# test split of things_v2 (every metric, Cls full), paired against upsample, then the side-by-side
# table and the contact sheet.
#   bash scripts/eval_detail.sh [OUT_DIR] [extra decollage eval options, e.g. --limit 40 --cls quick]
# Each evaluation writes OUT_DIR/<detailizer>/eval.{json,md} and its docs/benchmarks.md section.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-out/eval_detail}"
shift || true
EVAL=(.venv/bin/decollage eval --split test --doc docs/benchmarks.md "$@")
"${EVAL[@]}" --detailizer upsample --out "$OUT/upsample"
"${EVAL[@]}" --detailizer quilt --out "$OUT/quilt" --baseline "$OUT/upsample/eval.json"
"${EVAL[@]}" --detailizer decollage --out "$OUT/decollage" --baseline "$OUT/upsample/eval.json"
.venv/bin/decollage eval --compare "$OUT/upsample/eval.json" --compare "$OUT/quilt/eval.json" \
    --compare "$OUT/decollage/eval.json" --doc docs/benchmarks.md
.venv/bin/decollage eval --sheet docs/eval_sheet.png --sheet-detailizers upsample,quilt,decollage
