"""Beat-sync settings on cached dances (issue 15, beat hit rate ≥ 0.6): why kinematic beats miss, and a grid.

    PYTHONPATH=src:benchmarks python benchmarks/tune_beatsync.py music2dance val \
        '{"today": {}, "shift 0.4": {"max_shift": 0.4}}'

Arguments: model (an embedded model: its checkpoint's stages are applied as the pipeline does, the warp
excepted), split (val / test / song), a JSON object ``name -> beat_warp keyword arguments`` (``max_rate_change``,
``pair_rate_change``, ``max_shift``, ``smooth``, ``smooth_s``, ``between_tolerance``, ``max_rate_step``; ``null``
for the warp off), optionally ``--stage``: the variants
are ignored and the dances go through ``stages.finish`` as the pipeline runs it (the checkpoint's ``"beat_sync"``
entry read), next to beat sync off; ``--per-song``: also BAS, hit rate and jerk per song; ``--raw DIR``: the
dances' folder (default ``runs/feet_raw``); ``--json OUT``: every figure, unrounded, to ``OUT``. Dances: ``DIR/<model>/<split>/`` of ``benchmarks/feet_dances.py``.
Per variant: BAS, beat hit rate, kinematic beats per music beat, the share of kinematic beats matched by the warp,
mean jerk, foot skating, FID_k / FID_g against the training dances, the warp's rate steps (share of frames whose
rate changes by more than 1 % and 2 % from the frame before, the largest change); and for the unwarped dances where their
kinematic beats lie (the diagnosis). Choose settings on ``val`` only.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages
import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics.beat import beat_metrics, kinematic_beats
from dancekit.motion import get_skeleton
from dancekit.motion.timewarp import beat_warp, warp_motion
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult

SK = get_skeleton("tang2018")
FPS = 25.0


def where_beats(kin: np.ndarray, music: np.ndarray) -> dict[str, float]:
    """Where the kinematic beats of an unwarped dance lie against the music beats: the share within 0.1 s of a
    beat, the share nearer a half-beat than a beat, kinematic beats per music beat interval."""
    m = music[(music >= 0) & (music <= kin.max() + 1.0)] if len(kin) else music
    if len(kin) == 0 or len(m) < 2:
        return {"near": np.nan, "half": np.nan, "per_beat": np.nan}
    i = np.clip(np.searchsorted(m, kin) - 1, 0, len(m) - 2)
    phase = (kin - m[i]) / (m[i + 1] - m[i])  # 0 … 1 within the beat interval
    d = np.minimum(np.abs(kin[:, None] - m[None]).min(axis=1), 9.0)
    return {"near": float(np.mean(d <= 0.1)), "half": float(np.mean(np.abs(phase - 0.5) < 0.25)),
            "per_beat": len(kin) / max(len(m) - 1, 1)}


def main() -> None:
    model, split = sys.argv[1], sys.argv[2]
    use_stage = "--stage" in sys.argv
    per_song = "--per-song" in sys.argv
    variants = {"stage": "stage"} if use_stage else json.loads(sys.argv[3])
    raw = sys.argv[sys.argv.index("--raw") + 1] if "--raw" in sys.argv else "runs/feet_raw"
    data = PreparedData("data/tang2018")
    files = sorted(Path(f"{raw}/{model}/{split}").glob("*__*.npz"))
    audio = bench_feet.song_audio(data, split)
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")]
    folder = bench_feet.model_folder(model)
    t0 = time.process_time()
    pre, beats = {}, {}
    for f in files:
        song = f.stem.rsplit("__", 1)[0]
        a = audio[song]
        if song not in beats:
            beats[song] = stages.song_beats_for(a[0], start=a[1], end=a[2])
        res = DanceResult(motion=bench_feet.load(f, SK), model=folder, seed=0)
        from dancekit.pipelines.config import read_stage_config

        pre[f] = stages.finish(res, stages.Song(a[0], a[1], a[2]), read_stage_config(folder).switched(beat_sync=False))
    print(f"{model} {split}: {len(files)} dances, stages before the warp {time.process_time() - t0:.0f} s CPU", flush=True)
    diag = [where_beats(kinematic_beats(np.asarray(r.motion.to_positions(), np.float64), fps=FPS),
                        beats[f.stem.rsplit("__", 1)[0]].times) for f, r in pre.items()]
    print("unwarped kinematic beats: within 0.1 s of a beat {:.3f}, nearer the half-beat {:.3f}, per beat interval "
          "{:.2f}".format(*(np.nanmean([d[k] for d in diag]) for k in ("near", "half", "per_beat"))), flush=True)
    rows_out = {}
    for name, v in ({"off": None} | variants).items():
        t1 = time.process_time()
        rows, pos, matched, songs, steps = [], [], [], [], []
        for f, res in pre.items():
            song = f.stem.rsplit("__", 1)[0]
            b = beats[song]
            if v == "stage":
                a = audio[song]
                res = stages.beat_sync(res, a[0], start=a[1], end=a[2], beats=b)
            elif v is not None and b.has_beat:
                p = np.asarray(res.motion.to_positions(), np.float64)
                source, pairs = beat_warp(p, music_beats=b.times, fps=FPS, **v)
                n_k = len(kinematic_beats(p, fps=FPS, smooth=v.get("smooth")))
                matched.append(len(pairs) / max(n_k, 1))
                steps.append(np.abs(np.diff(source, 2)))  # the rate's change per frame
                if len(pairs):
                    res = DanceResult(motion=warp_motion(res.motion, source_frames=source), model=res.model, seed=0)
            p = np.asarray(res.motion.to_positions(), np.float64)
            row = bench_stages.dance_row(res.motion, None)
            bm = beat_metrics(p, b.times, fps=FPS, skeleton=SK)
            row.update(bas=bm["bas_bailando"], hit_rate=bm["beat_hit_rate"], coverage=bm["beat_coverage"])
            songs.append(song)
            rows.append(row)
            pos.append(p)
        m = bench_stages.mean_rows(rows)
        fd = bench_stages.fids(pos, reference, FPS, SK)
        st = np.concatenate(steps) if steps else np.zeros(0)
        out = {"bas": m["bas"], "hit": m["hit_rate"], "coverage": m["coverage"], "jerk": m["jerk"],
               "skating": m["foot_skating"], **fd, "matched": float(np.mean(matched)) if matched else np.nan,
               # rate steps (|rate[t+1] - rate[t]|, over every frame of the warped dances): share above 1 % and
               # 2 % per frame (1e-6 of slack: a step held at the bound counts as at it), the largest
               "step1": float(np.mean(st > 0.01 + 1e-6)) if len(st) else np.nan,
               "step2": float(np.mean(st > 0.02 + 1e-6)) if len(st) else np.nan,
               "stepmax": float(st.max()) if len(st) else np.nan}
        rows_out[name] = out
        print(f"{name:28s} BAS {out['bas']:.3f} hit {out['hit']:.3f} kin/music {out['coverage']:.2f} "
              f"matched {out['matched']:.2f} jerk {out['jerk']:.2f} skate {out['skating']:.4f} "
              f"FID_k {out['fid_k']:.2f} FID_g {out['fid_g']:.2f} steps>1% {out['step1']:.4f} >2% {out['step2']:.4f} "
              f"max {out['stepmax']:.4f} cpu {time.process_time() - t1:.0f}s", flush=True)
        if per_song:
            for song in dict.fromkeys(songs):
                ms = bench_stages.mean_rows([r for r, s in zip(rows, songs, strict=True) if s == song])
                print(f"    {song:26s} BAS {ms['bas']:.3f} hit {ms['hit_rate']:.3f} jerk {ms['jerk']:.2f}", flush=True)
    off = rows_out["off"]
    for name, out in rows_out.items():
        if name != "off":
            print(f"{name:28s} vs off: " + " ".join(f"{k} {100 * (out[k] / off[k] - 1):+.1f}%"
                                                    for k in ("fid_k", "fid_g", "jerk", "skating")))
    if "--json" in sys.argv:  # every figure unrounded
        Path(sys.argv[sys.argv.index("--json") + 1]).write_text(json.dumps(rows_out, indent=1))


if __name__ == "__main__":
    main()
