#!/usr/bin/env bash
# One GPU round (issue 41): the trainings of a round file side by side on one GPU, each sized to BUDGET_S seconds
# of steps:
#   bash scripts/gpu_round.sh scripts/gpu_rounds/round2.txt
# A round file has one run a line, `NAME FAMILY STEPS KEEP BATCH [--set KEY=VALUE ...]` (KEEP: checkpoints kept,
# BATCH: windows a step; `#` starts a comment); `$FMAP` in a line is the music attribute classifier that
# initialises F_map.
# Here, first:
#   python scripts/gpu_data.py slim data/tang2018 data/gpu/tang2018
#   cp -r src/dancekit/assets/models/revolution/music_attributes data/gpu/
#   python -m pip download --no-deps --only-binary=:all: --python-version 3.12 ... -d .whl \
#       soundfile==0.14.0 cffi==2.1.1 pycparser==3.12      # the one package the train path imports that the
#                                                           # GPU image lacks (checked with imports blocked)
# then the device call runs `bash scripts/gpu_round.sh ROUNDFILE` with carry ["data/gpu", ".whl"]; the tracked revolution
# model (46 MB) is moved out of the working tree for the call (the tree's limit is 64 MiB) and put back after.
# ROUND_S (500): seconds after the start by which every run stops and packs what it has (the device command's
# limit must be above it). OUT holds each run's tar parts (OUT/NAME/FAMILY.tar.NN) and log.txt; unpack with
#   cat NAME/FAMILY.tar.* | tar -x -C runs/gpu/NAME       # runs/gpu/NAME/run/{best,model,checkpoints,log.jsonl}
ROUNDFILE=$(realpath "${1:?usage: bash scripts/gpu_round.sh ROUNDFILE}")
cd "$(dirname "$0")/.."
export PYTHONUNBUFFERED=1
mkdir -p "$OUT"
exec > >(tee -a "$OUT/log.txt") 2>&1
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
if [ -d .whl ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    && export PYTHONPATH=/tmp/site || exit 1
fi
python3 -c "import torch, sklearn, soundfile; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())" || exit 1
T0=$(date +%s)
python3 scripts/gpu_data.py rebuild data/gpu/tang2018 || exit 1
echo "rebuild: $(( $(date +%s) - T0 )) s"
export DATA=data/gpu/tang2018 BUDGET_S=${BUDGET_S:-330} DEADLINE=$(( T0 + ${ROUND_S:-500} )) KEEP_STATE=0 PRECISION=fp32 HALF=1 CKPTS=8
run() {  # run NAME FAMILY STEPS [--set ...]
  local name=$1 family=$2 steps=$3; shift 3
  scripts/train_gpu.sh "$family" "$steps" "$OUT/$name" "$@" 2>&1 | sed "s/^/[$name] /"
}
FMAP="--set fmap_checkpoint=data/gpu/music_attributes"
PIDS=()
while read -r name family steps keep batch rest; do
  case "$name" in ''|'#'*) continue ;; esac
  # shellcheck disable=SC2086  # the settings split into words on purpose
  KEEP=$keep BATCH=$batch run "$name" "$family" "$steps" $(eval echo "$rest") </dev/null & PIDS+=($!)
done < "$ROUNDFILE"
wait "${PIDS[@]}"  # the runs only: a bare `wait` would also wait for the tee above, which never ends
echo "round: $(( $(date +%s) - T0 )) s"
ls -la "$OUT"/*
