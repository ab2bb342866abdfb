#!/usr/bin/env bash
# The curriculum ablation of Dance Revolution (Table 3 of the paper, schedule part), at a reduced
# budget that fits a 2-core CPU: the same default model trained for STEPS steps with
#   teacher forcing (p = 0), a constant p = 10, and the linear schedule p = floor(λ·epoch) (λ = 1),
# each scored on the test split by `dancekit evaluate --checkpoint` (1 dance per song).
#
#   [THREADS=2] bash scripts/curriculum_ablation.sh [DATA=data/tang2018] [STEPS=800]
set -euo pipefail
DATA="${1:-data/tang2018}"
STEPS="${2:-800}"
PY="${PY:-.venv/bin/python}"
OUT=runs/ablation
mkdir -p "$OUT"
declare -A SETS=(
  [teacher_forcing]="--set curriculum=teacher_forcing"
  [const]="--set curriculum=const --set curriculum_p=10"
  [linear]="--set curriculum=linear --set curriculum_lambda=1.0"
)
for name in teacher_forcing const linear; do
  start=$(date +%s)
  # shellcheck disable=SC2086
  "$PY" -m dancekit.cli.main train revolution --data "$DATA" --out "$OUT/$name" --quiet \
      --set steps="$STEPS" --set threads="${THREADS:-2}" ${SETS[$name]}
  echo "$name: trained $STEPS steps in $(( $(date +%s) - start )) s"
  "$PY" -m dancekit.cli.main evaluate --checkpoint "$OUT/$name/model" --data "$DATA" -o "$OUT/$name/eval" --seeds 1 --quiet
done
