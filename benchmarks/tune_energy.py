"""The energy stage (issues 14 and 15): its ``"energy"`` entry chosen per model on the validation songs, and
the chosen entry scored on the test songs and the songs of ``../shared/music``, on cached raw dances of
``benchmarks/feet_dances.py``.

    PYTHONPATH=src:benchmarks python benchmarks/tune_energy.py dual val \
        '{"none": null, "f0.45": {"floor": 0.45}, "f0.45 b2": {"floor": 0.45, "band_hz": 2.0}}' [--fid] [-o OUT.json]

Each setting runs ``stages.finish`` itself on every cached dance, with a candidate folder of the embedded model
(``benchmarks/candidate_folder.py``) whose ``"energy"`` entry is the setting (``null``: none); a ``"settle"``
key in a setting, e.g. ``{"settle": {"ratio_target": 0.07}}``, replaces the checkpoint's settle entry, and a
``"jitter_cap"`` key, e.g. ``{"jitter_cap": {"genre_jitter": {...}, "jitter_cap": 1.5, "jitter_cap_min_ratio":
0.7}}``, is music2dance's entry of that name (the cap before the foot lock, after it with ``"after_lock": true``,
held to the end with ``"to_end": true``; the song's genre read by music2dance's classifier). The checkpoint's
other entries apply as in the pipeline (foot lock, settle, the second grounding), the beat sync last. Per setting: per song (seeds averaged) smoothed energy, jitter (speed residual) and
their ratios to the song's real dance (``--split song``: the real test dances' mean), stillness; over all
dances planted share, skating, jerk, floor, BAS / hit rate, the gains, and with ``--fid`` FID_k / FID_g
against the training dances (10-s segments). Prints one block per setting.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages
import numpy as np
from candidate_folder import candidate_folder
from genre_tables import genre_table

from dancekit.data import PreparedData
from dancekit.features import MUSIC_BEAT_STRENGTH
from dancekit.motion import get_skeleton
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult, song_feature_set
from dancekit.pipelines.music_attributes import MusicAttributePipeline


def setting_folder(model: str, entry: dict | None, root: Path) -> tuple[str, dict | None]:
    """A candidate folder (``benchmarks/candidate_folder.py``) of the embedded ``model`` whose ``"energy"`` entry
    is the setting ``entry`` (None or only the keys below: no lift), its ``"settle"`` and ``"jitter_cap"``
    entries replaced by the setting's keys of those names where it has them; and that ``"jitter_cap"`` entry
    checked (:func:`dancekit.pipelines.stages.jitter_cap_from_entry`; None for none), once per setting."""
    entry = dict(entry or {})
    change = {k: entry.pop(k) for k in ("settle", "jitter_cap") if k in entry}
    change["energy"] = entry or None
    root.mkdir(parents=True, exist_ok=True)
    folder = str(candidate_folder(bench_feet.model_folder(model), root / f"setting{len(list(root.iterdir()))}",
                                  change, merge=False))
    return folder, stages.jitter_cap_from_entry(change.get("jitter_cap"), folder=folder)


def finish(motion, folder: str, cap: dict | None, audio, beats, probs: dict[str, float], music: bool = True):
    """A cached raw dance through ``stages.finish`` with the candidate ``folder``'s entries (the song's genre
    posterior ``probs`` for the energy floor and for ``cap``, the folder's checked ``"jitter_cap"`` entry):
    (the finished motion, the energy stage's gain, the motion before the lift)."""
    res = DanceResult(motion=motion, model=folder, seed=0, genre_probs=probs, looks_like_music=bool(music))
    cap = dict(cap) if cap else None  # its flags popped below, the setting's own entry kept
    flags = {"jitter_after_lock": bool(cap and cap.pop("after_lock")), "jitter_to_end": bool(cap and cap.pop("to_end"))}
    max_jitter = stages.plausible_jitter_cap(probs, **cap) if cap and music else None
    seen: dict[str, DanceResult] = {}
    out = stages.finish(res, audio[0], start=audio[1], end=audio[2], beat_sync_on=beats is not None, beats=beats,
                        max_jitter=max_jitter, trace=seen.__setitem__, **flags)
    return out.motion, bench_stages.energy_gain(seen["lift_energy"]), seen["smooth"].motion


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("split", choices=("val", "test", "song"))
    ap.add_argument("settings", help="JSON: name -> energy entry (or null)")
    ap.add_argument("--data", default="data/tang2018")
    ap.add_argument("--raw", default="runs/feet_raw")
    ap.add_argument("--music", default="../shared/music")
    ap.add_argument("--fid", action="store_true")
    ap.add_argument("-o", "--out")
    args = ap.parse_args()
    data = PreparedData(args.data)
    table = genre_table(data, "energy")
    print("genre energy (median of the real training dances, m/s):", json.dumps(table))
    settings = json.loads(args.settings)
    for entry in settings.values():
        if entry and "fraction" in entry and "genre_energy" not in entry:
            entry["genre_energy"] = table
    sk = get_skeleton("tang2018")
    fps = 25.0
    real_split = "test" if args.split == "song" else args.split
    real = {n: bench_feet.metrics(data.motion(n), np.asarray(data.features(n, "revolution")["beat_times"],
                                                            np.float64), None) for n in data.names(real_split)}
    real_mean = bench_feet.mean_rows(list(real.values()))
    audio = bench_feet.song_audio(data, args.split, args.music)
    beats = {k: stages.song_beats_for(a[0], start=a[1], end=a[2]) for k, a in audio.items()}
    reader = MusicAttributePipeline.from_pretrained(bench_feet.model_folder("music2dance") + "/music_attributes")
    probs = {k: reader(a[0], start=a[1], end=a[2]) for k, a in audio.items()}
    music = {k: not song_feature_set(a[0], fps=fps, preset="dual", hop_length=512, start=a[1],
                                     end=a[2]).beat_strength < MUSIC_BEAT_STRENGTH for k, a in audio.items()}
    print("looks like music:", music)
    files = sorted((Path(args.raw) / args.model / args.split).glob("*__*.npz"))
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")] if args.fid else []
    cache: dict = {}
    report = {}
    tmp = tempfile.TemporaryDirectory(prefix="tune_energy_")
    for name, entry in settings.items():
        t0, c0 = time.perf_counter(), time.process_time()
        folder, cap = setting_folder(args.model, entry, Path(tmp.name))
        rows, per_song, positions, gains = [], {}, [], []
        for f in files:
            song = f.stem.rsplit("__", 1)[0]
            m, gain, _ = finish(bench_feet.load(f, sk), folder, cap, audio[song], beats[song], probs[song],
                                music[song])
            r = bench_feet.metrics(m, beats[song].times, real.get(song, real_mean))
            r["gain"] = gain
            rows.append(r)
            gains.append(gain)
            per_song.setdefault(song, []).append(r)
            positions.append(np.asarray(m.to_positions(), np.float64))
        summary = bench_feet.mean_rows(rows)
        if args.fid:
            summary.update(bench_stages.fids(positions, reference, fps, sk, cache=cache))
        summary["per_song"] = {s: bench_feet.mean_rows(v) for s, v in per_song.items()}
        summary["seconds"], summary["cpu_seconds"] = time.perf_counter() - t0, time.process_time() - c0
        report[name] = summary
        ps = summary["per_song"]
        print(f"== {args.model} {args.split} {name}: {json.dumps(entry)}  ({summary['seconds']:.0f} s, "
              f"cpu {summary['cpu_seconds']:.0f} s)")
        for s, v in ps.items():
            fl = None if entry is None else stages.energy_floor(
                DanceResult(motion=None, model="", seed=0, genre_probs=probs[s]),
                **{k: entry[k] for k in ("floor", "fraction", "genre_energy") if k in entry})
            v["floor_m_s"] = fl
            print(f"   {s[:26]:26s} floor {fl or 0:.3f} energy {v['energy']:.3f} ({v['energy_ratio']:.3f}x) jitter {v['jitter']:.4f} "
                  f"({v['jitter_ratio']:.3f}x) still {v['stillness']:.3f} gain {v['gain']:.2f} "
                  f"planted {v['planted_foot_share']:.3f} skate {v['foot_skating']:.3f}")
        print(f"   ALL energy min {min(v['energy_ratio'] for v in ps.values()):.3f} mean {summary['energy_ratio']:.3f} "
              f"| jitter max {max(v['jitter_ratio'] for v in ps.values()):.3f} mean {summary['jitter_ratio']:.3f} | "
              f"still max {max(v['stillness'] for v in ps.values()):.3f} | planted {summary['planted_foot_share']:.3f} "
              f"skate {summary['foot_skating']:.3f} | jerk {summary['jerk']:.1f} | floor "
              f"{summary['floor_median_cm']:.2f}/{summary['floor_within_2cm']:.2f} | BAS {summary['bas']:.3f} hit "
              f"{summary['hit_rate']:.3f} | gain {min(gains):.2f}-{max(gains):.2f}"
              + (f" | FID_k {summary['fid_k']:.2f} FID_g {summary['fid_g']:.2f}" if args.fid else ""), flush=True)
    print(f"real {real_split}: planted {real_mean['planted_foot_share']:.3f} skate {real_mean['foot_skating']:.3f}")
    if args.out:
        Path(args.out).write_text(json.dumps({"real": real_mean, "settings": settings, "report": report}, indent=1,
                                             default=float))


if __name__ == "__main__":
    main()
