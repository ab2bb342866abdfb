"""Retargeting a dance onto the 24-joint SMPL skeleton (no SMPL model files: the public tree and a rest pose).

:func:`retarget_to_smpl` solves SMPL local rotations so that forward kinematics with the documented
rest offsets of :func:`~dancekit.motion.skeleton.smpl_skeleton` (T-pose, facing +z, left = +x, y up,
metres) points every SMPL bone the way the dance's matching bone points. The joint roles of the
source skeleton say which joints match:

========================  =====================================================================
SMPL                      taken from the dance
========================  =====================================================================
hip → knee, knee → ankle  the same bones (``*_hip``, ``*_knee``, ``*_ankle`` roles)
ankle → foot              ankle → ``*_toe`` (rigid with the shin when there is no toe)
shoulder → elbow → wrist  the same bones; the hand stays rigid with the forearm
neck → head               neck → head (the midpoint of ``head_left``/``head_right`` when present)
pelvis orientation        x = left hip − right hip, y = the trunk (hips' midpoint → neck)
spine3 orientation        x = left shoulder − right shoulder, y = the trunk; spine1, spine2 and
                          spine3 share the turn from the pelvis equally (a smooth spine)
collars                   rigid with spine3, so the shoulder line is the dance's
========================  =====================================================================

The neck is the ``neck`` role, or the shoulders' midpoint. Each limb joint gets the smallest
rotation, from its parent's frame, that takes its rest bone onto the dance's direction, so those
directions are reproduced exactly; the body frames are measured against the same frames of the
SMPL rest pose, so a dance in SMPL's rest pose retargets to zero rotations. A z-up dance is
turned to y up.

The body size goes into ``scaling`` as in AIST++: the dance's world positions are ``scaling ×``
the SMPL joints, i.e. the SMPL root sits at ``translation / scaling`` (metres of the SMPL body),
with ``scaling`` = (dance thigh + shin + trunk length) / (the same on the SMPL rest skeleton).

:func:`map_by_role` goes the other way, from any rig with the limb roles onto a model's skeleton (e.g. a humanoid
BVH or an SMPL pkl onto tang2018): the rig's bone directions on the target's bone lengths, at the target's size.
"""

from __future__ import annotations

import numpy as np
import torch

from dancekit.errors import ParameterError
from dancekit.motion.motion import Motion
from dancekit.motion.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from dancekit.motion.skeleton import SMPL_JOINT_NAMES, Skeleton, smpl_skeleton

__all__ = ["SMPL_BONE_SOURCES", "map_by_role", "retarget_to_smpl", "smpl_axis_angle", "smpl_bone_directions",
           "source_bone_directions"]

_REQUIRED = tuple(f"{s}_{p}" for s in ("left", "right") for p in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist"))

#: What the SMPL output follows, as (SMPL from, SMPL to) → (dance from, dance to) points (names of
#: :func:`_landmarks`): the limb bones, the neck, and the hip, shoulder and trunk lines. Tests measure
#: the angle between the two directions; the limbs, the neck and the two lines are exact by construction.
SMPL_BONE_SOURCES: dict[tuple[str, str], tuple[str, str]] = {
    **{(f"{s}_hip", f"{s}_knee"): (f"{s}_hip", f"{s}_knee") for s in ("left", "right")},
    **{(f"{s}_knee", f"{s}_ankle"): (f"{s}_knee", f"{s}_ankle") for s in ("left", "right")},
    **{(f"{s}_ankle", f"{s}_foot"): (f"{s}_ankle", f"{s}_toe") for s in ("left", "right")},
    **{(f"{s}_shoulder", f"{s}_elbow"): (f"{s}_shoulder", f"{s}_elbow") for s in ("left", "right")},
    **{(f"{s}_elbow", f"{s}_wrist"): (f"{s}_elbow", f"{s}_wrist") for s in ("left", "right")},
    ("neck", "head"): ("neck", "head"),
    ("right_hip", "left_hip"): ("right_hip", "left_hip"),
    ("right_shoulder", "left_shoulder"): ("right_shoulder", "left_shoulder"),
}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _min_rot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (T, 3, 3) taking unit vectors a onto unit vectors b (T, 3)."""
    c = np.sum(a * b, axis=-1)
    q = np.concatenate([(1.0 + c)[:, None], np.cross(a, b)], axis=-1)
    opposite = 1.0 + c < 1e-9
    if opposite.any():  # half turn about an axis perpendicular to a
        helper = np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        q[opposite] = np.concatenate([np.zeros((opposite.sum(), 1)), _unit(np.cross(a, helper))[opposite]], -1)
    w, x, y, z = _unit(q).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _frame(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rotations (T, 3, 3) with columns x, y (orthogonalised against x) and x × y."""
    x = _unit(x)
    y = _unit(y - np.sum(y * x, axis=-1, keepdims=True) * x)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _landmarks(motion: Motion) -> dict[str, np.ndarray]:
    """The dance's points used by the retargeting, (T, 3) float64 each, y up, in the skeleton's units."""
    sk = motion.skeleton
    if sk.dims != 3:
        raise ParameterError(f"SMPL retargeting needs a 3D motion, got {sk.name!r}")
    missing = [r for r in _REQUIRED if not sk.has(r)]
    if missing:
        raise ParameterError(f"skeleton {sk.name!r} has no {', '.join(missing)} role(s), needed for SMPL retargeting")
    pos = np.asarray(motion.to_positions(), np.float64)
    if sk.up_axis == "z":
        pos = np.stack([pos[..., 0], pos[..., 2], -pos[..., 1]], axis=-1)
    pt = {r: pos[:, sk.index(r)] for r in _REQUIRED}
    for s in ("left", "right"):
        pt[f"{s}_toe"] = pos[:, sk.index(f"{s}_toe")] if sk.has(f"{s}_toe") else None
    pt["mid_hip"] = 0.5 * (pt["left_hip"] + pt["right_hip"])
    pt["neck"] = pos[:, sk.index("neck")] if sk.has("neck") else 0.5 * (pt["left_shoulder"] + pt["right_shoulder"])
    if sk.has("head_left") and sk.has("head_right"):
        pt["head"] = 0.5 * (pos[:, sk.index("head_left")] + pos[:, sk.index("head_right")])
    else:
        pt["head"] = pos[:, sk.index("head")] if sk.has("head") else None
    return pt


def source_bone_directions(motion: Motion) -> dict[tuple[str, str], np.ndarray]:
    """The dance's unit direction (T, 3) (y up) for every SMPL bone in :data:`SMPL_BONE_SOURCES` it defines."""
    pt = _landmarks(motion)
    return {bone: _unit(pt[b] - pt[a]) for bone, (a, b) in SMPL_BONE_SOURCES.items()
            if pt.get(a) is not None and pt.get(b) is not None}


def smpl_bone_directions(positions: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
    """Unit directions (T, 3) of the SMPL bones of :data:`SMPL_BONE_SOURCES` from SMPL joint positions (T, 24, 3)."""
    i = {n: k for k, n in enumerate(SMPL_JOINT_NAMES)}
    return {(a, b): _unit(positions[:, i[b]] - positions[:, i[a]]) for a, b in SMPL_BONE_SOURCES}


def _body_size(pt: dict[str, np.ndarray]) -> float:
    """A body's size: its leg (hip → knee → ankle, the mean of the two sides) plus its trunk (``mid_hip`` →
    ``neck``), each length the mean over frames of the points ``pt`` (:func:`_landmarks`' names, (T, 3) each)."""
    def length(a: str, b: str) -> float:
        return float(np.mean(np.linalg.norm(pt[b] - pt[a], axis=-1)))

    size = sum(length(f"{s}_hip", f"{s}_knee") + length(f"{s}_knee", f"{s}_ankle") for s in ("left", "right"))
    return 0.5 * size + length("mid_hip", "neck")


def _size_points(skeleton: Skeleton, positions: np.ndarray) -> dict[str, np.ndarray]:
    """The points :func:`_body_size` measures, from positions ``(T, J, 3)`` of a skeleton with the limb roles: the
    hips, knees and ankles, ``mid_hip`` and ``neck`` (the ``neck`` role, or the shoulders' midpoint), as
    :func:`_landmarks` takes them."""
    pt = {r: positions[:, skeleton.index(r)] for r in _REQUIRED}
    pt["mid_hip"] = 0.5 * (pt["left_hip"] + pt["right_hip"])
    pt["neck"] = positions[:, skeleton.index("neck")] if skeleton.has("neck") else \
        0.5 * (pt["left_shoulder"] + pt["right_shoulder"])
    return pt


def retarget_to_smpl(motion: Motion, skeleton: Skeleton | None = None) -> tuple[Motion, float]:
    """The dance on the SMPL skeleton, and its AIST++ ``scaling`` (see the module docstring).

    Parameters
    ----------
    motion : Motion
        A 3D dance whose skeleton has the hip, knee, ankle, shoulder, elbow and wrist roles.
    skeleton : Skeleton or None
        The SMPL rest skeleton to solve for (default :func:`smpl_skeleton`, the documented one).

    Returns
    -------
    smpl_motion : Motion
        On ``skeleton`` (metres, y up): ``rotations`` (T, 24, 3, 3) float64 and ``root_translation``
        (T, 3) = the dance's pelvis / ``scaling``; positions by forward kinematics.
    scaling : float
        Dance units per SMPL metre (dance size / SMPL size).

    Raises
    ------
    ParameterError
        For a 2D motion or a skeleton lacking the limb roles.
    """
    smpl = skeleton if skeleton is not None else smpl_skeleton()
    pt = _landmarks(motion)
    T = motion.num_frames
    idx = {n: k for k, n in enumerate(smpl.joint_names)}
    off = np.asarray(smpl.offsets, np.float64)

    src_size = _body_size(pt)
    rest = np.zeros_like(off)
    for j in smpl.topological_order:
        if smpl.parents[j] >= 0:
            rest[j] = rest[smpl.parents[j]] + off[j]
    leg = sum(np.linalg.norm(off[idx[f"{s}_knee"]]) + np.linalg.norm(off[idx[f"{s}_ankle"]]) for s in ("left", "right"))
    mid_hip_rest = 0.5 * (rest[idx["left_hip"]] + rest[idx["right_hip"]])
    smpl_size = 0.5 * leg + np.linalg.norm(rest[idx["neck"]] - mid_hip_rest)
    scaling = float(src_size / smpl_size)

    targets = source_bone_directions(motion)
    r = {n: rest[None, idx[n]] for n in ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "neck")}
    trunk, trunk_rest = pt["neck"] - pt["mid_hip"], r["neck"] - mid_hip_rest[None]
    # body frames, relative to the same frames of the SMPL rest pose
    pelvis_rot = _frame(pt["left_hip"] - pt["right_hip"], trunk) @ _frame(
        r["left_hip"] - r["right_hip"], trunk_rest)[0].T
    chest_rot = _frame(pt["left_shoulder"] - pt["right_shoulder"], trunk) @ _frame(
        r["left_shoulder"] - r["right_shoulder"], trunk_rest)[0].T
    # spine1..spine3 share the turn from the pelvis to the chest: a third each
    turn = matrix_to_axis_angle(torch.from_numpy(np.swapaxes(pelvis_rot, -1, -2) @ chest_rot)).numpy()
    third = axis_angle_to_matrix(torch.from_numpy(turn / 3.0)).numpy()
    G = np.zeros((T, smpl.num_joints, 3, 3))
    for j in smpl.topological_order:
        name, p = smpl.joint_names[j], smpl.parents[j]
        if name == "pelvis":
            G[:, j] = pelvis_rot
            continue
        if name in ("spine1", "spine2", "spine3"):
            G[:, j] = G[:, p] @ third
            continue
        G[:, j] = G[:, p]  # a leaf, or a joint without a target, keeps its parent's frame
        kids = smpl.children(j)
        if len(kids) == 1 and (name, smpl.joint_names[kids[0]]) in targets:
            d_rest = _unit(np.einsum("tij,j->ti", G[:, p], off[kids[0]]))
            G[:, j] = _min_rot(d_rest, targets[(name, smpl.joint_names[kids[0]])]) @ G[:, p]
    R = G.copy()
    for j in range(smpl.num_joints):
        p = smpl.parents[j]
        if p >= 0:
            R[:, j] = np.swapaxes(G[:, p], -1, -2) @ G[:, j]
    # the SMPL pelvis sits above the hips' midpoint: place it from the solved pelvis frame
    pelvis_world = pt["mid_hip"] - scaling * np.einsum("tij,j->ti", G[:, idx["pelvis"]], mid_hip_rest)
    m = Motion(smpl, motion.fps, rotations=R, root_translation=pelvis_world / scaling)
    return m.with_positions(), scaling


def smpl_axis_angle(rotations: np.ndarray) -> np.ndarray:
    """(T, 24, 3, 3) local rotations → (T, 72) axis-angle, the ``smpl_poses`` layout."""
    aa = matrix_to_axis_angle(torch.from_numpy(np.asarray(rotations, np.float64))).numpy()
    return aa.reshape(aa.shape[0], -1)


#: Roles a dance needs for :func:`map_by_role` (the limbs and the head; the rest is placed from the rest pose).
MAP_REQUIRED = _REQUIRED + ("head",)


def _role_of(skeleton: Skeleton, joint: int) -> str | None:
    name = skeleton.joint_names[joint]
    for role, j in skeleton.roles.items():
        if j == name:
            return role
    return None


def map_by_role(motion: Motion, target: Skeleton) -> Motion:
    """A 3D dance moved onto another skeleton's joints by their roles: the dance's bone directions on the
    target's bone lengths, at the target's size (positions, target units, y up).

    * **Size**: the dance is scaled (about the origin, as AIST++ scales its bodies) by the target's body size over
      the dance's, the size being the leg (hip → knee → ankle) plus the trunk (hips' midpoint → the ``neck`` role
      or the shoulders' midpoint), as :func:`retarget_to_smpl` measures it.
    * **Pelvis**: the target's hips and its root are placed about the dance's hips' midpoint, at their rest
      offsets from the rest hips' midpoint turned as the dance's pelvis is turned from the target's rest pose
      (the hip line, and the trunk to the shoulders' midpoint).
    * **Limbs**: every other joint of ``target`` with a canonical role (``left_knee``, ``head``, ...) the dance
      has too is placed from its nearest placed ancestor (a hip, a knee, ..., or the root) in the direction the
      dance's joints of those roles are apart (from the root: from the placed root to the dance's joint), at the
      target's rest distance.
    * **The rest**: a joint the dance lacks is placed from its parent: on the straight line to its child when the
      two rest bones point the same way (e.g. tang2018's ``*_forearm`` between elbow and wrist, at the rest
      ratio), else by the target's rest offset turned with the body's heading (x = left, y = up, z = forward,
      the convention of the embedded rest skeletons; the second head marker, the hand markers, a heel).

    So a rig's other proportions do not move the dance's feet (the humanoid BVH and the SMPL pkl of a tang2018
    dance read back with its steps, which the composer's tempo follows, :mod:`dancekit.pipelines.compose`), the
    bones between role joints have the target's rest lengths, and a dance on the target's own proportions (a
    rigid trunk) comes back where it was.

    Parameters
    ----------
    motion : a 3D dance whose skeleton has the roles of :data:`MAP_REQUIRED`
    target : a y-up 3D skeleton with the hip, knee, ankle, shoulder, elbow and wrist roles (e.g. ``tang2018``)

    Returns
    -------
    Motion on ``target`` with positions ``(T, J_target, 3)`` float64 at the dance's fps.

    Raises
    ------
    ParameterError
        For a 2D dance or target, or either lacking a required role (the message names them).
    """
    sk = motion.skeleton
    if sk.dims != 3 or target.dims != 3:
        raise ParameterError(f"mapping joints by role needs 3D skeletons, got {sk.name!r} ({sk.dims}D) and "
                             f"{target.name!r} ({target.dims}D)")
    missing = [r for r in MAP_REQUIRED if not sk.has(r)]
    if missing:
        raise ParameterError(f"skeleton {sk.name!r} has no {', '.join(missing)} role(s): cannot map its joints "
                             f"onto {target.name!r}")
    missing = [r for r in _REQUIRED if not target.has(r)]
    if missing:
        raise ParameterError(f"skeleton {target.name!r} has no {', '.join(missing)} role(s): cannot map joints "
                             "onto it")
    pos = np.asarray(motion.to_positions(), np.float64) * (sk.unit_scale / target.unit_scale)
    if sk.up_axis == "z":
        pos = np.stack([pos[..., 0], pos[..., 2], -pos[..., 1]], axis=-1)
    off = np.asarray(target.offsets, np.float64)
    rest = np.zeros_like(off)  # the target's rest pose (J, 3)
    for j in target.topological_order:
        if target.parents[j] >= 0:
            rest[j] = rest[target.parents[j]] + off[j]
    size = _body_size(_size_points(sk, pos))
    if np.isfinite(size) and size > 0:  # the dance at the target's size (about the origin, as AIST++ scales)
        pos = pos * (_body_size(_size_points(target, rest[None])) / size)
    get = {r: pos[:, sk.index(r)] for r in sk.roles}
    left = (get["left_hip"] - get["right_hip"]) + (get["left_shoulder"] - get["right_shoulder"])
    left[:, 1] = 0.0
    left = _unit(left)
    up = np.broadcast_to(np.array([0.0, 1.0, 0.0]), left.shape)
    forward = np.cross(left, up)
    body = np.stack([left, up, forward], axis=-1)  # (T, 3, 3): columns = the rest frame's axes in the world
    at = {r: rest[target.index(r)] for r in ("left_hip", "right_hip", "left_shoulder", "right_shoulder")}
    mid_hip, rest_mid_hip = 0.5 * (get["left_hip"] + get["right_hip"]), 0.5 * (at["left_hip"] + at["right_hip"])
    turn = _frame(get["left_hip"] - get["right_hip"],
                  0.5 * (get["left_shoulder"] + get["right_shoulder"]) - mid_hip) @ _frame(
        (at["left_hip"] - at["right_hip"])[None],
        (0.5 * (at["left_shoulder"] + at["right_shoulder"]) - rest_mid_hip)[None])[0].T  # (T, 3, 3) rest → dance
    out = np.full((motion.num_frames, target.num_joints, 3), np.nan)
    roles = [_role_of(target, j) for j in range(target.num_joints)]
    source = {}  # placed joint → the dance's point it stands for
    for j in target.topological_order:
        role = roles[j]
        if target.parents[j] < 0 or role in ("left_hip", "right_hip"):  # turned with the pelvis
            out[:, j] = mid_hip + np.einsum("tij,j->ti", turn, rest[j] - rest_mid_hip)
            source[j] = get[role] if role in ("left_hip", "right_hip") else out[:, j]
            continue
        if role not in get:
            continue
        a = target.parents[j]
        while a not in source:  # the nearest placed ancestor (the root at the latest)
            a = target.parents[a]
        out[:, j] = out[:, a] + np.linalg.norm(rest[j] - rest[a]) * _unit(get[role] - source[a])
        source[j] = get[role]
    for j in target.topological_order:
        if not np.isnan(out[0, j]).any():
            continue
        p = target.parents[j]
        kids = target.children(j)
        k = kids[0] if len(kids) == 1 else None
        if k is not None and not np.isnan(out[0, k]).any() and float(_unit(off[j]) @ _unit(off[k])) > 0.5:
            a, b = np.linalg.norm(off[j]), np.linalg.norm(off[k])
            out[:, j] = out[:, p] + (a / (a + b)) * (out[:, k] - out[:, p])
        else:
            out[:, j] = out[:, p] + np.einsum("tij,j->ti", body, off[j])
    return Motion(target, motion.fps, positions=out)
