"""How often a hand comes within a head radius of the head (issue 15), per model and in the real dances.

    PYTHONPATH=src python benchmarks/hands_head.py --data data/tang2018 --raw runs/feet_raw

Head centre: the mean of tang2018's two head joints (10.5 cm apart in the rest pose); hand joints: wrists and
hand tips (``*_aux``). Share of frames with a hand joint within 10 / 15 / 20 cm of the head centre, on the
models' own dances (the stages move whole frames or the legs only, so they do not change this) of the test
songs and the three songs outside the dataset, and on the real training and test dances.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dancekit.data import PreparedData
from dancekit.motion import get_skeleton

RADII = (10.0, 15.0, 20.0)


def shares(p: np.ndarray, sk) -> np.ndarray:
    cm = sk.unit_scale * 100.0
    head = p[:, [sk.index("head_left"), sk.index("head_right")]].mean(axis=1)
    hands = [sk.index(n) for n in ("left_wrist", "right_wrist", "left_aux", "right_aux")]
    d = (np.linalg.norm(p[:, hands] - head[:, None], axis=-1) * cm).min(axis=1)
    return np.array([(d < r).mean() for r in RADII] + [d.min()])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--raw", required=True)
    args = ap.parse_args()
    data = PreparedData(args.data)
    sk = get_skeleton("tang2018")
    head = "share within " + " / ".join(f"{r:.0f}" for r in RADII) + " cm; closest (cm)"
    for split in ("train", "test"):
        rows = np.array([shares(np.asarray(data.motion(n).to_positions(), np.float64), sk) for n in data.names(split)])
        print(f"real {split:5s} ({len(rows)} dances): {head}: {rows[:, :3].mean(0).round(4)}; {rows[:, 3].min():.1f}; "
              f"dances with any frame within 10 cm: {(rows[:, 0] > 0).sum()}")
    for model in ("revolution", "music2dance", "dual"):
        files = [f for s in ("test", "song") for f in sorted((Path(args.raw) / model / s).glob("*.npz"))]
        rows = np.array([shares(np.load(f)["positions"].astype(np.float64), sk) for f in files])
        print(f"{model:11s} ({len(rows)} dances): {head}: {rows[:, :3].mean(0).round(4)}; {rows[:, 3].min():.1f}; "
              f"dances with any frame within 10 cm: {(rows[:, 0] > 0).sum()}")


if __name__ == "__main__":
    main()
