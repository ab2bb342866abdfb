"""Shared helpers of the metrics: input validation, axes, units, speeds.

Every metric takes world joint positions ``(T, J, 3)`` in the units of a skeleton
(tang2018: centimetres, y up), the frame rate ``fps`` and the skeleton itself.
Quantities that are compared across datasets are converted to metres and seconds
through ``skeleton.unit_scale`` (metres per unit) and ``fps``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancekit._checks import check_fps as check_fps  # re-exported for the metrics modules
from dancekit.errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

AXES = {"x": 0, "y": 1, "z": 2}


def check_positions(
    positions: np.ndarray,
    skeleton: Skeleton | None = None,
    *,
    min_frames: int = 2,
    name: str = "positions",
) -> np.ndarray:
    """Validate joint positions ``(T, J, 3)`` and return them as float64.

    Raises
    ------
    ParameterError
        If the array is not 3-D with 3 coordinates, has fewer than ``min_frames``
        frames, does not match ``skeleton.num_joints`` or holds NaN / inf.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ParameterError(f"{name} must have shape (T, J, 3), got {p.shape}")
    if skeleton is not None and p.shape[1] != skeleton.num_joints:
        raise ParameterError(
            f"{name} has {p.shape[1]} joints but skeleton {skeleton.name!r} has {skeleton.num_joints}"
        )
    if p.shape[0] < min_frames:
        raise ParameterError(f"{name} has {p.shape[0]} frames; this metric needs at least {min_frames}")
    if not np.isfinite(p).all():
        raise ParameterError(f"{name} contains NaN or inf values")
    return p


def up_index(skeleton: Skeleton) -> int:
    """Index (0, 1, 2) of the skeleton's up axis (``"-y"`` counts as axis 1)."""
    axis = str(skeleton.up_axis).lower()
    if axis.lstrip("-") in AXES:
        return AXES[axis.lstrip("-")]
    raise ParameterError(f"skeleton {skeleton.name!r} has an unknown up_axis {skeleton.up_axis!r}")


def up_sign(skeleton: Skeleton) -> float:
    """+1, or -1 when "up" is the negative direction of the axis (image space, ``"-y"``)."""
    return -1.0 if str(skeleton.up_axis).startswith("-") else 1.0


def heights(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Signed height of every point along the up direction (same units as ``positions``)."""
    return up_sign(skeleton) * positions[..., up_index(skeleton)]


def horizontal_axes(skeleton: Skeleton) -> tuple[int, int]:
    """The two axes other than the up axis, in increasing order."""
    up = up_index(skeleton)
    a, b = (i for i in range(3) if i != up)
    return a, b


def unit_scale(skeleton: Skeleton) -> float:
    """Metres per skeleton unit (tang2018: 0.01)."""
    s = float(skeleton.unit_scale)
    if not np.isfinite(s) or s <= 0:
        raise ParameterError(f"skeleton {skeleton.name!r} has an invalid unit_scale {s!r}")
    return s


def to_metres(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Positions in metres (a copy)."""
    return np.asarray(positions, dtype=np.float64) * unit_scale(skeleton)


def y_up(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Positions rotated so that up is +y (a proper rotation, so cross products keep their sign).

    z up: the cyclic permutation (x, y, z) -> (y, z, x); x up: (z, x, y); -y up: a half turn
    about x (y and z negated).
    """
    up = up_index(skeleton)
    if up == 1:
        return positions if up_sign(skeleton) > 0 else positions * np.array([1.0, -1.0, -1.0])
    if up == 2:  # new y = old z
        return positions[..., [1, 2, 0]]
    return positions[..., [2, 0, 1]]  # up == 0: new y = old x


def joint(skeleton: Skeleton, role: str) -> int:
    """Index of a joint given by name or canonical role, with a clear error when absent."""
    try:
        has = skeleton.has(role)
    except Exception:  # noqa: BLE001 - a skeleton without has(): try index directly
        has = True
    if not has:
        raise ParameterError(f"skeleton {skeleton.name!r} has no joint or role {role!r} (needed by this metric)")
    try:
        return int(skeleton.index(role))
    except (KeyError, ValueError) as exc:
        raise ParameterError(f"skeleton {skeleton.name!r} has no joint or role {role!r}: {exc}") from None


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


def resample_positions(positions: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Linearly resample ``(T, ...)`` frames from ``fps_in`` to ``fps_out`` (same duration)."""
    if abs(fps_in - fps_out) < 1e-9:
        return positions
    T = len(positions)
    n_out = int(np.floor((T - 1) / fps_in * fps_out + 1e-9)) + 1
    x = np.arange(n_out) * (fps_in / fps_out)  # fractional input frame of every output frame
    i0 = np.clip(np.floor(x).astype(int), 0, T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    w = (x - i0).reshape((-1,) + (1,) * (positions.ndim - 1))
    return (1.0 - w) * positions[i0] + w * positions[i1]
