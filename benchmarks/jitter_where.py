"""Where the foot lock's jitter is (issue 15): on cached dances of one song, the lock's added jitter (the
metrics' speed residual: body-relative speed minus its 5-frame-average speed) split by joint (knees, foot
joints) and by frame (held, between two holds ≤ 16 frames apart, between holds farther apart, free), the
hold and gap lengths, and the knee flips (frames where the hip-relative knee moves more than twice as fast as
the original knee plus 1 cm/frame, and faster than 1 m/s).

    PYTHONPATH=src python benchmarks/jitter_where.py revolution test DANCE_W_32 '{"c1_blend": false}'

The JSON object holds ``lock_feet`` keyword arguments (the former lock: ``{"c1_blend": false}``). Dances:
``runs/feet_raw/<model>/<split>/<song>__<seed>.npz`` of ``benchmarks/feet_dances.py``; the clean-up and the
smoothing stage run first, as in the pipeline (no warp).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import numpy as np
from scipy.ndimage import uniform_filter1d

from dancekit.motion import footlock as fl
from dancekit.motion import get_skeleton
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult

SK = get_skeleton("tang2018")
FPS = 25.0


def residual(p: np.ndarray) -> np.ndarray:
    """(T, J) per-frame speed residual (m/s) of body-relative positions."""
    rel = (p - p[:, SK.root : SK.root + 1]) * SK.unit_scale
    v = np.linalg.norm(np.gradient(rel, axis=0), axis=-1) * FPS
    vs = np.linalg.norm(np.gradient(uniform_filter1d(rel, 5, axis=0, mode="nearest"), axis=0), axis=-1) * FPS
    return v - vs


def main() -> None:
    model, split, song = sys.argv[1:4]
    kw = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
    legs = fl.leg_chains(SK)
    share: dict[tuple[str, str], float] = {}
    gaps, holds = [], []
    n_values = flips = n_frames = 0
    added = []
    for f in sorted(Path(f"runs/feet_raw/{model}/{split}").glob(f"{song}__*.npz")):
        res = stages.smooth(stages.clean_up(DanceResult(motion=bench_feet.load(f, SK), model="x", seed=0)))
        p = np.asarray(res.motion.to_positions(), np.float64)
        out, rep = fl.lock_feet(p, skeleton=SK, fps=FPS, return_report=True, **kw)
        d = residual(out) - residual(p)
        added.append(d.mean())
        n_values += d.size
        for leg, (hip, knee, ankle, below) in enumerate(legs):
            runs = fl._runs(rep.held[:, leg])
            label = np.array(["free"] * len(p), dtype=object)
            label[rep.held[:, leg]] = "held"
            for (_, e0), (s1, _) in zip(runs[:-1], runs[1:], strict=True):
                label[e0 + 1 : s1] = "gap <= 16" if s1 - e0 - 1 <= 16 else "gap > 16"
                gaps.append(s1 - e0 - 1)
            holds += [e - s + 1 for s, e in runs]
            for group, joints in (("knee", [knee]), ("foot", [ankle, *below])):
                for lab in set(label):
                    key = (lab, group)
                    share[key] = share.get(key, 0.0) + float(d[label == lab][:, joints].sum())
            k0, k1 = p[:, knee] - p[:, hip], out[:, knee] - out[:, hip]
            v0 = np.linalg.norm(np.diff(k0, axis=0), axis=-1)
            v1 = np.linalg.norm(np.diff(k1, axis=0), axis=-1)
            flips += int(((v1 > 2 * v0 + 1.0 / SK.unit_scale / 100) & (v1 * SK.unit_scale * FPS > 1.0)).sum())
            n_frames += len(v0)
    print(f"{model} {split} {song} {kw}: jitter added per dance (m/s) {np.round(added, 4).tolist()}")
    for key in sorted(share):
        print(f"  {key[0]:10s} {key[1]:5s} {share[key] / n_values:+.5f} m/s")
    print(f"  knee flips: {flips} of {n_frames} leg-frames")
    print(f"  hold length (frames) 10/50/90 %: {np.percentile(holds, [10, 50, 90]).tolist()}; gaps of 8 frames "
          f"(re-plants): {int(np.sum(np.array(gaps) == 8))} of {len(gaps)}")


if __name__ == "__main__":
    main()
