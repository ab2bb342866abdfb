"""Pick the sampling temperature of a Music2Dance checkpoint on the validation songs.

    PYTHONPATH=src python benchmarks/m2d_temperature.py runs/m2d/best runs/m2d_temp 0.5 0.7 1.0 [--seeds 2]

For each temperature, a copy of the checkpoint folder with ``"sampling": {"temperature": t}`` in its
config.json dances every validation song (``dancekit evaluate --checkpoint COPY --split val``, no style
classifier) and the quality figures are printed: stillness share (mean and worst song), smoothed energy and
jitter speed as ratios to the real dances, FID_k, FID_g and the foot-skating ratio. The targets of issue 13:
stillness <= 5 % on every song, energy >= 0.6x real, jitter <= 1.2x real.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import torch

from dancekit.evaluation import evaluate_checkpoint


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("checkpoint")
    p.add_argument("out")
    p.add_argument("temperatures", type=float, nargs="+")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--data", default="data/tang2018")
    p.add_argument("--split", default="val")
    args = p.parse_args()
    torch.set_num_threads(1)
    print("| temperature | stillness mean | stillness worst song | energy ratio | jitter ratio | FID_k | FID_g | foot skating |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for t in args.temperatures:
        folder = Path(args.out) / f"t{t:g}"
        model = folder / "model"
        if model.exists():
            shutil.rmtree(model)
        shutil.copytree(args.checkpoint, model)
        meta = json.loads((model / "config.json").read_text())
        meta["sampling"] = {"temperature": t}
        (model / "config.json").write_text(json.dumps(meta, indent=1))
        r = evaluate_checkpoint(model, args.data, folder / "eval", split=args.split, seeds=args.seeds,
                                classifier=None, progress=False)
        m = r["metrics"]
        still = {}
        for key, row in r["per_dance"].items():
            still.setdefault(key.split("#")[0].split("__")[0], []).append(row["stillness_share"])
        worst = max(np.mean(v) for v in still.values())
        print(f"| {t:g} | {m['stillness_share']:.3f} | {worst:.3f} | {m['smoothed_energy_ratio']:.2f} | "
              f"{m['jitter_speed_ratio']:.2f} | {m['fid_k']:.1f} | {m['fid_g']:.1f} | {m['foot_skating_ratio']:.3f} |",
              flush=True)


if __name__ == "__main__":
    main()
