"""G_M→D's output filter and checkpoint, per song, with the default stages (issue 14's motion points).

    PYTHONPATH=src:benchmarks python benchmarks/dual_decoding.py --data data/tang2018 --split val \
        --models dual runs/ft/checkpoints/step_0000100 ... --filters box13 bw1.0 bw1.5 bw2.0 --seeds 0 1 -o runs/dd_val

For every model, song and seed, G_M→D's raw output is generated once (``DualModel.generate_dance`` on the song's
features, start pose from the pool with the seed, each seed on its own as ``DualPipeline.dances`` does); every filter is then applied to it (``boxN``: the N-frame
moving average, ``bwF``: the zero-phase Butterworth low-pass at F Hz, ``none``; ``default``: the checkpoint's own setting), and the dance goes through the
default stages of ``dancekit dance`` (clean-up, smoothing, foot lock, beat sync: ``stages.finish``). Per dance:
stillness share, smoothed energy and jitter as ratios to the song's real dance, planted-foot share, foot
skating and mean jerk. Also the raw output's motion power per frequency band against the real dance's
(``--bands``). Writes ``OUT/decoding.json`` and prints one line per (model, filter) with the per-song worst
values. Choices are made on ``--split val``; ``--split test`` scores final candidates. ``--fid`` adds FID_k / FID_g
of each (model, filter)'s finished dances against the training dances (10-s segments, as
``benchmarks/tune_footlock.py`` with ``FID=1``).

A candidate folder's ``"energy"`` entry (``stages.energy_options``) is applied as ``dancekit dance`` applies it:
the genre probabilities its ``"genre_reader"`` component reads from the song go into the result, so the
energy stage of ``stages.finish`` lifts a dance under the genre floor (the gain is recorded per dance). Every
song is danced as music here (the pipeline would calm a song that does not look like music, e.g. W_11 of the
validation split; ``looks_like_music`` is recorded per song). Folders with identical weights and statistics
(e.g. one checkpoint with different stage entries) share one raw G_M→D output (it depends on the weights, the
features and the seed only). ``--genre-labels`` (a diagnostic) puts the dataset's genre label in place of the
reader's probabilities, to separate what the energy stage does from how well the music's genre is read.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import time
from pathlib import Path

import bench_stages  # benchmarks/ is on the path
import numpy as np
import torch

from dancekit.checkpoints.hub import components
from dancekit.data import PreparedData, tang2018_genre
from dancekit.features import MUSIC_BEAT_STRENGTH
from dancekit.metrics import smoothed_energy, stillness_share
from dancekit.metrics.stability import body_relative, jitter, to_metres
from dancekit.motion.representations import decode_motion
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult, song_feature_set
from dancekit.pipelines.dual import DualPipeline, lowpass, moving_average

BANDS = (0.0, 0.5, 1.0, 2.0, 3.0, 6.0, 12.5)


def band_power(p: np.ndarray, sk, fps: float) -> np.ndarray:
    """Power of the body-relative joint velocities (m²/s²) in each of BANDS (Hz), per frame."""
    q = body_relative(to_metres(p, sk), sk)
    v = np.diff(q, axis=0).reshape(len(q) - 1, -1) * fps
    v = v - v.mean(0)
    power = np.abs(np.fft.rfft(v, axis=0)) ** 2 / len(v)
    f = np.fft.rfftfreq(len(v), 1 / fps)
    return np.array([power[(f >= a) & (f < b)].sum() / len(v) for a, b in zip(BANDS[:-1], BANDS[1:])])


def apply_filter(y: np.ndarray, name: str, pipe: DualPipeline) -> np.ndarray:
    fps = pipe.fps
    if name == "default":  # the checkpoint's own setting, as `dancekit dance` uses it
        return pipe.output_filter(y)
    if name == "none":
        return y
    if name.startswith("box"):
        return moving_average(y, int(name[3:]))
    if name.startswith("bw"):
        return lowpass(y, cutoff_hz=float(name[2:]), fps=fps)
    raise SystemExit(f"unknown filter {name!r}")


def digest(*files: Path) -> str:
    """One hash of the files' bytes (which folders share weights and statistics, or a genre reader)."""
    h = hashlib.sha256()
    for f in files:
        h.update(Path(f).read_bytes())
    return h.hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val", choices=("val", "test"))
    ap.add_argument("--models", nargs="+", default=["dual"])
    ap.add_argument("--filters", nargs="+", default=["box13", "bw1.5"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--no-beat-sync", action="store_true")
    ap.add_argument("--fid", action="store_true", help="FID_k / FID_g against the training dances")
    ap.add_argument("--genre-labels", action="store_true",
                    help="diagnostic: the energy floor from the dataset's genre label (probability 1) instead of "
                         "the genre reader's probabilities (no user of `dancekit dance` has that label)")
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = PreparedData(args.data)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = data.names(args.split)
    real, feats, beats, audio = {}, {}, {}, {}
    first = DualPipeline.from_pretrained(args.models[0])
    for n in names:
        m = data.motion(n)
        p = np.asarray(m.to_positions(), np.float64)
        real[n] = {"energy": smoothed_energy(p, fps=m.fps, skeleton=m.skeleton),
                   "jitter": jitter(p, fps=m.fps, skeleton=m.skeleton)["speed_residual"],
                   "bands": band_power(p, m.skeleton, m.fps),
                   **bench_stages.physical(p, m.skeleton, m.fps)}
        a = data.audio(n)
        audio[n] = (str(a.path), a.start, a.end)
        feats[n] = first.features(a.path, start=a.start, end=a.end)  # same preset / stats for every dual model
        beats[n] = None if args.no_beat_sync else stages.song_beats_for(a.path, start=a.start, end=a.end)
    music = {n: not song_feature_set(audio[n][0], fps=first.fps, preset=first.preset, hop_length=first.hop_length,
                                     start=audio[n][1], end=audio[n][2]).beat_strength < MUSIC_BEAT_STRENGTH
             for n in names}
    raw_cache: dict[str, dict[str, np.ndarray]] = {}
    probs_cache: dict[tuple[str, str], dict[str, float]] = {}
    ref_features: dict[str, np.ndarray] = {}

    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")] \
        if args.fid else []

    def fids(dances: list[np.ndarray], sk, fps: float) -> dict[str, float]:
        return bench_stages.fids(dances, reference, fps, sk, cache=ref_features)

    results = []
    for model in args.models:
        pipe = DualPipeline.from_pretrained(model)
        sk, fps = pipe.skeleton, pipe.fps
        folder = Path(pipe.folder)
        raw = raw_cache.setdefault(digest(folder / "model.safetensors", folder / "stats.npz"), {})
        t0 = time.process_time()
        for n in names:
            if n in raw:  # the same weights and statistics scored before in this run
                continue
            # each seed on its own, as `DualPipeline.dances` decodes it (a batch rounds differently)
            f = torch.from_numpy(feats[n])[None]
            raw[n] = np.stack([pipe.model.generate_dance(f, start=pipe.start_pose(None, seed)[None])[0].cpu().numpy()
                               for seed in args.seeds])
        gen_cpu = time.process_time() - t0
        probs = {n: {} for n in names}  # the genres the music calls for, where the energy entry's floor needs them
        config = pipe.stage_options(beat_sync=not args.no_beat_sync)  # the folder's stage settings
        if pipe.genre_reader is not None and config.lift_energy is not None and config.genre_stats.energy:
            reader = digest(*sorted(Path(components(folder)["genre_reader"]).glob("*.*")))
            for n in names:
                if args.genre_labels:
                    probs_cache[reader, n] = {tang2018_genre(n): 1.0}
                if (reader, n) not in probs_cache:
                    probs_cache[reader, n] = dict(pipe.genre_reader(audio[n][0], start=audio[n][1], end=audio[n][2]))
                probs[n] = probs_cache[reader, n]
        for filt in args.filters:
            rows, finished = [], []
            for n in names:
                for k, seed in enumerate(args.seeds):
                    y = apply_filter(raw[n][k], filt, pipe)
                    motion = decode_motion(pipe.stats.denormalize_dance(y), sk, fps, "rot6d")
                    res = DanceResult(motion=motion, model=pipe.folder, seed=seed,  # the folder: its stage settings
                                      genre_probs=probs[n])
                    res = stages.finish(res, stages.Song(audio[n][0], audio[n][1], audio[n][2], beats[n]), config)
                    p = np.asarray(res.motion.to_positions(), np.float64)
                    finished.append(p)
                    row = {"song": n, "seed": seed,
                           "stillness": stillness_share(p, fps=fps, skeleton=sk),
                           "energy_ratio": smoothed_energy(p, fps=fps, skeleton=sk) / real[n]["energy"],
                           "jitter_ratio": jitter(p, fps=fps, skeleton=sk)["speed_residual"] / real[n]["jitter"],
                           "energy_gain": bench_stages.energy_gain(res),
                           **bench_stages.dance_row(res.motion, None)}
                    if filt == args.filters[0]:
                        raw_p = np.asarray(decode_motion(pipe.stats.denormalize_dance(raw[n][k]), sk, fps,
                                                         "rot6d").to_positions(), np.float64)
                        row["raw_band_ratio"] = (band_power(raw_p, sk, fps) / real[n]["bands"]).tolist()
                    rows.append(row)
            per_song = {n: {key: float(np.mean([r[key] for r in rows if r["song"] == n]))
                            for key in ("stillness", "energy_ratio", "jitter_ratio", "planted_foot_share",
                                        "energy_gain")} | {"looks_like_music": music[n], "genre_probs": probs[n]}
                        for n in names}
            summary = {
                "model": str(model), "filter": filt, "gen_cpu_s": gen_cpu,
                "stillness_max": max(v["stillness"] for v in per_song.values()),
                "energy_min": min(v["energy_ratio"] for v in per_song.values()),
                "energy_mean": float(np.mean([v["energy_ratio"] for v in per_song.values()])),
                "jitter_max": max(v["jitter_ratio"] for v in per_song.values()),
                "jitter_mean": float(np.mean([v["jitter_ratio"] for v in per_song.values()])),
                "energy_entry": None if config.lift_energy is None else dataclasses.asdict(config.lift_energy),
                "planted": float(np.mean([r["planted_foot_share"] for r in rows])),
                "skating": float(np.mean([r["foot_skating"] for r in rows])),
                "jerk": float(np.mean([r["jerk"] for r in rows])),
                "real_planted": float(np.mean([real[n]["planted_foot_share"] for n in names])),
                "per_song": per_song, "rows": rows,
                **(fids(finished, sk, fps) if args.fid else {}),
            }
            results.append(summary)
            print(f"{model} {filt}: stillness max {summary['stillness_max']:.3f} | energy min {summary['energy_min']:.2f} "
                  f"mean {summary['energy_mean']:.2f} | jitter max {summary['jitter_max']:.2f} mean "
                  f"{summary['jitter_mean']:.2f} | planted {summary['planted']:.3f} (real {summary['real_planted']:.3f}) "
                  f"skating {summary['skating']:.3f} jerk {summary['jerk']:.1f} | "
                  + (f"FID_k {summary['fid_k']:.1f} FID_g {summary['fid_g']:.0f} | " if args.fid else "")
                  + "per song e/j "
                  + " ".join(f"{n[6:]}:{v['energy_ratio']:.2f}/{v['jitter_ratio']:.2f}" for n, v in per_song.items())
                  + " | gain " + " ".join(f"{v['energy_gain']:.2f}" for v in per_song.values()),
                  flush=True)
            (out / "decoding.json").write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
