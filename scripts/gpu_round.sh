#!/usr/bin/env bash
# One GPU round (issue 41): three trainings side by side on one GPU, each within BUDGET_S seconds.
# Here, first:  python scripts/gpu_data.py slim data/tang2018 data/gpu/tang2018
#               cp -r src/dancekit/assets/models/revolution/music_attributes data/gpu/
# then the device call runs `bash scripts/gpu_round.sh` with carry ["data/gpu"] (the tracked models must not
# travel: the working tree's limit is 64 MiB); OUT holds each run's tar parts and log.txt.
cd "$(dirname "$0")/.."
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
python3 -c "import torch, sklearn; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())" || exit 1
T0=$(date +%s)
python3 scripts/gpu_data.py rebuild data/gpu/tang2018 || exit 1
echo "rebuild: $(( $(date +%s) - T0 )) s"
export DATA=data/gpu/tang2018 BUDGET_S=${BUDGET_S:-400} KEEP_STATE=0 PRECISION=fp32
run() {  # run NAME FAMILY STEPS [--set ...]
  local name=$1 family=$2 steps=$3; shift 3
  scripts/train_gpu.sh "$family" "$steps" "$OUT/$name" "$@" 2>&1 | sed "s/^/[$name] /" >> "$OUT/log.txt"
}
mkdir -p "$OUT"
HALF=1 KEEP=8 CKPTS=8 run dual_a dual 6000 --set latent_dim=16 &
HALF=1 KEEP=8 CKPTS=8 run dual_b dual 6000 --set latent_dim=16 --set kl_free_bits=0.5 --set dropout=0.2 &
HALF=0 KEEP=10 CKPTS=10 run m2d music2dance 16000 --set fmap_checkpoint=data/gpu/music_attributes &
wait
ls -la "$OUT"/*
tail -n 30 "$OUT/log.txt"
