"""Motion representations: how a :class:`~dancekit.motion.Motion` becomes a model's per-frame vector and back.

A small registry (:data:`REPRESENTATIONS`, :func:`get_representation`, :func:`register_representation`) used
alike by the datasets (encoding training dances), the models (their output size) and the pipelines
(decoding a generated vector into a Motion). Each representation is a :class:`Representation` with
``dim(skeleton)``, ``encode(motion)`` and ``decode(x, skeleton, fps)``. Registered:

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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dancekit.errors import ParameterError
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import Skeleton, get_skeleton


def up_and_horizontal_axes(skeleton: Skeleton) -> tuple[int, tuple[int, int]]:
    up = skeleton.up_index
    horizontal = tuple(a for a in range(3) if a != up)
    return up, horizontal  # type: ignore[return-value]


def encode_positions(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """World joint positions ``(T, J, 3)`` → ``positions3d`` features ``(T, 3J + 3)`` float32."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (skeleton.num_joints, 3):
        raise ParameterError(
            f"positions must have shape (T, {skeleton.num_joints}, 3) for skeleton {skeleton.name!r}, "
            f"got {positions.shape}"
        )
    up, (h0, h1) = up_and_horizontal_axes(skeleton)
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
    up, (h0, h1) = up_and_horizontal_axes(skeleton)
    T = len(x)
    root = np.zeros((T, 3))
    root[:, h0] = np.cumsum(x[:, 3 * J])
    root[:, h1] = np.cumsum(x[:, 3 * J + 1])
    root[:, up] = x[:, 3 * J + 2]
    local = x[:, : 3 * J].reshape(T, J, 3)
    return (local + root[:, None, :]).astype(np.float32)


def _encode_positions3d(motion: Motion) -> np.ndarray:
    return encode_positions(motion.to_positions(), motion.skeleton)


def _decode_positions3d(x: np.ndarray, skeleton: Skeleton, fps: float) -> Motion:
    return Motion(skeleton=skeleton, fps=float(fps), positions=decode_positions(x, skeleton))


def _encode_keypoints2d(motion: Motion) -> np.ndarray:
    m2 = motion if motion.skeleton.dims == 2 else motion.project_2d()
    p = m2.to_positions()
    return p.reshape(len(p), -1).astype(np.float32)


def _decode_keypoints2d(x: np.ndarray, skeleton: Skeleton, fps: float) -> Motion:
    x = np.asarray(x, dtype=np.float32)
    if x.ndim != 2 or x.shape[1] != 50:
        raise ParameterError(f"keypoints2d features must have shape (T, 50), got {x.shape}")
    return Motion(skeleton=get_skeleton("body25"), fps=float(fps), positions=x.reshape(len(x), 25, 2))


@dataclass(frozen=True)
class Representation:
    """One way of turning a Motion into per-frame vectors ``(T, P)`` and back.

    ``dim(skeleton)`` is P; ``encode(motion)`` → ``(T, P)`` float32; ``decode(x, skeleton, fps)`` → Motion
    (``skeleton`` is the model's training skeleton; a 2D representation decodes onto its own skeleton).
    """

    name: str
    dim: Callable[[Skeleton], int]
    encode: Callable[[Motion], np.ndarray]
    decode: Callable[[np.ndarray, Skeleton, float], Motion]
    description: str = ""


_REGISTRY: dict[str, Representation] = {}


def register_representation(rep: Representation) -> Representation:
    """Add a representation (a second one of the same name is an error)."""
    if rep.name in _REGISTRY:
        raise ParameterError(f"representation {rep.name!r} is registered already")
    _REGISTRY[rep.name] = rep
    return rep


def get_representation(name: str) -> Representation:
    """The representation called ``name``; :class:`ParameterError` naming the known ones otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParameterError(f"unknown representation {name!r}; choose one of {', '.join(_REGISTRY)}") from None


register_representation(Representation(
    "positions3d", dim=lambda sk: 3 * sk.num_joints + 3, encode=_encode_positions3d, decode=_decode_positions3d,
    description="joints relative to the root (3J) + root horizontal velocity (2) + root height (1)"))
register_representation(Representation(
    "keypoints2d", dim=lambda sk: 50, encode=_encode_keypoints2d, decode=_decode_keypoints2d,
    description="BODY_25 keypoints of the front projection, x and y in pixels"))

#: names of the registered representations (a live view: later registrations appear)
REPRESENTATIONS = _REGISTRY.keys()


def pose_dim(skeleton: Skeleton, representation: str = "positions3d") -> int:
    """Number of columns P of ``representation`` for ``skeleton``."""
    return get_representation(representation).dim(skeleton)


def encode_motion(motion: Motion, representation: str = "positions3d") -> np.ndarray:
    """A :class:`Motion` → per-frame features ``(T, P)`` float32 in ``representation``."""
    return get_representation(representation).encode(motion)


def decode_motion(x: np.ndarray, skeleton: Skeleton, fps: float, representation: str = "positions3d") -> Motion:
    """Per-frame features ``(T, P)`` → a :class:`Motion` at ``fps`` on ``skeleton`` (BODY_25 for 2D)."""
    return get_representation(representation).decode(x, skeleton, fps)


# ------------------------------------------------------------------------------------------------ rot6d
# Dual learning of music and dance (Wu et al., MM 2021, §3.1): root translation + a 6D rotation (the first two
# columns of the local rotation matrix, Zhou et al. 2019) per joint of the skeleton's rig, i.e. the rotations
# the toolkit's inverse kinematics computes (tang2018: 28 rig joints → 3 + 6·28 = 171 columns).

#: columns of ``rot6d`` that hold the root translation (the rest are 6D rotations, never normalised)
ROT6D_TRANSLATION = 3


def encode_rot6d(motion: Motion) -> np.ndarray:
    """A 3D Motion → ``rot6d`` features ``(T, 3 + 6·J_rig)`` float32: ``[root translation (3), 6D of each rig joint]``.

    Rotations come from :meth:`Motion.with_rotations` (inverse kinematics when the motion has positions only).
    """
    import torch

    from dancekit.motion.rotations import matrix_to_rotation_6d

    if motion.skeleton.dims != 3:
        raise ParameterError(f"rot6d needs a 3D motion, {motion.skeleton.name!r} is 2D")
    m = motion.with_rotations()
    assert m.rotations is not None and m.root_translation is not None
    d6 = matrix_to_rotation_6d(torch.from_numpy(np.asarray(m.rotations, np.float64))).numpy()  # (T, Jr, 6)
    T = m.num_frames
    return np.concatenate([np.asarray(m.root_translation, np.float64), d6.reshape(T, -1)], axis=1).astype(np.float32)


def decode_rot6d(x: np.ndarray, skeleton: Skeleton, fps: float, *, root_decode: str = "gram_schmidt") -> Motion:
    """``rot6d`` features ``(T, 3 + 6·J_rig)`` → a Motion with rotations (always proper rotations) and positions by
    forward kinematics.

    Every joint's 6D is decoded by Gram-Schmidt (:func:`~dancekit.motion.rotations.rotation_6d_to_matrix`); with
    ``root_decode="procrustes"`` the root's is decoded to the nearest rotation, both columns weighted by their
    length (:func:`~dancekit.motion.rotations.rotation_6d_to_matrix_procrustes`): for a model whose root heading
    column comes out short and noisy while its up column is long and sure, that keeps the body upright
    (docs/DUAL.md).
    """
    import torch

    from dancekit.motion.rotations import rotation_6d_to_matrix, rotation_6d_to_matrix_procrustes

    if root_decode not in ("gram_schmidt", "procrustes"):
        raise ParameterError(f"root_decode must be 'gram_schmidt' or 'procrustes', got {root_decode!r}")
    x = np.asarray(x, dtype=np.float64)
    rig = skeleton.rig()
    Jr = rig.num_joints
    if x.ndim != 2 or x.shape[1] != ROT6D_TRANSLATION + 6 * Jr:
        raise ParameterError(f"rot6d features must have shape (T, {ROT6D_TRANSLATION + 6 * Jr}) for skeleton "
                             f"{skeleton.name!r}, got {x.shape}")
    T = len(x)
    d6 = torch.from_numpy(x[:, ROT6D_TRANSLATION:].reshape(T, Jr, 6))
    rot = rotation_6d_to_matrix(d6).numpy()
    if root_decode == "procrustes":
        rot[:, rig.root] = rotation_6d_to_matrix_procrustes(d6[:, rig.root]).numpy()
    m = Motion(skeleton=skeleton, fps=float(fps), rotations=rot.astype(np.float32),
               root_translation=x[:, :ROT6D_TRANSLATION].astype(np.float32))
    return m.with_positions()


register_representation(Representation(
    "rot6d", dim=lambda sk: ROT6D_TRANSLATION + 6 * sk.rig().num_joints, encode=encode_rot6d, decode=decode_rot6d,
    description="root translation (3) + 6D rotation (first two matrix columns) of each rig joint (6 J_rig)"))


# ---- rotations_rootdelta (Music2Dance §4.4.1; dancekit.motion.root_delta, imported on use: it needs torch)

def _rootdelta_dim(skeleton: Skeleton) -> int:
    from dancekit.motion.root_delta import rootdelta_layout

    return rootdelta_layout(skeleton).dim


def _encode_rootdelta(motion: Motion) -> np.ndarray:
    from dancekit.motion.root_delta import encode_rootdelta

    return encode_rootdelta(motion).astype(np.float32)


def _decode_rootdelta(x: np.ndarray, skeleton: Skeleton, fps: float) -> Motion:
    from dancekit.motion.root_delta import decode_rootdelta

    return decode_rootdelta(x, skeleton, fps)


register_representation(Representation(
    "rotations_rootdelta", dim=_rootdelta_dim, encode=_encode_rootdelta, decode=_decode_rootdelta,
    description="Music2Dance: root (Δt_x, t_y, Δt_z, Δr_y, r_x, r_z) + 6D rig rotations + end effectors "
                "relative to the root + 2 toe contacts (155 for tang2018)"))
