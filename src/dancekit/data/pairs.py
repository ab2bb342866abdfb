"""The user's own music–dance pairs: ``dancekit prepare pairs SRC -o DIR`` (:func:`prepare_pairs`).

``SRC`` holds songs (``.wav .flac .ogg .mp3 .m4a .aac .opus``) and motion files paired by name (file stem):
``NAME.wav`` with ``NAME.npz`` (dancekit npz), ``NAME.bvh``, ``NAME.pkl`` (AIST++ SMPL) or ``NAME/`` (a folder
of OpenPose ``*_keypoints.json`` files). Motion frame 0 plays at second 0 of its song.

An optional ``pairs.csv`` (columns ``name,start,end,genre``, any of them empty) or ``pairs.json``
(``{"NAME": {"start": s, "end": s, "genre": g}}``) cuts a pair to ``[start, end)`` seconds (song and motion
alike) and labels its genre (default ``unknown``).

Broken or unmatched files are skipped, not fatal: ``DIR/report.json`` lists every pair prepared and every
file skipped with the reason (unreadable motion or audio, no partner, too short, or a skeleton other than
the dataset's: a dataset has one skeleton, that of most pairs). Each pair is prepared on its own (memory
bounded by the longest dance), in ``workers`` processes. The layout is :func:`prepare_tang2018`'s, so
``dancekit train`` reads it unchanged; splits are whole dances stratified by genre (:func:`split_by_genre`).
"""

from __future__ import annotations

import contextlib
import csv
import json
import multiprocessing
import os
import shutil
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._checks import check_fps
from dancekit._io import atomic_dir
from dancekit.data.prepared import split_by_genre
from dancekit.errors import DancekitError, DatasetError, ParameterError

AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".mp3", ".m4a", ".aac", ".opus")
MOTION_SUFFIXES = (".npz", ".bvh", ".pkl")
MIN_FRAMES = 8
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


@contextlib.contextmanager
def _one_thread_each():
    """Within: the thread-count variables the user did not set are "1" (for worker processes spawned here)."""
    unset = [k for k in THREAD_VARIABLES if k not in os.environ]
    os.environ.update(dict.fromkeys(unset, "1"))
    try:
        yield
    finally:
        for k in unset:
            os.environ.pop(k, None)


def _read_labels(src: Path) -> dict[str, dict[str, Any]]:
    """``pairs.csv`` / ``pairs.json`` of ``src``: name → {start, end, genre} (absent: {})."""
    labels: dict[str, dict[str, Any]] = {}
    if (src / "pairs.json").is_file():
        try:
            raw = json.loads((src / "pairs.json").read_text())
        except (OSError, ValueError) as exc:
            raise DatasetError(f"{src / 'pairs.json'}: not readable JSON ({exc})") from None
        if not isinstance(raw, dict):
            raise DatasetError(f"{src / 'pairs.json'}: expected {{name: {{start, end, genre}}}}")
        labels.update({str(k): dict(v) for k, v in raw.items() if isinstance(v, dict)})
    if (src / "pairs.csv").is_file():
        with (src / "pairs.csv").open(newline="") as f:
            for row in csv.DictReader(f):
                name = (row.get("name") or "").strip()
                if name:
                    labels[name] = {k: v.strip() for k, v in row.items() if k != "name" and v and v.strip()}
    out = {}
    for name, entry in labels.items():
        try:
            out[name] = {"start": float(entry["start"]) if entry.get("start") not in (None, "") else 0.0,
                         "end": float(entry["end"]) if entry.get("end") not in (None, "") else None,
                         "genre": str(entry.get("genre") or "unknown")}
        except (TypeError, ValueError):
            raise DatasetError(f"{src}: bad start/end for pair {name!r}: {entry}") from None
    return out


def find_pairs(src: str | os.PathLike) -> tuple[dict[str, tuple[Path, Path]], list[dict[str, str]]]:
    """(name → (song, motion), skipped files with reasons) of the folder ``src``, paired by stem."""
    src = Path(src)
    songs: dict[str, Path] = {}
    motions: dict[str, Path] = {}
    skipped: list[dict[str, str]] = []
    for p in sorted(src.iterdir()):
        if p.name.startswith(".") or p.name in ("pairs.csv", "pairs.json"):
            continue
        suffix = p.suffix.lower()
        if p.is_dir():
            if any(p.glob("*.json")):
                motions.setdefault(p.name, p)
            else:
                skipped.append({"file": p.name, "reason": "a folder without OpenPose *.json files"})
        elif suffix in AUDIO_SUFFIXES:
            if p.stem in songs:
                skipped.append({"file": p.name, "reason": f"a second song named {p.stem!r}"})
            else:
                songs[p.stem] = p
        elif suffix in MOTION_SUFFIXES:
            if p.stem in motions:
                skipped.append({"file": p.name, "reason": f"a second motion named {p.stem!r}"})
            else:
                motions[p.stem] = p
        else:
            skipped.append({"file": p.name, "reason": "neither a song nor a motion file"})
    pairs = {n: (songs[n], motions[n]) for n in sorted(set(songs) & set(motions))}
    skipped += [{"file": songs[n].name, "reason": "no motion file of the same name"} for n in sorted(set(songs) - set(motions))]
    skipped += [{"file": motions[n].name, "reason": "no song of the same name"} for n in sorted(set(motions) - set(songs))]
    return pairs, skipped


def _prepare_one(job: dict[str, Any]) -> dict[str, Any]:
    """Prepare one pair into ``job["dir"]``; returns its meta entry, or ``{"error": ...}``."""
    from dancekit.audio import load
    from dancekit.features import extract_file
    from dancekit.motion import Motion
    from dancekit.motion.analysis import floor_curve
    from dancekit.motion.formats import read_motion, write_motion

    song, motion_path, fps = Path(job["song"]), Path(job["motion"]), job["fps"]
    try:
        motion = read_motion(motion_path)
        if abs(motion.fps - fps) > 1e-6:
            motion = motion.resample(fps)
        skel = motion.skeleton
        positions = motion.to_positions().astype(np.float64)
        start, end = job["start"], job["end"]
        y, sr = load(song, sr=22050, mono=True)
        duration = len(y) / sr
        end = min(x for x in (end, duration, len(positions) / fps) if x is not None)
        first = int(round(start * fps))
        T = int(np.floor((end - start) * fps + 1e-6))
        if T < MIN_FRAMES:
            return {"error": f"too short: {max(T, 0)} frames in [{start:g}, {end:g}) s (song {duration:.1f} s, "
                             f"motion {len(positions) / fps:.1f} s)"}
        positions = positions[first:first + T]
        try:
            floor = floor_curve(positions, skel, fps=fps)
        except (DancekitError, ValueError, KeyError, IndexError):
            floor = np.full(len(positions), positions[..., skel.up_index].min())
        positions[..., skel.up_index] -= floor[:, None]
        feats = {}
        for preset in job["presets"]:
            fs = extract_file(song, fps=fps, preset=preset, start=start, end=start + T / fps,
                              hop_length=job["hop_length"], use_cache=False)
            if abs(len(fs.features) - T) > 2:
                return {"error": f"{preset} features have {len(fs.features)} frames for {T} motion frames"}
            feats[preset] = fs
            T = min(T, len(fs.features))
        motion = Motion(skeleton=skel, fps=fps, positions=positions[:T].astype(np.float32))
        try:
            motion = motion.with_rotations()
        except (DancekitError, ValueError, KeyError, IndexError):
            pass  # positions only: a skeleton whose rotations cannot be solved
        out = Path(job["dir"])
        out.mkdir(parents=True)
        write_motion(out / "motion.npz", motion)
        for preset, fs in feats.items():
            beats = np.asarray(fs.beat_times, np.float64)
            np.savez(out / f"features_{preset}.npz", features=np.asarray(fs.features[:T], np.float32),
                     names=np.asarray(list(fs.names)), beat_times=beats[beats < T / fps], fps=np.float64(fps),
                     preset=np.asarray(preset))
    except DancekitError as exc:
        return {"error": str(exc)}
    except (OSError, ValueError, EOFError, KeyError, IndexError) as exc:  # a broken file of another kind
        return {"error": f"{type(exc).__name__}: {exc}"}
    return {"genre": job["genre"], "frames": int(T), "floor_offset": [float(floor.min()), float(floor.max())],
            "audio": [str(song.resolve()), float(start), float(start + T / fps)],
            "motion_source": str(motion_path), "skeleton": skel.to_dict()}


def check_prepare_args(*, presets: tuple[str, ...], fps: float, workers: int) -> float:
    """Check the arguments every ``prepare`` shares; returns ``fps`` as a float.

    Raises
    ------
    ParameterError
        For an unknown preset, a bad ``fps`` or ``workers`` < 1.
    """
    from dancekit.features import PRESET_DIMS

    for p in presets:
        if p not in PRESET_DIMS:
            raise ParameterError(f"unknown feature preset {p!r}; choose from {sorted(PRESET_DIMS)}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an integer >= 1, got {workers!r}")
    return check_fps(fps)


def prepare_pairs(
    src: str | os.PathLike,
    out: str | os.PathLike,
    *,
    fps: float = 25.0,
    presets: tuple[str, ...] = ("revolution",),
    seed: int = 0,
    hop_length: int = 512,
    workers: int = 1,
    progress: bool = True,
) -> tuple[Path, dict[str, Any]]:
    """Prepare the music–dance pairs of the folder ``src`` into ``out`` (see the module docstring).

    Parameters
    ----------
    src : folder of songs and motion files paired by name (optional ``pairs.csv`` / ``pairs.json``)
    out : folder to create (replaced once complete)
    fps : motion and feature frame rate (motions are resampled)
    presets : music feature presets to compute
    seed : seed of the split
    workers : processes preparing pairs in parallel

    Returns
    -------
    (``out``, the report): ``{"prepared": [names], "skipped": [{"file", "reason"}], ...}``, also written to
    ``out/report.json``.

    Raises
    ------
    DatasetError
        When ``src`` is not a folder, holds no usable pair, or its ``pairs.csv`` / ``pairs.json`` is malformed.
    ParameterError
        For an unknown preset, a bad ``fps`` or ``workers``.
    """
    src = Path(src)
    if not src.is_dir():
        raise DatasetError(f"pairs source folder not found: {src}")
    fps = check_prepare_args(presets=presets, fps=fps, workers=workers)
    labels = _read_labels(src)
    pairs, skipped = find_pairs(src)
    if not pairs:
        raise DatasetError(f"no song and motion file share a name in {src} (skipped: {len(skipped)} files)")
    return prepare_dataset(src, out, pairs, skipped, labels=labels, source="pairs", fps=fps, presets=presets,
                           seed=seed, hop_length=hop_length, workers=workers, progress=progress)


def prepare_dataset(
    src: Path,
    out: str | os.PathLike,
    pairs: dict[str, tuple[Path, Path]],
    skipped: list[dict[str, str]],
    *,
    labels: dict[str, dict[str, Any]],
    source: str,
    fps: float,
    presets: tuple[str, ...],
    seed: int = 0,
    hop_length: int = 512,
    workers: int = 1,
    progress: bool = True,
    splits: dict[str, list[str]] | None = None,
) -> tuple[Path, dict[str, Any]]:
    """The machinery of :func:`prepare_pairs` and :func:`dancekit.data.aistpp.prepare_aistpp`: prepare every
    (song, motion) pair of ``pairs`` (name → paths) in ``workers`` processes into ``out`` (atomically), skip
    and report the broken ones and those of a minority skeleton; ``labels`` give per-pair ``start``, ``end``,
    ``genre``; ``splits`` (``{"train": [names], "val": ..., "test": ...}``) are used as given (restricted to
    the pairs prepared), else whole dances are split by genre with ``seed``."""
    from tqdm import tqdm

    with atomic_dir(out) as tmp:
        jobs = [{"name": n, "song": str(s), "motion": str(m), "fps": fps, "presets": tuple(presets),
                 "hop_length": hop_length, "dir": str(tmp / "dances" / n), **labels.get(n, {}),
                 } for n, (s, m) in pairs.items()]
        for j in jobs:
            j.setdefault("start", 0.0)
            j.setdefault("end", None)
            j.setdefault("genre", "unknown")
        bar = tqdm(total=len(jobs), desc=f"prepare {source}", unit="pair", disable=not progress)
        results: dict[str, dict[str, Any]] = {}
        if workers == 1:
            for j in jobs:
                results[j["name"]] = _prepare_one(j)
                bar.update(1)
        else:
            # spawned, not forked: a fork of a process whose BLAS / OpenMP / numba threads are running can deadlock
            # one thread each: N workers on N cores, not N x (BLAS / OpenMP threads) (children inherit the environment)
            with _one_thread_each(), ProcessPoolExecutor(max_workers=workers,
                                                         mp_context=multiprocessing.get_context("spawn")) as pool:
                for j, r in zip(jobs, pool.map(_prepare_one, jobs), strict=True):
                    results[j["name"]] = r
                    bar.update(1)
        bar.close()
        for name, r in results.items():
            if "error" in r:
                skipped.append({"file": f"{pairs[name][0].name} + {pairs[name][1].name}", "reason": r["error"]})
        good = {n: r for n, r in results.items() if "error" not in r}
        if not good:
            raise DatasetError(f"no pair of {src} could be prepared: "
                               + "; ".join(f"{s['file']}: {s['reason']}" for s in skipped[:5]))
        # one skeleton per dataset (the same joints and tree): that of most pairs (ties: the most frames)
        key = {n: json.dumps([r["skeleton"].get("joint_names"), r["skeleton"].get("parents")]) for n, r in good.items()}
        votes, frames = Counter(key.values()), Counter()
        for n, k in key.items():
            frames[k] += good[n]["frames"]
        chosen = max(votes, key=lambda k: (votes[k], frames[k]))
        skeleton = good[min(n for n in good if key[n] == chosen)]["skeleton"]
        for n in sorted(good):
            if key[n] != chosen:
                skipped.append({"file": f"{pairs[n][0].name} + {pairs[n][1].name}",
                                "reason": f"its skeleton ({len(json.loads(key[n])[0] or [])} joints) differs from "
                                          f"the dataset's ({len(json.loads(chosen)[0] or [])} joints, that of most "
                                          "pairs)"})
                shutil.rmtree(tmp / "dances" / n)
                del good[n]
        dances = {n: {k: v for k, v in r.items() if k != "skeleton"} for n, r in good.items()}
        by_genre: dict[str, list[str]] = {}
        for n, d in dances.items():
            by_genre.setdefault(d["genre"], []).append(n)
        if splits is not None:
            given = splits
            splits = {k: sorted(n for n in given.get(k, ()) if n in dances) for k in ("train", "val", "test")}
            splits["method"] = f"the {source} release's own splits"
        else:
            splits = split_by_genre(by_genre, seed=seed)
            splits["seed"] = seed
            splits["method"] = "whole dances, stratified by genre (dancekit.data.split_by_genre)"
        meta = {"source": source, "source_path": str(src.resolve()), "fps": fps, "hop_length": hop_length,
                "skeleton": skeleton, "presets": list(presets), "genres": sorted(by_genre),
                "dances": dances}
        report = {"source": str(src.resolve()), "prepared": sorted(dances), "skipped": skipped}
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1))
        (tmp / "splits.json").write_text(json.dumps(splits, indent=1))
        (tmp / "report.json").write_text(json.dumps(report, indent=1))
    return Path(out), report
