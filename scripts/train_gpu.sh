#!/usr/bin/env bash
# Resume a committed training run on a lent GPU machine and bring the results back.
#
#   bash scripts/train_gpu.sh RUN_DIR SET_NPZ STEPS [MINUTES]
#
# RUN_DIR holds the run's resumable state (last.pt, log.jsonl), e.g. model/weights/warmup_run;
# SET_NPZ is the style set file the run trains on (decollage styles build things, then copy
# ~/.cache/decollage/styles/things.npz beside the run: the GPU image has torch, numpy and scipy
# but not the packages that build a set). The run continues exactly as `decollage train` would
# (scripts/train_resume.py reads every setting from last.pt), on CUDA, with last.pt saved every
# 50 iterations and when MINUTES (default 8) are up; data samples are made on the machine's CPUs.
# When $OUT is set (the device tool), last.pt, model.pt and log.jsonl are copied there, with the
# time per iteration and per 16³ → 256³ shape measured on the GPU (gpu_timing.txt).
#
# With the device tool (not run unless its status says can_start_another):
#   run(command="bash scripts/train_gpu.sh model/weights/warmup_run model/weights/warmup_run/things.npz 20000 8",
#       timeout_s=600)
# then copy the files from files_at into model/weights/warmup_run/ and commit them with the log.
set -euo pipefail
cd "$(dirname "$0")/.."
RUN="$1"; SET="$2"; STEPS="$3"; MINUTES="${4:-8}"
PY="${PYTHON:-python3}"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
"$PY" - <<'EOF'
import torch
print("torch", torch.__version__, "cuda", torch.cuda.is_available(),
      torch.cuda.get_device_name() if torch.cuda.is_available() else "")
EOF
"$PY" scripts/train_resume.py "$RUN" --set "$SET" --steps "$STEPS" --device cuda --minutes "$MINUTES" \
    --checkpoint-every 50 2>&1 | tee "$RUN/gpu_session.log"
"$PY" - "$RUN" <<'EOF' | tee "$RUN/gpu_timing.txt"
import json, statistics, sys, time
import numpy as np, torch
from model.checkpoint import load_checkpoint
from model.networks import Generator
run = sys.argv[1]
rows = [json.loads(line) for line in open(f"{run}/log.jsonl")]
recent = [r["seconds"] for r in rows[-50:]]
print(f"s/iteration (median of the last {len(recent)}): {statistics.median(recent):.3f}")
ck = load_checkpoint(f"{run}/model.pt")
gen = Generator(ck.config).cuda().eval()
gen.load_state_dict(ck.generator)
occ = torch.zeros(1, 18, 18, 18, device="cuda"); occ[0, 1:17, 1:11, 1:17] = 1; occ[0, 4:14, 11:15, 4:14] = 1
lab = torch.zeros(1, 18, 18, 18, dtype=torch.long, device="cuda")
with torch.inference_mode():
    ins = gen.make_inputs(occ, lab, lab)
    for _ in range(3): gen(*ins, final_only=True)
    torch.cuda.synchronize(); times = []
    for _ in range(10):
        t = time.perf_counter(); gen(*ins, final_only=True); torch.cuda.synchronize(); times.append(time.perf_counter() - t)
print(f"16³ → 256³ forward on the GPU: {statistics.median(times) * 1000:.1f} ms median of 10; "
      f"peak {torch.cuda.max_memory_allocated() / 2**30:.2f} GiB")
EOF
if [ -n "${OUT:-}" ]; then
    cp "$RUN/last.pt" "$RUN/model.pt" "$RUN/log.jsonl" "$RUN/gpu_session.log" "$RUN/gpu_timing.txt" "$OUT/"
fi
