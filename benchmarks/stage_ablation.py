"""FID_k and FID_g after each inference stage (issue 15): where a model's dances gain or lose realism on the way
from the network's output to the final dance. Validation songs by default (choices are made there).

    PYTHONPATH=src python benchmarks/stage_ablation.py --model revolution --data data/tang2018 [--split val] \
        [--seeds 5] [--json OUT.json]

Each song of the split is danced with ``--seeds`` seeds by the pipeline with every stage off (``cleanup=False``,
``beat_sync=False``: the network's output, genre draw included), then run through
:func:`dancekit.pipelines.stages.finish` with every stage on, exactly as ``dancekit dance`` and ``dancekit
evaluate`` do, its ``trace`` keeping the dance after each stage (:data:`~dancekit.pipelines.stages.STAGE_NAMES`;
a stage that does not apply to a dance, e.g. the jitter cap of a dance under its cap, passes it on unchanged).
The stage settings (a jitter cap) are the pipeline's own (``pipe.stage_options()``): the genre draw's cap for
Dance Revolution, the ``"jitter_cap"`` entry's for music2dance, none for dual. FID as ``dancekit evaluate`` computes it (AIST++ features of 10-s segments, z-scored
with the training dances' statistics, against the training dances): the last column is evaluate's number.
Printed: one row per feature kind, the FID after each stage; with ``--json``, also the mean and covariance terms.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics import fid as fid_mod
from dancekit.pipelines import load_pipeline
from dancekit.pipelines import stages as S

ROWS = ("raw", *S.STAGE_NAMES)


def stage_dances(model: str, data: PreparedData, split: str, seeds: int) -> dict[str, list[np.ndarray]]:
    """Per stage name (``"raw"`` first), the positions ``(T, J, 3)`` of every dance of the split after it."""
    pipe = load_pipeline(model)
    out: dict[str, list[np.ndarray]] = {n: [] for n in ROWS}
    for name in data.names(split):
        ref = data.audio(name)
        beats = S.song_beats_for(ref.path, start=ref.start, end=ref.end)
        for r in pipe.dances(ref.path, seeds=list(range(seeds)), start=ref.start, end=ref.end, beat_sync=False,
                             cleanup=False):
            seen: dict[str, object] = {}
            S.finish(r, S.Song(ref.path, ref.start, ref.end, beats), pipe.stage_options(),
                     trace=lambda stage, res, _seen=seen: _seen.__setitem__("raw" if stage == "input" else stage, res))
            last = r
            for stage in ROWS:  # a stage that did not run passes the dance before it on
                last = seen.get(stage, last)
                out[stage].append(last.motion.to_positions())
    return out


def fid_row(train: np.ndarray, dances: list[np.ndarray], *, data: PreparedData, kind: str) -> dict[str, float]:
    """FID of ``dances`` against the training features ``train`` (z-scored with the training statistics),
    with its mean and covariance terms."""
    pred = fid_mod.feature_sets(dances, fps=data.fps, skeleton=data.skeleton, kind=kind, segment_seconds=10.0)
    a, b, _, _ = fid_mod.normalize_features(train, pred, pred)
    total = float(fid_mod.frechet_distance(b, a))
    mean = float(((a.mean(0) - b.mean(0)) ** 2).sum())
    return {"fid": total, "mean_term": mean, "cov_term": total - mean}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default="revolution")
    ap.add_argument("--data", default="data/tang2018")
    ap.add_argument("--split", default="val")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    data = PreparedData(args.data)
    dances = stage_dances(args.model, data, args.split, args.seeds)
    train = [data.motion(n).to_positions() for n in data.names("train")]
    table = {}
    for kind in ("kinetic", "geometric"):
        ref = fid_mod.feature_sets(train, fps=data.fps, skeleton=data.skeleton, kind=kind, segment_seconds=10.0)
        table[kind] = {stage: fid_row(ref, dances[stage], data=data, kind=kind) for stage in ROWS}
    print("| FID | " + " | ".join(ROWS) + " |")
    print("| --- |" + " ---: |" * len(ROWS))
    for kind, label in (("kinetic", "FID_k"), ("geometric", "FID_g")):
        print(f"| {label} | " + " | ".join(f"{table[kind][s]['fid']:.2f}" for s in ROWS) + " |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"model": args.model, "split": args.split, "seeds": args.seeds, "dances": len(dances["raw"]),
                       "stages": table}, f, indent=1)


if __name__ == "__main__":
    main()
