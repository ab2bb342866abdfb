"""A prepared dataset with a preset's features as a live session computes them (:func:`prepare_online`).

A model that ``dancekit live`` steps sees the rows of :class:`dancekit.features.online.OnlineFeatures` (computed as
the audio arrives, with a short lookahead), not the offline extractor's. :func:`prepare_online` writes a copy of a
prepared dataset (:mod:`dancekit.data.prepared`) whose ``features_<preset>.npz`` hold those rows — each song fed in
blocks of ``block_s`` with the live session's settings — so that a model can be trained on what it will get live
(``dancekit prepare online DATA -o OUT``, then ``dancekit train … --data OUT``). The motion, the splits and the other
presets' features are the source's; ``meta.json`` records the settings under ``"online_features"``.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from dancekit._io import atomic_dir
from dancekit.data.prepared import PreparedData
from dancekit.errors import DatasetError, ParameterError

__all__ = ["ONLINE_DEFAULTS", "prepare_online"]

#: the live session's defaults (``dancekit.live.LiveConfig``: block, feature lookahead, context, beat window; s)
ONLINE_DEFAULTS = {"block_s": 0.04, "lookahead_s": 0.08, "context_s": 6.0, "beat_window_s": 6.0,
                   "tempogram_future": "bar"}


def _one(job: tuple) -> tuple[str, int]:
    """One dance's online rows written to ``dance_dir`` (a worker's task)."""
    from threadpoolctl import threadpool_limits

    from dancekit.audio import load
    from dancekit.features.online import online_rows
    from dancekit.features.presets import feature_sr

    name, path, start, end, preset, fps, hop, settings, dance_dir, offline_frames, names = job
    y, _ = load(path, sr=feature_sr(fps=fps, hop_length=hop), start=start, end=end)
    with threadpool_limits(1):  # one BLAS thread per dance: several workers would oversubscribe the cores
        rows, beats = online_rows(y, preset=preset, fps=fps, hop_length=hop, **settings)
    if not 0 <= len(rows) - offline_frames <= 2:
        raise DatasetError(f"{name}: {len(rows)} online {preset} rows for {offline_frames} offline (alignment broken)")
    T = offline_frames
    np.savez(Path(dance_dir) / f"features_{preset}.npz", features=rows[:T], names=names,
             beat_times=beats[beats < T / fps], fps=np.float64(fps), preset=np.asarray(preset))
    return name, T


def prepare_online(src: str | os.PathLike, out: str | os.PathLike, *, presets: tuple[str, ...] = ("revolution",),
                   workers: int = 1, progress: bool = True, **settings: float) -> Path:
    """Copy the prepared dataset ``src`` to ``out`` with ``presets``' features replaced by the online rows.

    Parameters
    ----------
    src : a prepared dataset folder (``dancekit prepare``)
    out : folder to create (replaced once complete)
    presets : presets to recompute (``revolution``, ``music2dance``: the ones live dancing runs)
    workers : processes (one dance each at a time)
    settings : ``block_s``, ``lookahead_s``, ``context_s``, ``beat_window_s`` (s) and ``tempogram_future``
        (``"bar"`` or ``"none"``); default :data:`ONLINE_DEFAULTS`, the live session's
    """
    from concurrent.futures import ProcessPoolExecutor

    from tqdm import tqdm

    from dancekit.features.online import OnlineFeatures

    data = PreparedData(src)
    unknown = sorted(set(settings) - set(ONLINE_DEFAULTS))
    if unknown:
        raise ParameterError(f"unknown online feature setting(s) {unknown}; known: {sorted(ONLINE_DEFAULTS)}")
    merged = dict(ONLINE_DEFAULTS)
    for key, value in settings.items():
        if key != "tempogram_future":
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"online feature setting {key} must be a number of seconds, got {value!r}") \
                    from None
        merged[key] = value
    settings = merged
    fps, hop = data.fps, int(data.meta["hop_length"])
    if not 0 < settings["block_s"] <= 2.0:
        raise ParameterError(f"online feature setting block_s must be in (0, 2] s, got {settings['block_s']!r}")
    for p in presets:
        if p not in ("revolution", "music2dance"):
            raise ParameterError(f"online features exist for the presets revolution and music2dance, not {p!r}")
        if p not in data.presets:
            raise DatasetError(f"{data.root} has no {p!r} features to replace (prepared presets: {data.presets})")
        # the features' own checks of the settings, here rather than in a worker
        OnlineFeatures(preset=p, fps=fps, hop_length=hop, **{k: v for k, v in settings.items() if k != "block_s"})
    if Path(out).resolve() == data.root.resolve():
        raise ParameterError(f"the online copy must go to another folder than its source {data.root}")
    replaced = {f"features_{p}.npz" for p in presets}
    with atomic_dir(out) as tmp:
        jobs = []
        for name in data.names():
            dance_dir = tmp / "dances" / name
            dance_dir.mkdir(parents=True)
            for f in sorted((data.root / "dances" / name).iterdir()):
                if f.is_file() and f.name not in replaced:
                    shutil.copy2(f, dance_dir / f.name)
            ref = data.audio(name)
            for p in presets:
                offline = data.features(name, p)
                jobs.append((name, ref.path, ref.start, ref.end, p, fps, hop, settings, str(dance_dir),
                             len(offline["features"]), offline["names"]))
        bar = tqdm(total=len(jobs), desc="online features", unit="dance", disable=not progress)
        if workers > 1:
            with ProcessPoolExecutor(workers) as pool:
                for _ in pool.map(_one, jobs):
                    bar.update()
        else:
            for job in jobs:
                _one(job)
                bar.update()
        bar.close()
        meta = dict(data.meta)
        meta["online_features"] = {"presets": list(presets), **settings,
                                   "source": str(data.root.resolve())}
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1))
        shutil.copy2(data.root / "splits.json", tmp / "splits.json")
    return Path(out)
