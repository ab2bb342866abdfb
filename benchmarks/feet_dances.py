"""Generate and cache the models' own dances (stages off) for the foot / smoothing measurements (issue 15).

    PYTHONPATH=src python benchmarks/feet_dances.py --data data/tang2018 --music ../shared/music -o runs/feet_raw \
        --jobs val:3 test:5 song:3 --models music2dance dual revolution

Writes ``OUT/<model>/<split>/<song>__<seed>.npz`` (positions, and rotations + root translation where the model
has them); a file already there is kept (the run can be resumed). ``--reuse DIR`` takes a model's test dances
from an ``dancekit evaluate`` pred folder (``DIR/<song>__<seed>.npz``, positions) instead of dancing them again.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dancekit.data import PreparedData
from dancekit.pipelines import load_pipeline

SONGS = ("Kevin_MacLeod_-_Vibe_Ace.ogg", "brahms_hungarian_dance_5.ogg",
         "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg")


def save(path: Path, motion) -> None:
    arrays = {"positions": np.asarray(motion.to_positions(), np.float32), "fps": np.float64(motion.fps)}
    if motion.rotations is not None:
        arrays["rotations"] = np.asarray(motion.rotations, np.float32)
        arrays["root_translation"] = np.asarray(motion.root_translation, np.float32)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.rename(path)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--music", required=True)
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--jobs", nargs="+", default=["val:3", "test:5", "song:3"])
    ap.add_argument("--models", nargs="+", default=["music2dance", "dual", "revolution"])
    ap.add_argument("--reuse", nargs="*", default=[], help="MODEL=DIR: test dances of MODEL from DIR")
    args = ap.parse_args()
    data = PreparedData(args.data)
    reuse = dict(r.split("=", 1) for r in args.reuse)
    for job in args.jobs:
        split, n = job.split(":")
        seeds = list(range(int(n)))
        if split == "song":
            songs = [(s.split(".")[0][:24], str(Path(args.music) / s), None, None) for s in SONGS]
        else:
            songs = [(name, str(data.audio(name).path), data.audio(name).start, data.audio(name).end)
                     for name in data.names(split)]
        for model in args.models:
            pipe = load_pipeline(model)
            folder = Path(args.out) / model / split
            folder.mkdir(parents=True, exist_ok=True)
            for label, path, start, end in songs:
                todo = [k for k in seeds if not (folder / f"{label}__{k}.npz").exists()]
                if not todo:
                    continue
                if split == "test" and model in reuse:
                    for k in todo:
                        z = np.load(Path(reuse[model]) / f"{label}__{k}.npz")
                        np.savez(folder / f"{label}__{k}.npz", positions=z["positions"], fps=z["fps"])
                    continue
                t0 = time.perf_counter()
                if hasattr(pipe, "dances"):
                    results = pipe.dances(path, seeds=todo, start=start, end=end, beat_sync=False, cleanup=False)
                else:
                    results = [pipe(path, seed=k, start=start, end=end, beat_sync=False, cleanup=False) for k in todo]
                for k, r in zip(todo, results, strict=True):
                    save(folder / f"{label}__{k}.npz", r.motion)
                print(f"{model} {split} {label} seeds {todo}: {time.perf_counter() - t0:.1f} s", flush=True)


if __name__ == "__main__":
    main()
