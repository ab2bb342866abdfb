"""Beat alignment between a dance and its music.

Kinematic beats (:func:`dancekit.motion.analysis.kinematic_beats`, re-exported here)
    Local minima of the mean joint speed: joint velocities by central differences (world
    positions, so the root's travel counts, as in AIST++), speed averaged over joints, then
    smoothed with a Gaussian of standard deviation ``smooth`` seconds (default 5/60 s, the
    5 frames at 60 fps of the AIST++ / Bailando code), then every strict local minimum
    (``scipy.signal.argrelextrema(np.less)``). Beats are returned in seconds; frame ``t``
    is at ``t / fps``.

Beat alignment score (BAS), two conventions
    ``exp(-d² / 2σ²)`` with ``d`` the distance to the nearest beat of the other kind, σ in
    seconds (default 0.05 s = 3 frames at 60 fps, as in the reference code), averaged over

    * the *music* beats (``convention="bailando"``, the Bailando / EDGE code and most papers'
      tables), or
    * the *kinematic* beats (``convention="aist"``, the AIST++ / FACT paper's definition).

    Only music beats inside the dance (``0 <= t <= (T-1) / fps``) are used.

Beat coverage and beat hit rate (Dance Revolution Table 2, after Lee et al. 2019)
    ``coverage = B_k / B_m`` and ``hit_rate = B_a / B_k``, with ``B_k`` the number of
    kinematic beats, ``B_m`` the number of music beats and ``B_a`` the number of kinematic
    beats within ``tolerance`` seconds of a music beat. The default tolerance is 0.1 s;
    the dual-learning paper's "beats alignment" is the hit rate with ``tolerance=0.2``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancekit._checks import check_fps, check_times
from dancekit.errors import ParameterError
from dancekit.motion.analysis import DEFAULT_BEAT_SMOOTH, kinematic_beats, mean_joint_speed

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

__all__ = [
    "beat_align_score",
    "beat_coverage",
    "beat_hit_rate",
    "beat_metrics",
    "kinematic_beats",
    "mean_joint_speed",
]

DEFAULT_SMOOTH = DEFAULT_BEAT_SMOOTH
DEFAULT_SIGMA = 0.05
DEFAULT_TOLERANCE = 0.1


def _nearest_distance(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """For every time in ``x``, the distance to the nearest time in ``y`` (y sorted, non-empty)."""
    k = np.searchsorted(y, x)
    left = y[np.clip(k - 1, 0, len(y) - 1)]
    right = y[np.clip(k, 0, len(y) - 1)]
    return np.minimum(np.abs(x - left), np.abs(x - right))


def _in_dance(music_beats: np.ndarray, duration: float | None) -> np.ndarray:
    if duration is None:
        return music_beats
    return music_beats[(music_beats >= 0) & (music_beats <= duration + 1e-9)]


def beat_align_score(
    kinematic: np.ndarray,
    music: np.ndarray,
    *,
    sigma: float = DEFAULT_SIGMA,
    convention: str = "bailando",
    duration: float | None = None,
) -> float:
    """Beat alignment score in [0, 1].

    Parameters
    ----------
    kinematic : kinematic beat times, seconds
    music : music beat times, seconds
    sigma : tolerance of the Gaussian, seconds
    convention : ``"bailando"`` (mean over music beats) or ``"aist"`` (mean over kinematic beats)
    duration : dance duration in seconds; music beats outside ``[0, duration]`` are ignored

    Returns
    -------
    float; 0 when the beats averaged over exist but the other list is empty, NaN when the
    beats averaged over do not exist.
    """
    if not sigma > 0:
        raise ParameterError(f"sigma must be positive seconds, got {sigma}")
    k = check_times(kinematic, "kinematic beats")
    m = _in_dance(check_times(music, "music beats"), duration)
    if convention == "bailando":
        over, other = m, k
    elif convention == "aist":
        over, other = k, m
    else:
        raise ParameterError(f"unknown BAS convention {convention!r}; choose 'bailando' or 'aist'")
    if len(over) == 0:
        return float("nan")
    if len(other) == 0:
        return 0.0
    d = _nearest_distance(over, other)
    return float(np.mean(np.exp(-(d**2) / (2.0 * sigma**2))))


def beat_coverage(kinematic: np.ndarray, music: np.ndarray, *, duration: float | None = None) -> float:
    """``B_k / B_m``: kinematic beats per music beat (NaN without music beats)."""
    k = check_times(kinematic, "kinematic beats")
    m = _in_dance(check_times(music, "music beats"), duration)
    return float(len(k) / len(m)) if len(m) else float("nan")


def beat_hit_rate(
    kinematic: np.ndarray, music: np.ndarray, *, tolerance: float = DEFAULT_TOLERANCE, duration: float | None = None
) -> float:
    """``B_a / B_k``: share of kinematic beats within ``tolerance`` seconds of a music beat (NaN without kinematic beats)."""
    if not tolerance >= 0:
        raise ParameterError(f"tolerance must be >= 0 seconds, got {tolerance}")
    k = check_times(kinematic, "kinematic beats")
    m = _in_dance(check_times(music, "music beats"), duration)
    if len(k) == 0:
        return float("nan")
    if len(m) == 0:
        return 0.0
    return float(np.mean(_nearest_distance(k, m) <= tolerance + 1e-12))


def beat_metrics(
    positions: np.ndarray,
    music_beats: np.ndarray,
    *,
    fps: float,
    skeleton: Skeleton | None = None,
    sigma: float = DEFAULT_SIGMA,
    tolerance: float = DEFAULT_TOLERANCE,
    smooth: float | None = DEFAULT_SMOOTH,
) -> dict[str, float]:
    """Every beat metric of one dance against its music beats (seconds).

    Returns ``bas_bailando``, ``bas_aist``, ``beat_coverage``, ``beat_hit_rate`` (at
    ``tolerance``), ``beat_hit_rate_dual`` (0.2 s, the dual-learning "beats alignment"),
    ``n_kinematic`` and ``n_music`` (music beats inside the dance).
    """
    fps = check_fps(fps)
    k = kinematic_beats(positions, fps=fps, skeleton=skeleton, smooth=smooth)
    duration = (len(positions) - 1) / fps
    m = _in_dance(check_times(music_beats, "music beats"), duration)
    return {
        "bas_bailando": beat_align_score(k, m, sigma=sigma, convention="bailando"),
        "bas_aist": beat_align_score(k, m, sigma=sigma, convention="aist"),
        "beat_coverage": beat_coverage(k, m),
        "beat_hit_rate": beat_hit_rate(k, m, tolerance=tolerance),
        "beat_hit_rate_dual": beat_hit_rate(k, m, tolerance=0.2),
        "n_kinematic": int(len(k)),
        "n_music": int(len(m)),
    }
