"""Foot-lock settings on cached dances (issue 15, the lock's jitter): per variant, per-song jitter / energy
ratios to the song's real dance, planted share, skating, jerk, knees, floor, travel, BAS / hit rate (with the
warp) and FID_k / FID_g against the training dances (``FID=1``).

    PYTHONPATH=src FID=1 python benchmarks/tune_footlock.py revolution val \
        '{"former": {"lock": {"c1_blend": false}, "warp": true}, "hold 0.4": {"lock": {"min_hold_s": 0.4}, "warp": true}}'

Arguments: model, split (val / test / song), a JSON object ``name -> {"smooth": target | null | "off",
"noisy_ratio": the smoothing stage's NOISY_RATIO (default 0.2), "noisy_target": its SMOOTH_TARGET_NOISY (0.065), "kind": the smoothing filter ("lowpass" /
"savgol", default the stage's), "post": a final low-pass cut-off in Hz after the lock (``stages.settle``), "post_ground": the lowest joint
put back on the floor after it,
"lock": lock_feet keyword arguments | null (no lock), "warp": bool}``, optionally a comma-separated list of
song-name prefixes. Dances: ``runs/feet_raw/<model>/<split>/`` of ``benchmarks/feet_dances.py``; real dances
and songs from ``data/tang2018`` and ``../shared/music``. Choose settings on ``val`` only.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages
import numpy as np

from dancekit.data import PreparedData
from dancekit.motion import Motion, get_skeleton
from dancekit.motion import footlock as fl
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult

SK = get_skeleton("tang2018")
FPS = 25.0


def main() -> None:
    model, split = sys.argv[1], sys.argv[2]
    variants = json.loads(sys.argv[3])
    songs = sys.argv[4].split(",") if len(sys.argv) > 4 and sys.argv[4] else None
    do_fid = os.environ.get("FID") == "1"
    data = PreparedData("data/tang2018")
    real = {n: bench_feet.metrics(data.motion(n), None, None) for n in data.names("test" if split == "song" else split)}
    rm = bench_feet.mean_rows(list(real.values()))
    print(f"real {split}: planted {rm['planted_foot_share']:.3f} skate {rm['foot_skating']:.3f} knee p5 "
          f"{rm['knee_p5_deg']:.1f} floor {rm['floor_median_cm']:.2f}/{rm['floor_within_2cm']:.2f}", flush=True)
    files = sorted(Path(f"runs/feet_raw/{model}/{split}").glob("*__*.npz"))
    if songs:
        files = [f for f in files if any(f.stem.startswith(s) for s in songs)]
    audio = bench_feet.song_audio(data, split)
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")] if do_fid else []
    ref_features: dict[str, np.ndarray] = {}

    def fids(dances):
        return bench_stages.fids(dances, reference, FPS, SK, cache=ref_features)

    beats = {}
    cleaned = {f: stages.clean_up(DanceResult(motion=bench_feet.load(f, SK), model="x", seed=0)) for f in files}
    for name, v in variants.items():
        per, pos = {}, []
        t0 = time.process_time()
        for f, res in cleaned.items():
            song = f.stem.rsplit("__", 1)[0]
            if v.get("smooth") != "off":
                stages.NOISY_RATIO = v.get("noisy_ratio", 0.2)
                stages.SMOOTH_TARGET_NOISY = v.get("noisy_target", 0.065)
                res = stages.smooth(res, target=v.get("smooth"), kind=v.get("kind"))
            if v.get("lock") is not None:
                q = fl.lock_feet(np.asarray(res.motion.to_positions(), np.float64), skeleton=SK, fps=FPS, **v["lock"])
                res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=q.astype(np.float32)), model="x", seed=0)
            if v.get("post"):
                res = stages.settle(res, cutoff=v["post"], legs=v.get("post_legs", True))
                if v.get("post_ground"):  # the lowest joint put back on the floor (the clean-up's offset)
                    from dancekit.motion.analysis import up_sign
                    from dancekit.motion.cleanup import ground_offset

                    q = np.asarray(res.motion.to_positions(), np.float64)
                    q[..., SK.up_index] -= up_sign(SK) * ground_offset(q, skeleton=SK, fps=FPS)[:, None]
                    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=q.astype(np.float32)), model="x",
                                      seed=0)
            b = None
            if v.get("warp"):
                a = audio[song]
                if song not in beats:
                    beats[song] = stages.song_beats_for(a[0], start=a[1], end=a[2])
                b = beats[song]
                res = stages.beat_sync(res, a[0], start=a[1], end=a[2], beats=b)
            per.setdefault(song, []).append(bench_feet.metrics(res.motion, None if b is None else b.times,
                                                               real.get(song, rm)))
            pos.append(np.asarray(res.motion.to_positions(), np.float64))
        cpu = time.process_time() - t0
        m = bench_feet.mean_rows([r for x in per.values() for r in x])
        js = {s[6:][:8]: round(float(np.mean([r["jitter_ratio"] for r in x])), 3) for s, x in per.items()}
        es = {s[6:][:8]: round(float(np.mean([r["energy_ratio"] for r in x])), 3) for s, x in per.items()}
        st = max(float(np.mean([r["stillness"] for r in x])) for x in per.values())
        extra = ""
        if do_fid:
            fd = fids(pos)
            extra = f" FID_k {fd['fid_k']:.2f} FID_g {fd['fid_g']:.2f}"
        if "bas" in m:
            extra += f" BAS {m['bas']:.3f} hit {m['hit_rate']:.3f}"
        print(f"{name:24s} planted {m['planted_foot_share']:.3f} skate {m['foot_skating']:.3f} jerk {m['jerk']:.1f} "
              f"knee p5 {m['knee_p5_deg']:.1f} floor {m['floor_median_cm']:.2f}/{m['floor_within_2cm']:.2f} far "
              f"{m['max_distance_m']:.1f}{extra} cpu {cpu:.0f}s\n   jitter {js} max {max(js.values())}\n"
              f"   energy {es} min {min(es.values())} stillness worst song {st:.3f}", flush=True)


if __name__ == "__main__":
    main()
