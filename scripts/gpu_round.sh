#!/usr/bin/env bash
# The device call: re-solve the slim dataset's rotations, then three trainings side by side on the one GPU.
cd "$(dirname "$0")/../.."
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
