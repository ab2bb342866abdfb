"""Long-term stability: does the dance keep moving, and how smoothly?

All speeds are *body-relative* (every joint minus the pelvis of the same frame, so a dancer
gliding across the floor in a frozen pose counts as still) and in metres per second
(through ``skeleton.unit_scale``), so thresholds hold for any units and frame rate.

* :func:`freeze_score` — motion energy (mean squared body-relative joint speed) of the last
  ``window`` seconds over that of the first ``window`` seconds (default 10 s; for dances
  shorter than two windows, the first and last halves). About 1 for a steady dance, near 0
  for a dance that freezes.
* :func:`stillness_share` — share of consecutive non-overlapping 1-second windows whose mean
  body-relative joint speed is below 0.10 m/s (10 cm/s).
* :func:`smoothed_energy` — mean body-relative joint speed after a 5-frame centred moving
  average of the positions.
* :func:`jitter` — raw mean speed minus smoothed mean speed (the speed that the 5-frame
  average removes), and the mean jerk magnitude (third finite difference, m/s³).
* :func:`windowed_fid` — FID over consecutive windows (Dance Revolution Fig. 4): the feature
  vectors of window ``k`` of every generated dance against the whole reference set.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from dancekit.errors import ParameterError
from dancekit.metrics._common import (
    body_relative,
    check_fps,
    check_positions,
    joint_speed,
    moving_average,
    to_metres,
)
from dancekit.metrics.fid import frechet_distance

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

__all__ = [
    "body_speed",
    "freeze_score",
    "jitter",
    "smoothed_energy",
    "stillness_share",
    "windowed_fid",
]


def body_speed(positions: np.ndarray, *, fps: float, skeleton: Skeleton) -> np.ndarray:
    """Body-relative joint speeds ``(T, J)`` in m/s."""
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=2), skeleton)
    return joint_speed(body_relative(p, skeleton), fps)


def freeze_score(
    positions: np.ndarray, *, fps: float, skeleton: Skeleton, window: float = 10.0
) -> float:
    """Energy of the last ``window`` seconds over the first ``window`` seconds.

    Energy = mean over frames and joints of the squared body-relative speed (m²/s²).
    Returns NaN if the first window has no motion at all.
    """
    if not window > 0:
        raise ParameterError(f"freeze window must be positive seconds, got {window}")
    speed = body_speed(positions, fps=fps, skeleton=skeleton)
    n = max(1, min(int(round(window * fps)), len(speed) // 2))
    first = float(np.mean(speed[:n] ** 2))
    last = float(np.mean(speed[-n:] ** 2))
    return last / first if first > 0 else float("nan")


def stillness_share(
    positions: np.ndarray, *, fps: float, skeleton: Skeleton, window: float = 1.0, threshold: float = 0.10
) -> float:
    """Share of ``window``-second windows whose mean body-relative joint speed is below ``threshold`` m/s.

    Windows are consecutive and non-overlapping; a last partial window shorter than half a
    window is ignored. A dance shorter than one window is one window.
    """
    if not window > 0 or not threshold >= 0:
        raise ParameterError(f"stillness needs window > 0 s and threshold >= 0 m/s, got {window}, {threshold}")
    speed = body_speed(positions, fps=fps, skeleton=skeleton).mean(axis=1)  # (T,)
    n = max(1, int(round(window * fps)))
    windows = [speed[s : s + n] for s in range(0, len(speed), n)]
    windows = [w for k, w in enumerate(windows) if k == 0 or 2 * len(w) >= n]
    return float(np.mean([w.mean() < threshold for w in windows]))


def smoothed_energy(positions: np.ndarray, *, fps: float, skeleton: Skeleton, window_frames: int = 5) -> float:
    """Mean body-relative joint speed (m/s) after a ``window_frames`` centred moving average of the positions."""
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=2), skeleton)
    smooth = moving_average(body_relative(p, skeleton), int(window_frames))
    return float(joint_speed(smooth, fps).mean())


def jitter(positions: np.ndarray, *, fps: float, skeleton: Skeleton, window_frames: int = 5) -> dict[str, float]:
    """High-frequency motion of a dance.

    Returns
    -------
    dict: ``speed_residual`` (raw mean body-relative speed minus :func:`smoothed_energy`, m/s)
    and ``jerk`` (mean magnitude of the third finite difference of body-relative positions
    times ``fps**3``, m/s³; 0 for fewer than 4 frames).
    """
    fps = check_fps(fps)
    p = body_relative(to_metres(check_positions(positions, skeleton, min_frames=2), skeleton), skeleton)
    raw = float(joint_speed(p, fps).mean())
    smooth = float(joint_speed(moving_average(p, int(window_frames)), fps).mean())
    jerk = float(np.linalg.norm(np.diff(p, n=3, axis=0), axis=-1).mean() * fps**3) if len(p) >= 4 else 0.0
    return {"speed_residual": raw - smooth, "jerk": jerk}


def windowed_fid(pred_windows: Sequence[np.ndarray], reference: np.ndarray, *, min_samples: int = 2) -> list[float]:
    """FID of window ``k`` of the generated dances against a reference feature set, for every k.

    Parameters
    ----------
    pred_windows : per generated dance, its consecutive window features ``(K_i, F)``
    reference : reference window features ``(M, F)`` (e.g. every window of every real dance)
    min_samples : windows ``k`` present in fewer dances than this get NaN

    Returns
    -------
    list of ``max_i K_i`` floats.
    """
    ref = np.asarray(reference, np.float64)
    K = max((len(w) for w in pred_windows), default=0)
    curve = []
    for k in range(K):
        rows = [np.asarray(w[k], np.float64) for w in pred_windows if len(w) > k]
        curve.append(frechet_distance(np.stack(rows), ref) if len(rows) >= max(2, min_samples) else float("nan"))
    return curve
