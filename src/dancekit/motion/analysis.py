"""Motion analysis that several layers need (data preparation, models, pipelines, metrics, evaluation).

NumPy in, NumPy out. Arrays are world joint positions ``(T, J, 3)`` in the skeleton's units at ``fps``
frames per second; the skeleton gives the up axis (:attr:`Skeleton.up_index`, :func:`up_sign`) and the
metric scale (:attr:`Skeleton.unit_scale`, metres per unit).

=============================  ====================================================================
function                       what
=============================  ====================================================================
:func:`up_sign`                +1, or -1 when up is the negative direction of the up axis ("-y")
:func:`horizontal_axes`        the two axes other than the up axis
:func:`heights`                signed height of every point along the up direction
:func:`rest_pose`              joint positions of the skeleton's rest pose (its offsets chained)
:func:`heading_axes`           the body's heading frame per frame (left, up, forward)
:func:`heading_rotation`       the same as world → body rotation matrices ``(T, 3, 3)``
:func:`floor_curve`            the floor under the dancer at every frame
:func:`resample_indices`       source frames and weights of a linear resampling (one rounding rule)
:func:`resample_positions`     ``(T, ...)`` frames linearly resampled to another frame rate
:func:`mean_joint_speed`       mean joint speed per frame, Gaussian-smoothed
:func:`kinematic_beats`        local minima of the mean joint speed, in seconds
=============================  ====================================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dancekit._checks import check_fps, check_positions
from dancekit.errors import ParameterError
from dancekit.motion.skeleton import Skeleton

__all__ = [
    "DEFAULT_BEAT_SMOOTH",
    "floor_curve",
    "heading_axes",
    "heading_rotation",
    "heights",
    "horizontal_axes",
    "kinematic_beats",
    "mean_joint_speed",
    "resample_indices",
    "resample_positions",
    "rest_pose",
    "up_sign",
]

#: Standard deviation (s) of the speed smoothing of :func:`kinematic_beats`: the 5 frames at 60 fps of
#: the AIST++ / Bailando code.
DEFAULT_BEAT_SMOOTH = 5.0 / 60.0


# ---------------------------------------------------------------------------------------------- axes


def up_sign(skeleton: Skeleton) -> float:
    """+1.0, or -1.0 when "up" is the negative direction of the up axis (image space, ``"-y"``)."""
    return -1.0 if str(skeleton.up_axis).startswith("-") else 1.0


def horizontal_axes(skeleton: Skeleton) -> tuple[int, int]:
    """The two axes other than the up axis (:attr:`Skeleton.up_index`), in increasing order."""
    up = skeleton.up_index
    a, b = (i for i in range(3) if i != up)
    return a, b


def heights(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Signed height of every point ``(...,)`` along the up direction, in the units of ``positions``."""
    return up_sign(skeleton) * np.asarray(positions)[..., skeleton.up_index]


def rest_pose(skeleton: Skeleton) -> np.ndarray:
    """Joint positions ``(J, 3)`` float64 of the rest pose: every offset added to its parent's position
    (the root at the origin), i.e. forward kinematics of identity rotations, in skeleton units."""
    offsets = np.asarray(skeleton.offsets, dtype=np.float64)
    rest = np.zeros_like(offsets)
    for j in skeleton.topological_order:
        parent = skeleton.parents[j]
        rest[j] = offsets[j] if parent < 0 else rest[parent] + offsets[j]
    return rest


# ---------------------------------------------------------------------------------------------- heading


def heading_axes(positions: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body's heading frame at every frame: ``(left, up, forward)``, three ``(T, 3)`` unit vectors.

    ``left`` is the horizontal part of the hip line plus the shoulder line (left minus right joints;
    roles ``left_hip``, ``right_hip``, ``left_shoulder``, ``right_shoulder``), ``up`` the skeleton's up
    direction, ``forward = left × up``. A frame whose hips and shoulders give no horizontal direction
    takes the first horizontal axis as ``left``.
    """
    p = np.asarray(positions, dtype=np.float64)
    up = np.zeros(3)
    up[skeleton.up_index] = up_sign(skeleton)
    index = skeleton.index
    lateral = (p[:, index("left_hip")] - p[:, index("right_hip")]) + (
        p[:, index("left_shoulder")] - p[:, index("right_shoulder")]
    )
    lateral = lateral - np.outer(lateral @ up, up)
    norm = np.linalg.norm(lateral, axis=-1, keepdims=True)
    fallback = np.zeros(3)
    fallback[horizontal_axes(skeleton)[0]] = 1.0
    lateral = np.where(norm > 1e-9, lateral / np.maximum(norm, 1e-12), fallback)
    ups = np.broadcast_to(up, lateral.shape)
    forward = np.cross(lateral, ups)
    return lateral, ups, forward


def heading_rotation(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """World → body rotations ``(T, 3, 3)``: the rows are :func:`heading_axes` (left, up, forward), so
    ``R[t] @ v`` is a world vector ``v`` in the body's heading frame at frame ``t``."""
    return np.stack(heading_axes(positions, skeleton), axis=1)


# ---------------------------------------------------------------------------------------------- floor


def floor_curve(
    positions: np.ndarray,
    skeleton: Skeleton,
    *,
    fps: float,
    window_s: float = 3.0,
    percentile: float = 5.0,
    smooth_s: float = 1.0,
    feet: Sequence[str] | None = None,
) -> np.ndarray:
    """Floor coordinate along the up axis at every frame ``(T,)``, in the units of ``positions``.

    The ``percentile`` of the lowest foot joint's height in a ``window_s`` window around each frame,
    smoothed with a ``smooth_s``-second moving average (0: not smoothed). A dancer's feet touch the floor
    most of the time, so jumps do not lift the curve; a drifting capture floor is followed.
    ``percentile=0, smooth_s=0`` is the running minimum of the lowest foot.

    ``feet``: joint names or roles (default ``skeleton.feet``; every joint when the skeleton names none).
    """
    from dancekit.motion.filters import percentile_filter1d, uniform_filter1d

    names = list(feet) if feet is not None else list(skeleton.feet)
    idx = [skeleton.index(f) for f in names] or list(range(skeleton.num_joints))
    sign = up_sign(skeleton)
    lowest = (sign * np.asarray(positions, np.float64)[:, idx, skeleton.up_index]).min(axis=1)
    size = max(1, int(round(window_s * fps)))
    floor = percentile_filter1d(lowest, percentile, size)
    if smooth_s:
        floor = uniform_filter1d(floor, max(1, int(round(smooth_s * fps))))
    return sign * floor


# ---------------------------------------------------------------------------------------------- timing


def resample_indices(n_frames: int, *, orig_fps: float, target_fps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Source frames and weights of a linear resampling from ``orig_fps`` to ``target_fps``.

    New frame ``k`` is at ``k / target_fps`` seconds, for every such time up to the last original frame
    (no extrapolation): ``floor((T - 1) * target_fps / orig_fps) + 1`` frames. It lies between source
    frames ``i0[k]`` and ``i1[k]`` at weight ``w[k]`` of ``i1`` (a time within 1e-9 frames of a source
    frame takes that frame exactly).

    Returns
    -------
    ``(i0, i1, w)``: int arrays ``(n,)`` and a float64 array ``(n,)`` in [0, 1].
    """
    orig_fps = check_fps(orig_fps, name="orig_fps")
    target_fps = check_fps(target_fps, name="target_fps")
    T = int(n_frames)
    if T < 1:
        raise ParameterError(f"cannot resample {T} frames")
    n = int(math.floor((T - 1) * target_fps / orig_fps + 1e-9)) + 1
    src = np.arange(n) * (orig_fps / target_fps)  # fractional source frame
    i0 = np.clip(np.floor(src + 1e-9).astype(int), 0, T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    w = np.clip(src - i0, 0.0, 1.0)
    return i0, i1, w


def resample_positions(x: np.ndarray, *, orig_fps: float, target_fps: float) -> np.ndarray:
    """Frames ``(T, ...)`` linearly interpolated to ``target_fps`` (see :func:`resample_indices`): a new
    array in the dtype of ``x`` (float32 frames are interpolated in float32)."""
    x = np.asarray(x)
    i0, i1, w = resample_indices(len(x), orig_fps=orig_fps, target_fps=target_fps)
    ww = w.reshape((-1,) + (1,) * (x.ndim - 1)).astype(x.dtype)
    return x[i0] * (1 - ww) + x[i1] * ww


# ---------------------------------------------------------------------------------------------- beats


def mean_joint_speed(
    positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None, smooth: float | None = DEFAULT_BEAT_SMOOTH
) -> np.ndarray:
    """Mean joint speed per frame ``(T,)`` in skeleton units per second, Gaussian-smoothed.

    Joint velocities by central differences of the world positions (so the root's travel counts, as in
    AIST++), speed averaged over joints; ``smooth`` is the Gaussian's standard deviation in seconds
    (None or 0: no smoothing). ``skeleton`` (optional) only checks the joint count.
    """
    from dancekit.motion.filters import gaussian_filter1d

    fps = check_fps(fps)
    p = check_positions(positions, skeleton, min_frames=3)
    speed = np.linalg.norm(np.gradient(p, axis=0), axis=-1).mean(axis=1) * fps
    if smooth:
        if smooth < 0:
            raise ParameterError(f"smooth must be >= 0 seconds, got {smooth}")
        speed = gaussian_filter1d(speed, smooth * fps)
    return speed


def kinematic_beats(
    positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None, smooth: float | None = DEFAULT_BEAT_SMOOTH
) -> np.ndarray:
    """Kinematic beats of a dance, in seconds: the strict local minima of :func:`mean_joint_speed`.

    Parameters
    ----------
    positions : (T, J, 3) world joint positions (any units), ``T >= 3``
    fps : frames per second
    skeleton : optional, only checks the joint count
    smooth : standard deviation of the Gaussian smoothing, seconds

    Returns
    -------
    (B,) float64 beat times in seconds, increasing (frame ``t`` is at ``t / fps``).
    """
    speed = mean_joint_speed(positions, fps=fps, skeleton=skeleton, smooth=smooth)
    # strict local minima, ``scipy.signal.argrelextrema(speed, np.less)`` (not imported: scipy.signal pulls in
    # scipy.stats, a second of a fresh process's start-up)
    idx = np.flatnonzero((speed[1:-1] < speed[:-2]) & (speed[1:-1] < speed[2:])) + 1
    return idx.astype(np.float64) / float(fps)


def leg_chains(skeleton: Skeleton) -> list[tuple[int, int, int, list[int]]]:
    """Per leg ``(hip, knee, ankle, [foot joints below the ankle, parents first])`` joint indices.

    Legs are found by role names (``left_hip`` / ``left_knee`` / ``left_ankle``, the same on the right);
    the foot joints are the ankle's descendants. A skeleton without them has no legs (empty list).
    """
    out = []
    for side in ("left", "right"):
        names = [f"{side}_{j}" for j in ("hip", "knee", "ankle")]
        if not all(skeleton.has(n) for n in names):
            continue
        hip, knee, ankle = (skeleton.index(n) for n in names)
        parents = list(skeleton.parents)
        if parents[knee] != hip or parents[ankle] != knee:
            continue
        below, frontier = [], [ankle]
        while frontier:
            kids = [j for j, q in enumerate(parents) if q in frontier]
            below += kids
            frontier = kids
        out.append((hip, knee, ankle, below))
    return out
