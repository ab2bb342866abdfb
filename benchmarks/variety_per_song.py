"""Per song, the quality guards of issue 5 on a folder of generated dances (``NAME__k.npz``): the worst
seed's stillness share, the lowest smoothed energy / real and the highest jitter / real.

    PYTHONPATH=src python benchmarks/variety_per_song.py runs/tune/0_0_0/pred --data data/tang2018 --split val
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dancekit.data import PreparedData
from dancekit.evaluation.score import _read_dir, group_predictions
from dancekit.metrics import stability
from dancekit.motion import read_motion


def guards(m) -> tuple[float, float, float]:
    p = np.asarray(m.to_positions(), np.float64)
    return (stability.stillness_share(p, fps=m.fps, skeleton=m.skeleton),
            stability.smoothed_energy(p, fps=m.fps, skeleton=m.skeleton),
            stability.jitter(p, fps=m.fps, skeleton=m.skeleton)["speed_residual"])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pred", nargs="+")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    args = ap.parse_args()
    data = PreparedData(args.data)
    real = {n: guards(data.motion(n)) for n in data.names(args.split)}
    for folder in args.pred:
        groups = group_predictions(_read_dir(Path(folder), "generated"))
        worst = []
        for name, paths in sorted(groups.items()):
            g = np.array([guards(read_motion(p)) for p in paths])  # (seeds, 3)
            row = (g[:, 0].max(), g[:, 1].min() / real[name][1], g[:, 2].max() / real[name][2])
            worst.append(row)
            print(f"{folder} {name}: stillness worst {row[0]:.3f}, energy/real min {row[1]:.2f}, "
                  f"jitter/real max {row[2]:.2f}")
        w = np.array(worst)
        print(f"{folder} ALL: stillness worst {w[:, 0].max():.3f}, energy/real min {w[:, 1].min():.2f}, "
              f"jitter/real max {w[:, 2].max():.2f}")


if __name__ == "__main__":
    main()
