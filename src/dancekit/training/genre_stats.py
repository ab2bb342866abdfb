"""Per-genre statistics of real dances: the ``"genre_stats"`` tables a dance checkpoint's stages compare a
generated dance with (:class:`dancekit.pipelines.config.GenreStats`).

Per genre, over the real dances given (a checkpoint's training split):

* ``jitter``: the median speed (m/s) a 5-frame average removes (:func:`dancekit.motion.jitter.jitter_speed`,
  equal to :func:`dancekit.metrics.stability.jitter`'s ``speed_residual``);
* ``energy``: the median smoothed energy (m/s, :func:`dancekit.motion.energy.smoothed_energy`);
* ``planted_share``: the mean share of foot-frames with a planted foot (:func:`dancekit.motion.floor.planted_share`);
* ``smoothing``: the median jitter-to-energy ratio of the smoothing stage (:func:`dancekit.motion.jitter.smoothing_window`'s).

Each value rounded to :data:`DECIMALS` decimals, genres in the order of :data:`dancekit.data.prepared.GENRES`
(then any other, sorted).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from dancekit.motion import Motion

__all__ = ["DECIMALS", "MEASURES", "genre_stats", "prepared_genre_stats", "tang2018_genre_stats"]

#: the decimals the tables are stored with
DECIMALS = 3
#: table name → how its per-dance values are pooled per genre
MEASURES = {"jitter": "median", "energy": "median", "planted_share": "mean", "smoothing": "median"}


def _values(motion: Motion) -> dict[str, float]:
    from dancekit.motion.energy import smoothed_energy
    from dancekit.motion.floor import planted_share
    from dancekit.motion.jitter import jitter_ratio, jitter_speed

    sk, fps = motion.skeleton, motion.fps
    p = np.asarray(motion.to_positions(), np.float64)
    return {"jitter": float(jitter_speed(p, skeleton=sk, fps=fps)),
            "energy": float(smoothed_energy(p, skeleton=sk, fps=fps)),
            "planted_share": float(planted_share(p, skeleton=sk, fps=fps)),
            "smoothing": float(jitter_ratio(np.asarray(motion.to_positions()), sk, fps))}


def genre_stats(dances: Iterable[tuple[str, Motion]]) -> dict[str, dict[str, float]]:
    """The four tables (table → genre → value, :data:`MEASURES`) of ``dances``, pairs of (genre, real dance)."""
    from dancekit.data.prepared import GENRES

    per: dict[str, dict[str, list[float]]] = {}
    for genre, motion in dances:
        for name, v in _values(motion).items():
            per.setdefault(name, {}).setdefault(str(genre), []).append(v)
    out: dict[str, dict[str, float]] = {}
    for name, how in MEASURES.items():
        table = per.get(name, {})
        order = [g for g in GENRES if g in table] + sorted(g for g in table if g not in GENRES)
        pool = np.median if how == "median" else np.mean
        out[name] = {g: round(float(pool(table[g])), DECIMALS) for g in order}
    return out


def tang2018_genre_stats(root: str | os.PathLike, names: Iterable[str], *,
                         fps: float = 25.0) -> dict[str, dict[str, float]]:
    """:func:`genre_stats` of the tang2018 dances ``names`` (folders ``DANCE_<W|R|C|T>_<n>`` under ``root``) as
    ``dancekit prepare tang2018`` makes them (:func:`dancekit.data.prepared.level_tang2018`: the floor levelled
    to 0 frame by frame, float32): the tables ``dancekit train`` writes from the prepared dataset
    (:func:`prepared_genre_stats`), recomputed from the raw dances without preparing their music."""
    from dancekit.data.prepared import level_tang2018, tang2018_genre

    def dances():
        for name in names:
            yield tang2018_genre(name), level_tang2018(Path(root) / name, fps=fps)[0]

    return genre_stats(dances())


def prepared_genre_stats(data, split: str = "train") -> dict[str, dict[str, float]]:
    """:func:`genre_stats` of a prepared dataset's ``split`` (:class:`dancekit.data.PreparedData`)."""
    return genre_stats((data.genre(name), data.motion(name)) for name in data.names(split))
