"""Speed of inverse / forward kinematics on a 3-minute tang2018-sized dance (target: IK < 1 s on one core).

IK returns rotations on the tang2018 rig (28 joints: the 23 plus 5 pelvis branch joints); FK is
``rig_forward_kinematics`` back to the 23 joints.

Run by hand::

    OMP_NUM_THREADS=1 python benchmarks/bench_kinematics.py [--frames 4500] [--repeat 3]

Uses a real dance from ../shared/data/tang2018 when present (tiled to the
requested length), else a random rigid motion.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from dancekit.motion import Motion, get_skeleton
from dancekit.motion.kinematics import forward_kinematics, inverse_kinematics, rig_forward_kinematics
from dancekit.motion.rotations import axis_angle_to_matrix

TANG = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "tang2018" / "DANCE_W_1"


def _positions(frames: int) -> tuple[np.ndarray, str]:
    sk = get_skeleton("tang2018")
    if TANG.is_dir():
        from dancekit.motion.formats import read_tang2018

        pos = read_tang2018(TANG)[0].positions
        reps = int(np.ceil(frames / len(pos)))
        return np.concatenate([pos] * reps)[:frames], f"{TANG.name} tiled"
    rng = np.random.default_rng(0)
    R = axis_angle_to_matrix(torch.from_numpy(rng.normal(scale=0.5, size=(frames, 23, 3))))
    tr = torch.from_numpy(rng.normal(size=(frames, 3)))
    return forward_kinematics(R, tr, offsets=sk.offsets, parents=sk.parents).numpy(), "random rigid motion"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=4500, help="frames (4500 = 3 min at 25 fps)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    sk = get_skeleton("tang2018")
    pos, src = _positions(args.frames)
    print(f"{args.frames} frames ({src}), torch threads {torch.get_num_threads()}")
    for dtype in (torch.float32, torch.float64):
        x = torch.from_numpy(pos).to(dtype)
        best_ik = best_fk = float("inf")
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            R, tr = inverse_kinematics(x, sk)
            t1 = time.perf_counter()
            rig_forward_kinematics(R, tr, sk)
            t2 = time.perf_counter()
            best_ik, best_fk = min(best_ik, t1 - t0), min(best_fk, t2 - t1)
        print(f"  {str(dtype):14s} IK {best_ik:.3f} s   FK {best_fk:.3f} s")
    t0 = time.perf_counter()
    Motion(sk, 25, positions=pos.astype(np.float32)).with_rotations()
    print(f"  Motion.with_rotations (float64 inside) {time.perf_counter() - t0:.3f} s")


if __name__ == "__main__":
    main()
