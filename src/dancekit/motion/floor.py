"""The floor under a dance: where it is (a local floor: captured floors are not level) and how the dance meets it.

NumPy in, NumPy out (keyword-only arguments). Arrays are world joint positions ``(T, J, 3)`` in the skeleton's
units at ``fps`` frames per second; heights along the skeleton's up axis.

These are measures, and :mod:`dancekit.metrics.floor` reports them; they live in ``motion`` because processing
steps below the metrics act on them (docs/ARCHITECTURE.md's layer table: metrics may import motion, not the
reverse): the foot lock keeps a planted-foot share (:func:`dancekit.motion.footlock.lock_feet_to_share`) and
the pipeline's re-grounding bounds the float (:func:`floor_float_cm`).

=============================  ====================================================================
function                       what
=============================  ====================================================================
:func:`local_floor`            per frame, the lowest point of the lowest joint within a window (m)
:func:`floor_gap_cm`           per frame, the lowest joint's height over the local floor (cm)
:func:`floor_float_cm`         its median: how far the figure floats
:func:`planted_share`          the share of foot-frames whose lowest joint is on the local floor
                               and still (the planted-foot share of docs/BENCHMARKS.md)
=============================  ====================================================================
"""

from __future__ import annotations

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.analysis import heights, leg_chains
from dancekit.motion.skeleton import Skeleton

__all__ = ["PLANTED_HEIGHT_M", "PLANTED_SPEED", "floor_float_cm", "floor_gap_cm", "local_floor", "planted_share"]

#: :func:`planted_share`'s thresholds: the foot's lowest joint at most this high over the local floor (m) ...
PLANTED_HEIGHT_M = 0.03
#: ... and slower than this (m/s, the joint's speed in 3-D).
PLANTED_SPEED = 0.15


def _check(positions: np.ndarray, name: str) -> np.ndarray:
    p = np.array(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"{name} needs (T, J, 3) positions, got shape {np.shape(positions)}")
    return p


def local_floor(p: np.ndarray, skeleton: Skeleton, fps: float, window_s: float) -> np.ndarray:
    """(T,) the floor under each frame of ``p`` ``(T, J, 3)``: the lowest point of the lowest joint within
    ±``window_s``/2 seconds, metres along the up axis."""
    from dancekit.motion.filters import minimum_filter1d

    low = heights(p, skeleton).min(axis=1) * skeleton.unit_scale
    return minimum_filter1d(low, 2 * int(round(window_s * fps / 2)) + 1)


def floor_gap_cm(positions: np.ndarray, *, skeleton: Skeleton, fps: float) -> np.ndarray:
    """(T,) cm: per frame, the lowest joint's height above the *local floor* (the lowest point of the lowest
    joint within ±1 s; tang2018's captured floor is not level). docs/BENCHMARKS.md's floor metrics (issue 15)
    are its median (:func:`floor_float_cm`) and its share of frames within 2 cm.

    Parameters
    ----------
    positions : (T, J, 3) world positions in skeleton units at ``fps``
    skeleton, fps : the skeleton (up axis, units) and the frame rate
    """
    fps = check_fps(fps)
    p = _check(positions, "floor_gap_cm")
    low = heights(p, skeleton).min(axis=1) * skeleton.unit_scale  # (T,) metres
    return (low - local_floor(p, skeleton, fps, 2.0)) * 100.0


def floor_float_cm(positions: np.ndarray, *, skeleton: Skeleton, fps: float) -> float:
    """How far the figure floats: the median of :func:`floor_gap_cm` over frames, cm (real tang2018 dances
    0.8-1.3 cm, the issue's bound 2 cm)."""
    return float(np.median(floor_gap_cm(positions, skeleton=skeleton, fps=fps)))


def planted_share(positions: np.ndarray, *, skeleton: Skeleton, fps: float,
                  height_m: float = PLANTED_HEIGHT_M, speed: float = PLANTED_SPEED) -> float:
    """The share of foot-frames in which the foot is planted (0-1; NaN for a skeleton without legs).

    Per leg of :func:`leg_chains` and frame, the foot's lowest joint (ankle, heel or toe) counts as planted
    when it is at most ``height_m`` metres above the *local floor* (the lowest joint of the whole body within
    ±1 s) and that joint moves slower than ``speed`` m/s (central differences, in 3-D). This is the
    planted-foot share docs/BENCHMARKS.md reports (issue 15): real tang2018 dances read 0.09-0.50 per dance,
    0.28 on average for the training waltzes.

    Parameters
    ----------
    positions : (T, J, 3) world positions in skeleton units at ``fps``
    skeleton, fps : the skeleton (up axis, units, legs) and the frame rate
    height_m, speed : the thresholds (m, m/s)
    """
    fps = check_fps(fps)
    p = _check(positions, "planted_share")
    legs = leg_chains(skeleton)
    if not legs:
        return float("nan")
    h = heights(p, skeleton) * skeleton.unit_scale  # (T, J) metres
    local = local_floor(p, skeleton, fps, 2.0)  # the lowest joint within ±1 s
    t = np.arange(len(p))
    cols = []
    for _hip, _knee, ankle, below in legs:
        foot = np.array([ankle, *below])
        v = np.linalg.norm(np.gradient(p[:, foot], axis=0), axis=-1) * fps * skeleton.unit_scale if len(p) > 1 \
            else np.zeros((len(p), len(foot)))
        low = h[:, foot].argmin(axis=1)
        cols.append((h[t, foot[low]] - local <= height_m) & (v[t, low] < speed))
    return float(np.mean(np.stack(cols, axis=1)))
