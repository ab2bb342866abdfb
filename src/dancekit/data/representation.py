"""Pose representations: how a :class:`~dancekit.motion.Motion` becomes a model's per-frame vector.

Two representations, one per Dance Revolution setting:

``positions3d`` (default, P = 3J + 3; 72 for the 23-joint tang2018 skeleton)
    Columns ``[0, 3J)``: every joint relative to the root joint (the skeleton's
    root, e.g. the pelvis), in the skeleton's units, world-aligned axes.
    Columns ``3J, 3J+1``: the root's horizontal velocity (the two axes other than
    ``up_axis``), in units per frame (backward difference; frame 0 has zero velocity).
    Column ``3J+2``: the root's height along ``up_axis``.
    Decoding integrates the velocity from the horizontal origin, so a decoded
    dance starts at (0, height, 0); the body-relative pose is exact.

``keypoints2d`` (P = 50)
    The 25 BODY_25 keypoints of the orthographic front projection
    (:meth:`Motion.project_2d`), x then y for each keypoint, in pixels.
"""

from __future__ import annotations

import numpy as np

from dancekit.errors import ParameterError
from dancekit.motion import Motion, Skeleton, get_skeleton

REPRESENTATIONS = ("positions3d", "keypoints2d")


def _axes(skeleton: Skeleton) -> tuple[int, tuple[int, int]]:
    up = skeleton.up_index
    horizontal = tuple(a for a in range(3) if a != up)
    return up, horizontal  # type: ignore[return-value]


def pose_dim(skeleton: Skeleton, representation: str = "positions3d") -> int:
    """Number of columns P of ``representation`` for ``skeleton``."""
    if representation == "positions3d":
        return 3 * skeleton.num_joints + 3
    if representation == "keypoints2d":
        return 50
    raise ParameterError(f"unknown representation {representation!r}; choose one of {REPRESENTATIONS}")


def encode_positions(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """World joint positions ``(T, J, 3)`` → ``positions3d`` features ``(T, 3J + 3)`` float32."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (skeleton.num_joints, 3):
        raise ParameterError(
            f"positions must have shape (T, {skeleton.num_joints}, 3) for skeleton {skeleton.name!r}, "
            f"got {positions.shape}"
        )
    up, (h0, h1) = _axes(skeleton)
    root = positions[:, skeleton.root]  # (T, 3)
    local = positions - root[:, None, :]  # (T, J, 3)
    vel = np.zeros((len(positions), 2))
    vel[1:, 0] = np.diff(root[:, h0])
    vel[1:, 1] = np.diff(root[:, h1])
    out = np.concatenate([local.reshape(len(positions), -1), vel, root[:, up : up + 1]], axis=1)
    return out.astype(np.float32)


def decode_positions(x: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """``positions3d`` features ``(T, 3J + 3)`` → world joint positions ``(T, J, 3)`` float32."""
    x = np.asarray(x, dtype=np.float64)
    J = skeleton.num_joints
    if x.ndim != 2 or x.shape[1] != 3 * J + 3:
        raise ParameterError(f"features must have shape (T, {3 * J + 3}) for skeleton {skeleton.name!r}, got {x.shape}")
    up, (h0, h1) = _axes(skeleton)
    T = len(x)
    root = np.zeros((T, 3))
    root[:, h0] = np.cumsum(x[:, 3 * J])
    root[:, h1] = np.cumsum(x[:, 3 * J + 1])
    root[:, up] = x[:, 3 * J + 2]
    local = x[:, : 3 * J].reshape(T, J, 3)
    return (local + root[:, None, :]).astype(np.float32)


def encode_motion(motion: Motion, representation: str = "positions3d") -> np.ndarray:
    """A :class:`Motion` → per-frame features ``(T, P)`` float32 in ``representation``."""
    if representation == "positions3d":
        return encode_positions(motion.to_positions(), motion.skeleton)
    if representation == "keypoints2d":
        m2 = motion if motion.skeleton.dims == 2 else motion.project_2d()
        p = m2.to_positions()
        return p.reshape(len(p), -1).astype(np.float32)
    raise ParameterError(f"unknown representation {representation!r}; choose one of {REPRESENTATIONS}")


def decode_motion(x: np.ndarray, skeleton: Skeleton, fps: float, representation: str = "positions3d") -> Motion:
    """Per-frame features ``(T, P)`` → a :class:`Motion` at ``fps`` on ``skeleton`` (BODY_25 for 2D)."""
    if representation == "positions3d":
        return Motion(skeleton=skeleton, fps=float(fps), positions=decode_positions(x, skeleton))
    if representation == "keypoints2d":
        x = np.asarray(x, dtype=np.float32)
        if x.ndim != 2 or x.shape[1] != 50:
            raise ParameterError(f"keypoints2d features must have shape (T, 50), got {x.shape}")
        return Motion(skeleton=get_skeleton("body25"), fps=float(fps), positions=x.reshape(len(x), 25, 2))
    raise ParameterError(f"unknown representation {representation!r}; choose one of {REPRESENTATIONS}")
