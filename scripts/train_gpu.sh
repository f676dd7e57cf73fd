#!/usr/bin/env bash
# Resume committed training runs on a lent GPU machine, side by side, and bring the results back.
#
#   bash scripts/train_gpu.sh MINUTES SET_NPZ RUN_DIR:STEPS [RUN_DIR:STEPS ...]
#
# Each RUN_DIR holds a run's resumable state (last.pt); SET_NPZ is the style set file the runs train
# on (decollage styles build things, then copy ~/.cache/decollage/styles/things.npz beside the runs:
# the GPU image has torch, numpy and scipy but not the packages that build a set). The runs share
# the GPU, each continues exactly as `decollage train` would (scripts/train_resume.py reads every
# setting from last.pt) up to STEPS or for MINUTES, whichever comes first, saving last.pt every 500
# iterations and at the end; the adversarial contents are made ahead by DATA_WORKERS (default 6)
# processes per run, the monitor's figures logged every MONITOR_EVERY (default 500) iterations.
# A distilling run (distill_frac > 0, e.g. warmup_centred_long_r1_fill_distill) has its workers make the
# distilled samples too (quilt on augmented contents, 0.5-0.9 s of CPU each): give it DATA_WORKERS >= 8.
# When $OUT is set (the device tool), each run's last.pt, log.jsonl, gpu_session.log and
# gpu_timing.txt (time per iteration and per 16³ → 256³ shape on the GPU) go to $OUT/<run name>/:
# eight files for two runs, the tool's limit.
#
# With the device tool (only when its status says can_start_another), from a working tree under
# 64 MiB (move the committed *_last.pt files out of model/weights/ for the call, restore them after):
#   run(command="bash scripts/train_gpu.sh 7.5 gpu_runs/things.npz gpu_runs/long:8000 gpu_runs/r4long:20000",
#       timeout_s=570)
# then copy the files from files_at into the runs' folders and commit them with the logs.
# The GPU image (Python 3.12) lacks pydantic and cc3d, which model/ imports: fetch their wheels here once,
#   python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#     --platform manylinux_2_28_x86_64 --platform manylinux2014_x86_64 -d .whl pydantic==2.14.3 \
#     pydantic_core==2.50.4 annotated-types==0.8.0 typing-inspection==0.4.5 typing_extensions==4.16.0 \
#     connected-components-3d==4.1.1
# (.whl in .git/info/exclude), carry .whl and begin the command with
#   python3 -m pip install -q --no-index --no-deps --target /tmp/site .whl/*.whl && export PYTHONPATH=/tmp/site;
set -uo pipefail
cd "$(dirname "$0")/.."
MINUTES="$1"; SET="$2"; shift 2
PY="${PYTHON:-python3}"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1 OMP_NUM_THREADS=2
"$PY" - <<'PYEOF'
import torch
print("torch", torch.__version__, "cuda", torch.cuda.is_available(),
      torch.cuda.get_device_name() if torch.cuda.is_available() else "")
PYEOF
# MINUTES counts from each run's start, set-up included; the session logs are written where they come
# back ($OUT) as they grow, so a command stopped at its limit still returns them.
pids=()
for spec in "$@"; do
    run="${spec%%:*}"; steps="${spec##*:}"
    log="$run/gpu_session.log"
    if [ -n "${OUT:-}" ]; then mkdir -p "$OUT/$(basename "$run")"; log="$OUT/$(basename "$run")/gpu_session.log"; fi
    "$PY" scripts/train_resume.py "$run" --set "$SET" --steps "$steps" --device cuda --minutes "$MINUTES" \
        --checkpoint-every 500 --data-workers "${DATA_WORKERS:-6}" --monitor-every "${MONITOR_EVERY:-500}" \
        > "$log" 2>&1 &
    pids+=($!)
done
for i in "${!pids[@]}"; do
    wait "${pids[$i]}"; echo "run ${@:$((i + 1)):1}: exit $?"
done
for spec in "$@"; do
    run="${spec%%:*}"
    if [ -n "${OUT:-}" ]; then cp "$OUT/$(basename "$run")/gpu_session.log" "$run/"; fi
    tail -3 "$run/gpu_session.log"
    "$PY" scripts/gpu_timing.py "$run" 2>&1 | tee "$run/gpu_timing.txt"
    if [ -n "${OUT:-}" ]; then
        cp "$run/last.pt" "$run/log.jsonl" "$run/gpu_timing.txt" "$OUT/$(basename "$run")/"
    fi
done
