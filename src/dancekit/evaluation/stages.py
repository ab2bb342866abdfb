"""What the pipeline stages change, and how different the seeds' dances are: two report sections.

``beat_sync`` (:func:`beat_sync_comparison`)
    The beat metrics (BAS in both conventions, beat hit rate, coverage) of the same dances before and
    after the beat-synchronous warp (:mod:`dancekit.pipelines.stages`), against the same music beats.

``seed_distance`` (:func:`seed_distance`)
    Per second of the song, the mean per-frame distance (cm) between the dances of two seeds for one
    song, and, for scale, between the dances of two different songs (same seed, for every seed both songs
    have, cropped to the shorter; averaged over those pairs, so one song pair is not one sample).
    Poses are compared relative to their root and in the body's heading frame
    (:func:`dancekit.motion.analysis.heading_rotation`: the root's travel and the figure's turns left out,
    so the same dance drifting or facing elsewhere is not "different"); joint distances are averaged over joints, then over frames of each
    second and over pairs. ``converged_after_s`` is the first second from which the seed distance stays
    below half the between-song distance to the end (None: it never does; 0.0: from the start).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dancekit.metrics import beat as beat_mod

__all__ = ["beat_sync_comparison", "seed_distance"]

_BEAT_KEYS = ("bas_bailando", "bas_aist", "beat_hit_rate", "beat_coverage")


def beat_sync_comparison(before: Mapping[str, Sequence[Any]], after: Mapping[str, Sequence[Any]],
                         music_beats: Mapping[str, np.ndarray], *, sigma: float = beat_mod.DEFAULT_SIGMA,
                         tolerance: float = beat_mod.DEFAULT_TOLERANCE) -> dict[str, Any]:
    """Mean beat metrics of the dances ``before`` and ``after`` the warp (name → motions, the same names
    and order), against ``music_beats`` (name → seconds from the dance start)."""
    out: dict[str, Any] = {}
    for label, dances in (("before", before), ("after", after)):
        rows = []
        for name in sorted(dances):
            for m in dances[name]:
                rows.append(beat_mod.beat_metrics(m.to_positions(), music_beats[name], fps=m.fps, skeleton=m.skeleton,
                                                  sigma=sigma, tolerance=tolerance))
        out[label] = {k: _finite_mean([r[k] for r in rows]) for k in _BEAT_KEYS}
        out[label]["n_dances"] = len(rows)
    return out


def _finite_mean(values: list[float]) -> float:
    """Mean of the finite values (NaN when there is none, without a warning)."""
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    return float(arr.mean()) if arr.size else float("nan")


def _pose(m: Any) -> np.ndarray:
    """(T, J, 3) cm: joints relative to the root, in the body's heading frame (travel and turns left out)."""
    from dancekit.motion.analysis import heading_rotation

    p = np.asarray(m.to_positions(), np.float64) * m.skeleton.unit_scale * 100.0  # cm
    rel = p - p[:, m.skeleton.root : m.skeleton.root + 1]
    return np.einsum("tij,tkj->tki", heading_rotation(p, m.skeleton), rel)


def _per_second(a: np.ndarray, b: np.ndarray, fps: float) -> np.ndarray:
    n = min(len(a), len(b))
    d = np.linalg.norm(a[:n] - b[:n], axis=-1).mean(axis=1)  # (n,) cm
    sec = (np.arange(n) / fps).astype(int)
    return np.bincount(sec, weights=d) / np.maximum(np.bincount(sec), 1)


def _mean_curves(curves: list[np.ndarray]) -> np.ndarray:
    if not curves:
        return np.zeros(0)
    n = max(len(c) for c in curves)
    total, count = np.zeros(n), np.zeros(n)
    for c in curves:
        total[: len(c)] += c
        count[: len(c)] += 1
    return total / np.maximum(count, 1)


def seed_distance(pred: Mapping[str, Sequence[Any]]) -> dict[str, Any]:
    """The ``seed_distance`` section (see the module docstring) for name → the dances of several seeds.

    ``pred[name][k]`` is the dance of seed index ``k`` (``NAME__k``); two songs are compared seed by seed
    (their ``k``-th dances, for every ``k`` both have), and the curves of all these pairs are averaged.

    Returns ``{"seed_cm": [...], "song_cm": [...]`` (per second), ``"song_seed0_cm"`` (the between-song
    curve of the first dances alone, one pair per song pair: what the report gave before the fifteenth
    session), ``"seed_mean_cm"``, ``"song_mean_cm"``, ``"seed_after_2s_cm"``, ``"converged_after_s"``,
    ``"pairs": {"seed": n, "song": n}}`` (dance pairs behind each curve); empty curves when no song has
    two dances (or there are fewer than two songs).
    """
    names = sorted(pred)
    poses = {name: [_pose(m) for m in pred[name]] for name in names}  # each dance's poses once, for both curves
    seed_curves = []
    for name in names:
        fps = float(pred[name][0].fps) if pred[name] else 1.0
        for i, j in itertools.combinations(range(len(poses[name])), 2):
            seed_curves.append(_per_second(poses[name][i], poses[name][j], fps))
    song_curves, first_curves = [], []
    for a, b in itertools.combinations(names, 2):
        for k in range(min(len(pred[a]), len(pred[b]))):  # the k-th dance of each song: the same seed
            curve = _per_second(poses[a][k], poses[b][k], float(pred[a][k].fps))
            song_curves.append(curve)
            if k == 0:
                first_curves.append(curve)
    seed_c, song_c = _mean_curves(seed_curves), _mean_curves(song_curves)
    converged = None
    if len(seed_c) and len(song_c):
        n = min(len(seed_c), len(song_c))
        below = seed_c[:n] < 0.5 * song_c[:n]
        if below[-1]:
            above = np.flatnonzero(~below)
            converged = float(above[-1] + 1) if len(above) else 0.0
    return {
        "seed_cm": [round(float(v), 3) for v in seed_c],
        "song_cm": [round(float(v), 3) for v in song_c],
        "song_seed0_cm": [round(float(v), 3) for v in _mean_curves(first_curves)],
        "seed_mean_cm": float(seed_c.mean()) if len(seed_c) else float("nan"),
        "song_mean_cm": float(song_c.mean()) if len(song_c) else float("nan"),
        "seed_after_2s_cm": float(seed_c[2:].mean()) if len(seed_c) > 2 else float("nan"),
        "converged_after_s": converged,
        "pairs": {"seed": len(seed_curves), "song": len(song_curves)},
    }
