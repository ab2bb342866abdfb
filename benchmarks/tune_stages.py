"""Choose the stage settings on the validation songs (issue 15): the warp's pair-rate bound and maximum
shift, and the ground-contact window. Never run on the test split.

    PYTHONPATH=src python benchmarks/tune_stages.py --data data/tang2018 --seeds 3
"""

from __future__ import annotations

import argparse

import bench_stages  # noqa: E402  (benchmarks/ is on the path when run as a script)
import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics import beat_metrics, jitter
from dancekit.motion.cleanup import contain_root_path, ground_contact
from dancekit.motion.timewarp import beat_warp, warp_bones
from dancekit.pipelines import load_pipeline, stages


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    data = PreparedData(args.data)
    pipe = load_pipeline()
    sk, fps = pipe.skeleton, pipe.fps
    dances = []
    for name in data.names("val"):
        ref = data.audio(name)
        beats = stages.song_beats_for(ref.path, start=ref.start, end=ref.end)
        for k in range(args.seeds):
            raw = pipe(ref.path, seed=k, start=ref.start, end=ref.end, beat_sync=False, cleanup=False)
            dances.append((np.asarray(raw.motion.to_positions(), np.float64), beats.times))
    real = [bench_stages.physical(np.asarray(data.motion(n).to_positions(), np.float64), sk, fps)
            for n in data.names("val")]
    print("real val: floor median {:.2f} cm, within 2 cm {:.3f}".format(np.mean([r["floor_median_cm"] for r in real]),
                                                               np.mean([r["floor_within_2cm"] for r in real])))
    for window in (0.2, 0.3, 0.5):
        rows = [bench_stages.physical(ground_contact(contain_root_path(p, skeleton=sk, fps=fps), skeleton=sk,
                                                     fps=fps, window_s=window), sk, fps) for p, _ in dances]
        print("ground window {:.1f} s: floor median {:.2f} cm, within 2 cm {:.3f}".format(
            window, np.mean([r["floor_median_cm"] for r in rows]), np.mean([r["floor_within_2cm"] for r in rows])))
    cleaned = [(ground_contact(contain_root_path(p, skeleton=sk, fps=fps), skeleton=sk, fps=fps), b) for p, b in dances]
    base = [beat_metrics(p, b, fps=fps) for p, b in cleaned]
    jerk0 = np.mean([jitter(p, fps=fps, skeleton=sk)["jerk"] for p, _ in cleaned])
    print("unwarped: BAS {:.3f} hit {:.3f} jerk {:.1f}".format(np.mean([r["bas_bailando"] for r in base]),
                                                    np.mean([r["beat_hit_rate"] for r in base]), jerk0))
    for prc in (0.10, 0.13, 0.145):
        for shift in (0.4, 0.6, 1.0):
            out, jerks = [], []
            for p, b in cleaned:
                s, _ = beat_warp(p, music_beats=b, fps=fps, pair_rate_change=prc, max_shift=shift)
                w = warp_bones(p, skeleton=sk, source_frames=s)
                out.append(beat_metrics(w, b, fps=fps))
                jerks.append(jitter(w, fps=fps, skeleton=sk)["jerk"])
            print("pair bound {:.3f}, max shift {:.1f} s: BAS {:.3f} hit {:.3f} jerk {:.1f}".format(
                prc, shift, np.mean([r["bas_bailando"] for r in out]), np.mean([r["beat_hit_rate"] for r in out]),
                np.mean(jerks)), flush=True)


if __name__ == "__main__":
    main()
