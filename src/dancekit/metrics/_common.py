"""Shared helpers of the metrics: joint lookup with a metric's error message, metres, speeds, smoothing.

Every metric takes world joint positions ``(T, J, 3)`` in the units of a skeleton
(tang2018: centimetres, y up), the frame rate ``fps`` and the skeleton itself.
Quantities that are compared across datasets are converted to metres and seconds
through ``skeleton.unit_scale`` (metres per unit) and ``fps``. The motion analysis the
metrics share with other layers (up axis, heights, heading frame, floor, resampling,
kinematic beats) is :mod:`dancekit.motion.analysis`; input checks are :mod:`dancekit._checks`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancekit._checks import check_fps as check_fps  # re-exported for the metrics modules
from dancekit._checks import check_positions as check_positions
from dancekit.errors import ParameterError
from dancekit.motion.analysis import up_sign

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton


def to_metres(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Positions in metres (a copy), through ``skeleton.unit_scale``."""
    return np.asarray(positions, dtype=np.float64) * skeleton.unit_scale


def y_up(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Positions rotated so that up is +y (a proper rotation, so cross products keep their sign).

    z up: the cyclic permutation (x, y, z) -> (y, z, x); x up: (z, x, y); -y up: a half turn
    about x (y and z negated).
    """
    up = skeleton.up_index
    if up == 1:
        return positions if up_sign(skeleton) > 0 else positions * np.array([1.0, -1.0, -1.0])
    if up == 2:  # new y = old z
        return positions[..., [1, 2, 0]]
    return positions[..., [2, 0, 1]]  # up == 0: new y = old x


def joint(skeleton: Skeleton, role: str) -> int:
    """Index of a joint given by name or canonical role; :class:`ParameterError` naming it when absent."""
    if not skeleton.has(role):
        raise ParameterError(f"skeleton {skeleton.name!r} has no joint or role {role!r} (needed by this metric)")
    return int(skeleton.index(role))


def root_index(skeleton: Skeleton) -> int:
    """The pelvis role if the skeleton has one, else the skeleton's root joint."""
    if skeleton.has("pelvis"):
        return int(skeleton.index("pelvis"))
    return int(skeleton.root)


def body_relative(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Joint positions relative to the pelvis (root) of the same frame, ``(T, J, 3)``."""
    r = root_index(skeleton)
    return positions - positions[:, r : r + 1, :]


def joint_speed(positions: np.ndarray, fps: float) -> np.ndarray:
    """Speed of every joint ``(T, J)`` in units per second (central differences, one-sided at the ends)."""
    v = np.gradient(positions, axis=0) * fps
    return np.linalg.norm(v, axis=-1)


def moving_average(x: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average along axis 0 over ``width`` frames (edge frames repeated)."""
    if width < 1:
        raise ParameterError(f"moving-average width must be >= 1 frame, got {width}")
    if width == 1 or len(x) == 0:
        return np.asarray(x, dtype=np.float64).copy()
    left = (width - 1) // 2
    right = width - 1 - left
    pad = [(left, right)] + [(0, 0)] * (x.ndim - 1)
    xp = np.pad(np.asarray(x, dtype=np.float64), pad, mode="edge")
    c = np.cumsum(xp, axis=0)
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), c], axis=0)
    return (c[width:] - c[:-width]) / width
