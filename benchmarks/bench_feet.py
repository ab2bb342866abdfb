"""Planted feet, knees, jitter and hands near the head, before and after the foot-lock and smoothing stages
(issue 15), per model, on cached dances of ``benchmarks/feet_dances.py``.

    PYTHONPATH=src python benchmarks/bench_feet.py --data data/tang2018 --raw runs/feet_raw --split val \
        --models revolution music2dance dual -o runs/feet_val [--grid]
    PYTHONPATH=src python benchmarks/bench_feet.py --data data/tang2018 --raw runs/feet_raw --split test ...
    PYTHONPATH=src python benchmarks/bench_feet.py --data data/tang2018 --raw runs/feet_raw --split song ...

Variants per dance: ``before`` = the stages as they were (clean-up, beat sync), ``after`` = clean-up,
smoothing, foot lock, the model's low-pass after the lock (``stages.settle``), beat sync (today's default),
``after, no settle`` = the same without the low-pass; with ``--grid`` (validation songs only) the foot-lock
contact thresholds and the smoothing target are varied, without the warp. Metrics per dance: the
``bench_stages`` floor / planted-foot / travel / knee metrics (planted foot: its lowest joint within 3 cm
of the local floor and slower than 0.15 m/s), foot skating (``dancekit.metrics.foot_skating``), jitter and
smoothed energy as ratios to the song's real dance (the mean of the real test dances for songs outside the
dataset), jerk, BAS / hit rate against the song's tracked beats, the share of frames with a hand joint
(wrist or hand tip) within a head radius (10 cm) of the head's centre, the stillness share, and FID_k / FID_g of each variant
against the training dances (10-s segments). Writes ``OUT/feet.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import bench_stages  # benchmarks/ is on the path when run as a script
import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics import smoothed_energy, stillness_share
from dancekit.motion import Motion, get_skeleton
from dancekit.motion import footlock as fl
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult

HEAD_RADIUS_CM = 10.0


def hands_in_head(p: np.ndarray, sk) -> float:
    """Share of frames with a hand joint within HEAD_RADIUS_CM of the head's centre (mean of the head joints)."""
    cm = sk.unit_scale * 100.0
    head = p[:, [sk.index("head_left"), sk.index("head_right")]].mean(axis=1)
    hands = [sk.index(n) for n in ("left_wrist", "right_wrist", "left_aux", "right_aux")]
    d = np.linalg.norm(p[:, hands] - head[:, None], axis=-1) * cm
    return float((d.min(axis=1) < HEAD_RADIUS_CM).mean())


def load(path: Path, sk) -> Motion:
    z = np.load(path)
    fps = float(z["fps"])
    if "rotations" in z.files:
        return Motion(skeleton=sk, fps=fps, positions=z["positions"], rotations=z["rotations"],
                      root_translation=z["root_translation"])
    return Motion(skeleton=sk, fps=fps, positions=z["positions"])


def metrics(motion: Motion, beats: np.ndarray | None, real: dict | None) -> dict:
    p = np.asarray(motion.to_positions(), np.float64)
    sk, fps = motion.skeleton, motion.fps
    row = bench_stages.dance_row(motion, beats)
    row["energy"] = smoothed_energy(p, fps=fps, skeleton=sk)
    row["hands_in_head"] = hands_in_head(p, sk)
    row["stillness"] = stillness_share(p, fps=fps, skeleton=sk)
    if real is not None:
        row["jitter_ratio"] = row["jitter"] / real["jitter"]
        row["energy_ratio"] = row["energy"] / real["energy"]
    return row


def model_folder(model: str) -> str:
    """The embedded model's folder (so the stages pick its settings, its config.json's ``"foot_lock"``, ``stages.foot_lock_options``)."""
    return str(Path(stages.__file__).resolve().parent.parent / "assets" / "models" / model)


def variant(motion: Motion, name: str, audio, beats, model: str = "cached", **opts) -> Motion:
    res = DanceResult(motion=motion, model=model_folder(model) if model != "cached" else model, seed=0)
    res = stages.clean_up(res)
    if name in ("after", "grid"):
        res = stages.smooth(res, target=opts.get("target"))
        if opts.get("lock", True):
            sk, fps = res.motion.skeleton, res.motion.fps
            contact = {k: v for k, v in opts.items() if k in ("height_on", "height_off", "speed_on", "speed_off",
                                                             "min_contact_s", "max_drift_m", "c1_blend",
                                                             "min_hold_s")}
            if contact:
                p = np.asarray(res.motion.to_positions(), np.float64)
                locked = fl.lock_feet(p, skeleton=sk, fps=fps, **contact)
                res = DanceResult(motion=Motion(skeleton=sk, fps=fps, positions=locked.astype(np.float32)),
                                  model="cached", seed=0)
            else:
                res = stages.foot_lock(res)
            if opts.get("settle", True):
                from dancekit.pipelines.config import read_stage_config

                res = stages.settle(res, **read_stage_config(res.model).settle.settle_options())
    if name != "grid" and beats is not None:
        res = stages.beat_sync(res, audio[0], start=audio[1], end=audio[2], beats=beats)
    return res.motion


def song_audio(data: PreparedData, split: str, music: str | Path = "../shared/music") -> dict:
    """Per song of ``split`` (``"song"``: the songs of ``bench_stages.SONGS`` in ``music``), the
    ``(audio path, start s, end s)`` the stages track its beats on; keys as the cached dances' file names."""
    if split == "song":
        return {s.split(".")[0][:24]: (str(Path(music) / s), None, None) for s in bench_stages.SONGS}
    return {n: (str(data.audio(n).path), data.audio(n).start, data.audio(n).end) for n in data.names(split)}


def mean_rows(rows):
    keys = [k for k in rows[0] if isinstance(rows[0][k], float)]
    return {k: float(np.nanmean([r[k] for r in rows])) for k in keys}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--raw", required=True)
    ap.add_argument("--split", required=True, choices=("val", "test", "song"))
    ap.add_argument("--music", default="../shared/music")
    ap.add_argument("--models", nargs="+", default=["revolution", "music2dance", "dual"])
    ap.add_argument("--grid", action="store_true")
    ap.add_argument("--today", action="store_true", help="also the foot lock as it was (offset blend, 0.12-s holds)")
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    if args.grid and args.split != "val":
        raise SystemExit("the grid runs on the validation songs only")
    data = PreparedData(args.data)
    sk = get_skeleton("tang2018")
    fps = 25.0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")]

    # the real dances: per song for val / test, the test dances' mean for songs outside the dataset
    real_split = "test" if args.split == "song" else args.split
    real = {}
    for n in data.names(real_split):
        m = data.motion(n)
        real[n] = metrics(m, np.asarray(data.features(n, "revolution")["beat_times"], np.float64), None)
    real_mean = mean_rows(list(real.values()))
    audio = song_audio(data, args.split, args.music)
    beats = {k: (stages.song_beats_for(a[0], start=a[1], end=a[2]) if not args.grid else None) for k, a in audio.items()}

    if args.grid:
        settings = [{"name": "clean-up only", "variant": "before"}]
        for target in (0.065, 0.09, 0.12):
            settings.append({"name": f"smooth target {target}, no lock", "variant": "grid", "target": target,
                             "lock": False})
        for target in (0.065, 0.09):
            for h_on, s_on, drift in ((0.05, 0.5, 0.2),):
                settings.append({"name": f"smooth {target} + lock {h_on}/{s_on}/{drift}", "variant": "grid",
                                 "target": target, "height_on": h_on, "height_off": h_on + 0.03, "speed_on": s_on,
                                 "speed_off": s_on + 0.4, "max_drift_m": drift})
    else:
        settings = [{"name": "before", "variant": "before"},
                    {"name": "after, no settle", "variant": "after", "settle": False},
                    {"name": "after", "variant": "after"}]
        if args.today:  # the stages as on main before the jitter work: the offset blend, 0.12-s holds
            settings.insert(1, {"name": "today", "variant": "after", "c1_blend": False, "min_hold_s": 0.12})

    report = {"real": real_mean, "real_per_song": real, "models": {}}
    for model in args.models:
        folder = Path(args.raw) / model / args.split
        files = sorted(folder.glob("*__*.npz"))
        if not files:
            print(f"{model}: no dances in {folder}")
            continue
        report["models"][model] = {}
        for st in settings:
            t0 = time.perf_counter()
            rows, positions, per_song = [], [], {}
            for f in files:
                song = f.stem.rsplit("__", 1)[0]
                m = load(f, sk)
                opts = {k: v for k, v in st.items() if k not in ("name", "variant")}
                b = beats.get(song)
                mm = variant(m, st["variant"], audio[song], b, model=model, **opts)
                r = metrics(mm, None if b is None else b.times, real.get(song, real_mean))
                rows.append(r)
                per_song.setdefault(song, []).append(r)
                positions.append(np.asarray(mm.to_positions(), np.float64))
            summary = {**mean_rows(rows), **bench_stages.fids(positions, reference, fps, sk)}
            summary["knee_min_deg_range"] = [min(r["knee_min_deg"] for r in rows), max(r["knee_min_deg"] for r in rows)]
            summary["per_song"] = {s: mean_rows(v) for s, v in per_song.items()}
            summary["seconds"] = time.perf_counter() - t0
            report["models"][model][st["name"]] = summary
            worst = max(summary["per_song"].items(), key=lambda kv: kv[1]["jitter_ratio"])
            print(f"{model:12s} {st['name']:34s} planted {summary['planted_foot_share']:.3f} skate "
                  f"{summary['foot_skating']:.3f} jitter/real {summary['jitter_ratio']:.2f} (worst {worst[0]} "
                  f"{worst[1]['jitter_ratio']:.2f}) energy/real {summary['energy_ratio']:.2f} knee p5 "
                  f"{summary['knee_p5_deg']:.1f} floor {summary['floor_median_cm']:.2f}/{summary['floor_within_2cm']:.2f}"
                  f" FID_k {summary['fid_k']:.2f} FID_g {summary['fid_g']:.2f} jerk {summary['jerk']:.1f} "
                  f"hands {summary['hands_in_head']:.3f} still {summary['stillness']:.3f} (worst "
                  f"{max(v['stillness'] for v in summary['per_song'].values()):.3f})"
                  + (f" BAS {summary['bas']:.3f} hit {summary['hit_rate']:.3f}" if "bas" in summary else ""),
                  flush=True)
    print(f"real {args.split}: planted {real_mean['planted_foot_share']:.3f} skate {real_mean['foot_skating']:.3f} "
          f"knee p5 {real_mean['knee_p5_deg']:.1f} jitter {real_mean['jitter']:.4f} hands {real_mean['hands_in_head']:.3f}")
    (out / "feet.json").write_text(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()
