"""Foot skating and FID_k / FID_g of the models' dances with and without a Foot Constraint Model (issue 13).

    PYTHONPATH=src python benchmarks/fcm_eval.py --data data/tang2018 --raw runs/feet_raw --split val \
        --fcm none embedded=default new=runs/fc_A/model [--lock off on] -o runs/fcm_eval_val.json

Per model (``--models``, cached raw dances of ``benchmarks/feet_dances.py``) and per foot model (``none``: no
foot model; ``NAME=FOLDER``: a foot_constraint checkpoint folder or a model name, ``default`` the embedded one),
each dance goes the way ``dancekit dance --foot-constraint`` takes it: the foot model on the model's own
dance, then the stages (clean-up, smoothing, the foot lock as ``--lock`` says; no beat warp, which moves
frames in time only). Scores: the mean foot-skating ratio (``dancekit.metrics.foot_skating``) and FID_k /
FID_g of all the model's dances of the split against the training dances (10-s segments, as
``bench_stages.fids``); the json also has each dance's skating ratio (``skating_per_dance``). Run the validation songs to choose, the test songs once per final candidate.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import bench_feet
import bench_stages
import numpy as np
import torch

from dancekit.data import PreparedData
from dancekit.metrics import foot_skating
from dancekit.motion import get_skeleton
from dancekit.pipelines.base import DanceResult
from dancekit.pipelines.config import read_stage_config
from dancekit.pipelines.foot_constraint import load_foot_constraint
from dancekit.pipelines.stages import finish

LEGS = tuple(f"{side}_{j}" for side in ("left", "right") for j in ("knee", "ankle", "toe"))


def leg_speed(positions: np.ndarray, fps: float, sk) -> float:
    """Mean world speed (m/s) of the knees, ankles and toes of positions ``(T, J, 3)`` (skeleton units)."""
    p = positions[:, [sk.index(n) for n in LEGS]] * sk.unit_scale
    return float(np.linalg.norm(np.diff(p, axis=0), axis=-1).mean() * fps)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--raw", required=True)
    ap.add_argument("--split", required=True, choices=("val", "test"))
    ap.add_argument("--models", nargs="+", default=["revolution", "music2dance"])
    ap.add_argument("--fcm", nargs="+", default=["none", "embedded=default"])
    ap.add_argument("--lock", nargs="+", default=["off"], choices=("off", "on"))
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = PreparedData(args.data)
    sk = get_skeleton("tang2018")
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")]
    fixes = {}
    for spec in args.fcm:
        name, _, folder = spec.partition("=")
        fixes[name] = None if name == "none" else load_foot_constraint(folder or name)
    report = {}
    real = [leg_speed(np.asarray(data.motion(n).to_positions(), np.float64), data.fps, sk) for n in data.names(args.split)]
    report["real/leg_speed"] = float(np.mean(real))
    print(f"{args.split} real leg speed {np.mean(real):.3f} m/s", flush=True)
    for model in args.models:
        files = sorted((Path(args.raw) / model / args.split).glob("*.npz"))
        raw = [bench_feet.load(f, sk) for f in files]
        for name, fix in fixes.items():
            for lock in args.lock:
                t0, cpu0 = time.perf_counter(), time.process_time()
                positions, skating, legs = [], [], []
                for motion in raw:
                    m = motion if fix is None else fix(motion)
                    config = read_stage_config(model).switched(beat_sync=False, foot_lock=lock == "on")
                    res = finish(DanceResult(motion=m, model=model, seed=0), "", config)
                    p = np.asarray(res.motion.to_positions(), np.float64)
                    positions.append(p)
                    skating.append(foot_skating(p, fps=res.motion.fps, skeleton=sk)["ratio"])
                    legs.append(leg_speed(p, res.motion.fps, sk))
                row = {"skating": float(np.nanmean(skating)), "leg_speed": float(np.mean(legs)),
                       "skating_per_dance": {f.stem: float(v) for f, v in zip(files, skating)},
                       **bench_stages.fids(positions, reference, 25.0, sk),
                       "dances": len(raw), "cpu_s": time.process_time() - cpu0, "wall_s": time.perf_counter() - t0}
                report[f"{model}/{name}/lock_{lock}"] = row
                print(f"{args.split} {model:<12} {name:<10} lock {lock:<3}  skating {row['skating']:.3f}  "
                      f"FID_k {row['fid_k']:.2f}  FID_g {row['fid_g']:.2f}  legs {row['leg_speed']:.3f} m/s  ({len(raw)} dances, {row['cpu_s']:.0f} s CPU)",
                      flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"split": args.split, "fcm": args.fcm, "rows": report}, indent=1))


if __name__ == "__main__":
    main()
