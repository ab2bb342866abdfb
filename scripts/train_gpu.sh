#!/usr/bin/env bash
# Train one model family on a GPU within a wall-clock budget, through the same code path as
# `dancekit train FAMILY --set device=cuda`:
#
#   scripts/train_gpu.sh FAMILY STEPS OUT [--set KEY=VALUE ...]
#
# FAMILY   a registered family (dual, music2dance, revolution, ...)
# STEPS    the most optimiser steps; fewer when the budget would not hold them (measured, see below)
# OUT      a folder: OUT/FAMILY.tar.00, .01, ... (one tar of the run cut in parts of at most 15 MiB: best/,
#          model/, the last KEEP checkpoints (the optimiser state of the newest only, enough to resume),
#          log.jsonl (the training curve) and train.json (steps, wall time, device)); nothing else
#
# Environment (defaults): DATA=data/tang2018 (a `dancekit prepare` folder), DEVICE=cuda, PRECISION=bf16,
# BATCH=64, BUDGET_S=480 (seconds of training), KEEP=6 (checkpoints kept for select-checkpoint), CKPTS=12
# (validations and checkpoints in the run), DEADLINE (unix seconds by which the run stops, optional), HALF=0 (1: the packed weights as float16, which the loader upcasts
# to float32, as `scripts/embed_model.py --half` embeds them), KEEP_STATE=1 (0: no optimiser state packed,
# the run then cannot be resumed), PYTHON=python3 (with torch; the package is taken
# from src/). Unpack with `cat OUT/FAMILY.tar.* | tar -x -C DIR` (DIR/run/...).
#
# The steps are sized to the budget: a 20-step calibration run (same batch, device and precision) measures the
# seconds per step, then the run takes min(STEPS, 0.9 * BUDGET_S / seconds-per-step) steps so its cosine schedule
# ends inside the budget. Checked on the CPU first with a few steps:
#   DEVICE=cpu PRECISION=fp32 BATCH=8 BUDGET_S=60 scripts/train_gpu.sh dual 20 /tmp/gpu_check
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: scripts/train_gpu.sh FAMILY STEPS OUT [--set KEY=VALUE ...]" >&2
  exit 2
fi
FAMILY=$1; STEPS=$2; OUT=$3; shift 3
cd "$(dirname "$0")/.."
DATA=${DATA:-data/tang2018}
DEVICE=${DEVICE:-cuda}
PRECISION=${PRECISION:-bf16}
BATCH=${BATCH:-64}
BUDGET_S=${BUDGET_S:-480}
KEEP=${KEEP:-6}
CKPTS=${CKPTS:-12}
HALF=${HALF:-0}
KEEP_STATE=${KEEP_STATE:-1}
PYTHON=${PYTHON:-python3}
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
[ -f "$DATA/meta.json" ] || [ -d "$DATA" ] || { echo "error: prepared dataset '$DATA' not found (DATA=...)" >&2; exit 2; }
mkdir -p "$OUT"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/train_gpu_${FAMILY}.XXXXXX")
train() {  # train STEPS RUN [extra --set ...]
  local steps=$1 run=$2; shift 2
  "$PYTHON" -m dancekit.cli.main train "$FAMILY" --data "$DATA" --out "$run" --quiet \
    --set device="$DEVICE" --set precision="$PRECISION" --set batch_size="$BATCH" --set steps="$steps" "$@"
}

# 1. calibration: seconds per step at this batch, device and precision (startup and validation excluded)
train 20 "$WORK/calib" --set log_every=10 --set val_every=1000000 --set ckpt_every=1000000 "$@" >/dev/null
SPS=$("$PYTHON" - "$WORK/calib/log.jsonl" <<'EOF'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if '"elapsed_s"' in line]
(a, b) = rows[-2], rows[-1]
print((b["elapsed_s"] - a["elapsed_s"]) / (b["step"] - a["step"]))
EOF
)
N=$("$PYTHON" -c "import sys; s, b, sps = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]); \
print(max(20, min(s, int(0.9 * b / sps))))" "$STEPS" "$BUDGET_S" "$SPS")
EVERY=$(( N / CKPTS > 10 ? N / CKPTS : 10 ))
echo "train_gpu: $FAMILY on $DEVICE ($PRECISION, batch $BATCH): ${SPS} s/step -> $N of $STEPS steps in ${BUDGET_S} s"

# 2. the run: validation and a checkpoint CKPTS times, the last KEEP checkpoints kept for select-checkpoint
START=$(date +%s)
# DEADLINE (unix seconds, optional): the run is stopped (SIGTERM) by then and packed as it stands, its last
# periodic checkpoint included, so a run that outgrows its budget still brings its checkpoints back
LIMIT=()
if [ -n "${DEADLINE:-}" ]; then LIMIT=(timeout -s TERM $(( DEADLINE - $(date +%s) > 30 ? DEADLINE - $(date +%s) : 30 ))); fi
"${LIMIT[@]}" "$PYTHON" -m dancekit.cli.main train "$FAMILY" --data "$DATA" --out "$WORK/run" --quiet \
  --set device="$DEVICE" --set precision="$PRECISION" --set batch_size="$BATCH" --set steps="$N" \
  --set val_every="$EVERY" --set ckpt_every="$EVERY" --set keep_checkpoints="$KEEP" \
  --set log_every=$(( EVERY / 4 > 1 ? EVERY / 4 : 1 )) "$@" \
  || echo "train_gpu: $FAMILY stopped (exit $?) before step $N: packing the checkpoints it wrote"
WALL=$(( $(date +%s) - START ))
"$PYTHON" - "$WORK/run/train.json" "$FAMILY" "$N" "$STEPS" "$WALL" "$DEVICE" "$PRECISION" "$BATCH" "$SPS" <<'EOF'
import json, sys
import torch
path, family, n, asked, wall, device, precision, batch, sps = sys.argv[1:]
name = torch.cuda.get_device_name(0) if device.startswith("cuda") and torch.cuda.is_available() else "cpu"
json.dump({"family": family, "steps": int(n), "steps_asked": int(asked), "wall_s": int(wall), "device": device,
           "device_name": name, "precision": precision, "batch_size": int(batch), "s_per_step": float(sps)},
          open(path, "w"), indent=1)
EOF
# 3. pack: the optimiser state of the newest checkpoint only; float16 weights with HALF=1
"$PYTHON" - "$WORK/run" "$HALF" "$KEEP_STATE" <<'EOF'
import sys
from pathlib import Path
run, half, keep_state = Path(sys.argv[1]), sys.argv[2] == "1", sys.argv[3] == "1"
steps = sorted((run / "checkpoints").glob("step_*"))
for old in steps[:-1] if keep_state else steps:
    (old / "training_state.pt").unlink(missing_ok=True)
if half:
    from safetensors.torch import load_file, save_file
    for f in run.glob("**/model.safetensors"):
        state = load_file(str(f))
        save_file({k: v.half() if v.is_floating_point() else v for k, v in state.items()}, str(f))
EOF
rm -f "$OUT/$FAMILY".tar.*
tar -C "$WORK" -cf - run | split -b 15M -d -a 2 - "$OUT/$FAMILY.tar."
rm -rf "$WORK"
echo "train_gpu: $FAMILY done in ${WALL} s -> $(ls "$OUT/$FAMILY".tar.* | tr '\n' ' ')"
