"""The Music2Dance motion representation (§4.4.1, Eq. 2–4): ``rotations_rootdelta``.

Per frame, for a 3D skeleton with ``up_axis="y"`` (tang2018, SMPL), in this column order:

``[0, 6)`` the root (Eq. 2): ``Δt_x, t_y, Δt_z, Δr_y, r_x, r_z``
    The root's global rotation is split as intrinsic Euler ``YXZ``: ``R_root = R_Y(r_y) R_X(r_x) R_Z(r_z)``
    (``r_y`` the heading, ``r_x, r_z`` the tilt, radians). ``Δr_y`` is the heading change since the
    previous frame, wrapped to (-π, π]; ``(Δt_x, Δt_z)`` is the root's horizontal displacement since the
    previous frame expressed in the previous frame's heading frame, ``R_Y(r_y[t-1])ᵀ (t[t] - t[t-1])``;
    ``t_y`` is the root height. Frame 0 has zero deltas. So a window looks the same wherever the dancer
    stands and whichever way they face.
``[6, 6 + 6K)`` local joint rotations, 6D (Zhou et al. 2019, :func:`~dancekit.motion.rotations.matrix_to_rotation_6d`)
    The IK rotations of the skeleton's rig (:func:`~dancekit.motion.kinematics.inverse_kinematics`,
    ``Skeleton.rig()``) of every rig joint that has a child, except the root: K = 22 on tang2018
    (leaf rotations move nothing and are dropped). 6D is continuous, unlike Euler angles or axis-angle.
``[.., + 3E)`` end-effector positions (Eq. 3)
    The skeleton's ``end_effectors`` (tang2018: ``head_left``, ``left_toe``, ``right_toe`` and the two hand
    markers ``left_aux`` / ``right_aux`` hanging from the wrists) relative to the root, in the root's
    heading frame ``R_Y(r_y)ᵀ (p - t)``, skeleton units. Positions are those of the forward kinematics of
    the rotations (rest bone lengths), so they agree with the rotations.
``[P - 2, P)`` foot contacts ``c_foot`` (Eq. 4): left toe, right toe, 0/1
    A toe is in contact when it is less than :data:`CONTACT_HEIGHT_CM` above the floor (the running floor of
    :func:`~dancekit.motion.analysis.floor_curve`) **and** moves slower than :data:`CONTACT_SPEED_CM_S`
    (central difference, 3D), measured on the motion's observed positions when it has them (else on the
    forward kinematics). Thresholds are in cm and cm/s, converted to the skeleton's units. On the real
    tang2018 dances (see ``tests/models/test_music2dance.py``) toes are within 5 cm of the floor 80–95 % of the
    time (ballroom feet glide), and their median speed is 20–50 cm/s; the two thresholds flag 40–65 % of
    frames as contacts.

P = 6 + 6K + 3E + 2: 155 for tang2018 (K = 22, E = 5).

Decoding integrates the heading and the horizontal displacement back (from ``origin = (x, z, heading)``,
default zeros: a decoded dance starts at the horizontal origin facing +z) and runs forward kinematics of
the rotations; end effectors and contacts are not needed to decode (a model predicts them to keep its
rotations honest, and the Foot Constraint Model reads them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from dancekit.errors import ParameterError
from dancekit.motion.kinematics import inverse_kinematics, rig_forward_kinematics
from dancekit.motion.motion import Motion
from dancekit.motion.rotations import (
    euler_angles_to_matrix,
    matrix_to_euler_angles,
    matrix_to_rotation_6d,
    rotation_6d_to_matrix,
)
from dancekit.motion.skeleton import Skeleton

__all__ = [
    "CONTACT_HEIGHT_CM",
    "CONTACT_SPEED_CM_S",
    "RootDeltaDecoder",
    "RootDeltaLayout",
    "decode_rootdelta",
    "encode_rootdelta",
    "rootdelta_positions",
    "foot_contacts",
    "lower_body_cols",
    "rootdelta_layout",
]

#: a toe closer to the floor than this (cm) ...
CONTACT_HEIGHT_CM = 5.0
#: ... and slower than this (cm/s) is in contact with the floor
CONTACT_SPEED_CM_S = 30.0

ROOT_COLUMNS = ("dt_x", "t_y", "dt_z", "dr_y", "r_x", "r_z")


@dataclass(frozen=True)
class RootDeltaLayout:
    """Where everything sits in a ``rotations_rootdelta`` vector of one skeleton.

    ``rot_joints``: rig joint indices of the 6D blocks (in column order); ``end_effectors``: skeleton joint
    indices of the 3D blocks; ``contact_joints``: the left and right toe. ``*_cols`` are column index tuples.
    """

    rot_joints: tuple[int, ...]
    end_effectors: tuple[int, ...]
    contact_joints: tuple[int, int]
    dim: int

    @property
    def root_cols(self) -> tuple[int, ...]:
        return tuple(range(6))

    def rot_cols(self, joint: int) -> tuple[int, ...]:
        """The six columns of rig joint ``joint``."""
        k = self.rot_joints.index(joint)
        return tuple(range(6 + 6 * k, 12 + 6 * k))

    @property
    def end_effector_cols(self) -> tuple[int, ...]:
        start = 6 + 6 * len(self.rot_joints)
        return tuple(range(start, start + 3 * len(self.end_effectors)))

    def end_effector_col(self, joint: int) -> tuple[int, ...]:
        """The three columns of end effector ``joint`` (a skeleton joint index)."""
        k = self.end_effectors.index(joint)
        start = 6 + 6 * len(self.rot_joints) + 3 * k
        return tuple(range(start, start + 3))

    @property
    def contact_cols(self) -> tuple[int, int]:
        return (self.dim - 2, self.dim - 1)

    @property
    def toe_cols(self) -> tuple[int, ...]:
        """The end-effector columns of the two toes (the contact joints)."""
        return tuple(c for j in self.contact_joints if j in self.end_effectors for c in self.end_effector_col(j))


def lower_body_cols(skeleton: Skeleton) -> tuple[int, ...]:
    """Columns of the lower body's motion (§4.5): the root's six and the 6D rotations of every rig joint in
    the legs (the hips and everything below them, and the branch joints the hips hang from)."""
    lay = rootdelta_layout(skeleton)
    rig = skeleton.rig()
    hips = {skeleton.index("left_hip"), skeleton.index("right_hip")}

    def in_leg(j: int) -> bool:
        kids = rig.children(j)
        if len(kids) == 1 and kids[0] in hips:  # the branch joint above a hip
            return True
        while j >= 0:
            if j in hips:
                return True
            j = rig.parents[j]
        return False

    cols = list(lay.root_cols)
    for j in lay.rot_joints:
        if in_leg(j):
            cols.extend(lay.rot_cols(j))
    return tuple(cols)


def _check_skeleton(skeleton: Skeleton) -> None:
    if skeleton.dims != 3 or skeleton.up_axis != "y":
        raise ParameterError(f"rotations_rootdelta needs a 3D y-up skeleton, {skeleton.name!r} has up_axis "
                             f"{skeleton.up_axis!r} and {skeleton.dims} dimensions")
    for role in ("left_toe", "right_toe"):
        if not skeleton.has(role):
            raise ParameterError(f"rotations_rootdelta needs a {role!r} joint for the foot contacts; "
                                 f"skeleton {skeleton.name!r} has none")


def rootdelta_layout(skeleton: Skeleton) -> RootDeltaLayout:
    """The column layout of ``rotations_rootdelta`` for ``skeleton`` (see the module docstring)."""
    _check_skeleton(skeleton)
    rig = skeleton.rig()
    rot = tuple(j for j in range(rig.num_joints) if j != rig.root and rig.children(j))
    ends = tuple(skeleton.index(n) for n in skeleton.end_effectors) or tuple(
        j for j in range(skeleton.num_joints) if not skeleton.children(j))
    contacts = (skeleton.index("left_toe"), skeleton.index("right_toe"))
    return RootDeltaLayout(rot, ends, contacts, 6 + 6 * len(rot) + 3 * len(ends) + 2)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _yaw_matrix(a: np.ndarray) -> np.ndarray:
    """``R_Y(a)`` ``(..., 3, 3)`` for angles ``a`` ``(...)``."""
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(a.shape + (3, 3))


def foot_contacts(positions: np.ndarray, skeleton: Skeleton, *, fps: float,
                  height_cm: float = CONTACT_HEIGHT_CM, speed_cm_s: float = CONTACT_SPEED_CM_S) -> np.ndarray:
    """Left/right toe contact flags ``(T, 2)`` float (0/1) from world positions ``(T, J, 3)``.

    Contact: the toe is less than ``height_cm`` above the running floor
    (:func:`~dancekit.motion.analysis.floor_curve`) and its speed (central difference) is below
    ``speed_cm_s``; both thresholds are converted to the skeleton's units.
    """
    from dancekit.motion.analysis import floor_curve

    _check_skeleton(skeleton)
    p = np.asarray(positions, np.float64)
    per_cm = 0.01 / skeleton.unit_scale  # skeleton units per cm
    floor = floor_curve(p, skeleton, fps=fps) if len(p) > 1 else p[:, :, 1].min(axis=1)
    out = np.zeros((len(p), 2))
    for k, role in enumerate(("left_toe", "right_toe")):
        toe = p[:, skeleton.index(role)]  # (T, 3)
        speed = np.linalg.norm(np.gradient(toe, axis=0), axis=-1) * fps if len(p) > 1 else np.zeros(len(p))
        out[:, k] = (toe[:, 1] - floor < height_cm * per_cm) & (speed < speed_cm_s * per_cm)
    return out


def encode_rootdelta(motion: Motion) -> np.ndarray:
    """A 3D :class:`Motion` → ``rotations_rootdelta`` features ``(T, P)`` float64.

    Uses the motion's rig rotations when it has them, else the IK rotations of its positions.
    """
    sk = motion.skeleton
    lay = rootdelta_layout(sk)
    if motion.rotations is not None:
        R = np.asarray(motion.rotations, np.float64)
        tr = np.asarray(motion.root_translation, np.float64)
        if R.shape[1] != sk.rig().num_joints:
            from dancekit.motion.kinematics import rig_rotations

            R = rig_rotations(R, sk)
    else:
        R, tr = inverse_kinematics(np.asarray(motion.positions, np.float64), sk)  # (T, Jr, 3, 3), (T, 3)
    T = len(R)
    Rt = torch.from_numpy(np.ascontiguousarray(R))
    pos = rig_forward_kinematics(Rt, torch.from_numpy(np.ascontiguousarray(tr)), sk).numpy()  # (T, J, 3)
    euler = matrix_to_euler_angles(Rt[:, sk.root], "YXZ").numpy()  # (T, 3): heading, tilt x, tilt z
    heading = euler[:, 0]
    root = np.zeros((T, 6))
    yaw = _yaw_matrix(heading)  # (T, 3, 3)
    if T > 1:
        step = tr[1:] - tr[:-1]  # (T-1, 3) world
        local = np.einsum("tji,tj->ti", yaw[:-1], step)  # R_Y(prev)ᵀ step
        root[1:, 0], root[1:, 2] = local[:, 0], local[:, 2]
        root[1:, 3] = _wrap(np.diff(heading))
    root[:, 1] = tr[:, 1]
    root[:, 4], root[:, 5] = euler[:, 1], euler[:, 2]
    rot6 = matrix_to_rotation_6d(Rt[:, list(lay.rot_joints)]).numpy().reshape(T, -1)  # (T, 6K)
    rel = pos[:, list(lay.end_effectors)] - tr[:, None, :]  # (T, E, 3)
    ends = np.einsum("tji,tej->tei", yaw, rel).reshape(T, -1)  # heading frame
    # contacts from the observed positions when the motion has them (the markers touch the floor; rest
    # bone lengths can move a toe a few cm), else from the forward kinematics
    observed = motion.positions if motion.positions is not None else pos
    contacts = foot_contacts(observed, sk, fps=motion.fps)
    return np.concatenate([root, rot6, ends, contacts], axis=1)


def _root_path(x: np.ndarray, lay: RootDeltaLayout, skeleton: Skeleton, origin: tuple[float, float, float]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The checked features ``x (T, P)`` float64 and the root they integrate to from ``origin = (x, z, heading)``:
    ``(x, heading (T,), R_Y(heading) (T, 3, 3), root translation (T, 3))`` (the decoders' shared first step)."""
    x = np.asarray(x, np.float64)
    if x.ndim != 2 or x.shape[1] != lay.dim:
        raise ParameterError(f"rotations_rootdelta features must have shape (T, {lay.dim}) for skeleton "
                             f"{skeleton.name!r}, got {x.shape}")
    T = len(x)
    heading = float(origin[2]) + np.cumsum(np.concatenate([[0.0], x[1:, 3]]))  # (T,)
    yaw = _yaw_matrix(heading)
    step = np.zeros((T, 3))
    step[:, 0], step[:, 2] = x[:, 0], x[:, 2]
    world = np.einsum("tij,tj->ti", yaw[:-1], step[1:]) if T > 1 else np.zeros((0, 3))  # R_Y(prev) local
    tr = np.zeros((T, 3))
    tr[:, 0] = float(origin[0]) + np.concatenate([[0.0], np.cumsum(world[:, 0])])
    tr[:, 2] = float(origin[1]) + np.concatenate([[0.0], np.cumsum(world[:, 2])])
    tr[:, 1] = x[:, 1]
    return x, heading, yaw, tr


def decode_rootdelta(x: np.ndarray, skeleton: Skeleton, fps: float, *,
                     origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Motion:
    """``rotations_rootdelta`` features ``(T, P)`` → a :class:`Motion` (rig rotations, root, FK positions).

    ``origin = (x, z, heading)``: where the root stands and which way it faces at frame 0 (zeros: the
    horizontal origin, facing +z). The 6D blocks need not be orthonormal (Gram-Schmidt).
    """
    lay = rootdelta_layout(skeleton)
    x, heading, yaw, tr = _root_path(x, lay, skeleton, origin)
    T = len(x)
    rig = skeleton.rig()
    R = np.broadcast_to(np.eye(3), (T, rig.num_joints, 3, 3)).copy()
    R[:, skeleton.root] = euler_angles_to_matrix(torch.from_numpy(np.stack([heading, x[:, 4], x[:, 5]], -1)),
                                                 "YXZ").numpy()
    K = len(lay.rot_joints)
    R[:, list(lay.rot_joints)] = rotation_6d_to_matrix(torch.from_numpy(x[:, 6 : 6 + 6 * K].reshape(T, K, 6))).numpy()
    pos = rig_forward_kinematics(torch.from_numpy(R), torch.from_numpy(tr), skeleton).numpy()
    return Motion(skeleton=skeleton, fps=float(fps), positions=pos, rotations=R, root_translation=tr)


class RootDeltaDecoder:
    """The positions and root translation of :func:`decode_rootdelta` in NumPy alone, for one skeleton:
    ``decoder(x, origin=…)`` → ``(positions (T, J, 3), root_translation (T, 3))`` float64, skeleton units, for
    ``rotations_rootdelta`` features ``x (T, P)``.

    The same maths (the 6D blocks by Gram-Schmidt with the same fallbacks, the root as intrinsic ``YXZ``, the rig's
    forward kinematics) with the layout and the rig prepared once and the joints of one tree depth at a time: a
    row or two costs tens of microseconds rather than the milliseconds of torch's per-joint calls (the live
    stepper decodes one or two rows per frame). Equal to :func:`decode_rootdelta` to float64 rounding (a test).
    """

    def __init__(self, skeleton: Skeleton):
        self.skeleton = skeleton
        self.layout = rootdelta_layout(skeleton)
        rig = skeleton.rig()
        self.num_rig_joints = rig.num_joints
        self.offsets = np.asarray(rig.offsets, np.float64)
        parents = [int(p) for p in rig.parents]
        depth = [_depth(parents, j) for j in range(len(parents))]
        #: the joints below the root, one depth at a time, with their parents
        self.levels = [([j for j in range(len(parents)) if depth[j] == d], [parents[j] for j in range(len(parents))
                                                                             if depth[j] == d])
                       for d in range(1, max(depth) + 1)]
        self.rot_joints = list(self.layout.rot_joints)

    def __call__(self, x: np.ndarray, *, origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
                 ) -> tuple[np.ndarray, np.ndarray]:
        sk = self.skeleton
        x, _, yaw, tr = _root_path(x, self.layout, sk, origin)
        T = len(x)
        R = np.broadcast_to(np.eye(3), (T, self.num_rig_joints, 3, 3)).copy()
        root = sk.root
        R[:, root] = yaw @ _axis_x(x[:, 4]) @ _axis_z(x[:, 5])  # R_Y(r_y) R_X(r_x) R_Z(r_z)
        K = len(self.rot_joints)
        R[:, self.rot_joints] = _rotation_6d_to_matrix(x[:, 6 : 6 + 6 * K].reshape(T, K, 6))
        glob = np.empty_like(R)
        pos = np.empty((T, self.num_rig_joints, 3))
        glob[:, root], pos[:, root] = R[:, root], tr
        for joints, parents in self.levels:
            gp = glob[:, parents]  # (T, k, 3, 3)
            glob[:, joints] = gp @ R[:, joints]
            pos[:, joints] = pos[:, parents] + (gp @ self.offsets[joints, :, None])[..., 0]
        return pos[:, : sk.num_joints], tr


def _axis_x(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([o, z, z, z, c, -s, z, s, c], axis=-1).reshape(a.shape + (3, 3))


def _axis_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([c, -s, z, s, c, z, z, z, o], axis=-1).reshape(a.shape + (3, 3))


def _rotation_6d_to_matrix(d6: np.ndarray) -> np.ndarray:
    """:func:`~dancekit.motion.rotations.rotation_6d_to_matrix` on a float64 array ``(..., 6)`` → ``(..., 3, 3)``."""
    eps = 1e-12
    a1, a2 = d6[..., :3], d6[..., 3:]
    n1 = np.sqrt((a1 * a1).sum(-1, keepdims=True))
    ex = np.zeros_like(a1)
    ex[..., 0] = 1.0
    b1 = np.where(n1 > eps, a1 / np.maximum(n1, eps), ex)
    a2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    n2 = np.sqrt((a2 * a2).sum(-1, keepdims=True))
    if not (n1 > eps).all() or not (n2 > eps).all():  # a degenerate block: any unit vector perpendicular to b1
        alt = np.where(np.abs(b1[..., :1]) < 0.9, ex, np.roll(ex, 1, axis=-1))
        alt = alt - (b1 * alt).sum(-1, keepdims=True) * b1
        alt = alt / np.linalg.norm(alt, axis=-1, keepdims=True)
        b2 = np.where(n2 > eps, a2 / np.maximum(n2, eps), alt)
    else:
        b2 = a2 / n2
    out = np.empty(d6.shape[:-1] + (3, 3))
    out[..., 0], out[..., 1] = b1, b2
    x1, y1, z1 = b1[..., 0], b1[..., 1], b1[..., 2]
    x2, y2, z2 = b2[..., 0], b2[..., 1], b2[..., 2]
    out[..., 0, 2] = y1 * z2 - z1 * y2  # b1 x b2
    out[..., 1, 2] = z1 * x2 - x1 * z2
    out[..., 2, 2] = x1 * y2 - y1 * x2
    return out


def rootdelta_positions(x: torch.Tensor, skeleton: Skeleton, *, joints: tuple[int, ...] | None = None) -> torch.Tensor:
    """Differentiable :func:`decode_rootdelta` in torch: joint positions ``(..., T, len(joints), 3)`` of
    (denormalised) ``rotations_rootdelta`` features ``x (..., T, P)``, in skeleton units.

    Each sequence starts at the horizontal origin facing +z (``origin = (0, 0, 0)``); the positions equal
    :func:`decode_rootdelta`'s. ``joints``: skeleton joint indices (default all J). Only the rotations on the
    paths from the root to ``joints`` matter (the toes: the root's six columns and the legs'
    :func:`lower_body_cols`).
    """
    lay = rootdelta_layout(skeleton)
    if x.shape[-1] != lay.dim or x.dim() < 2:
        raise ParameterError(f"rotations_rootdelta features must have shape (..., T, {lay.dim}), got {tuple(x.shape)}")
    zero = torch.zeros_like(x[..., :1, 0])
    heading = torch.cumsum(torch.cat([zero, x[..., 1:, 3]], -1), -1)  # (..., T)
    c, s = torch.cos(heading[..., :-1]), torch.sin(heading[..., :-1])  # R_Y(previous heading)
    dx, dz = x[..., 1:, 0], x[..., 1:, 2]
    wx = torch.cumsum(torch.cat([zero, c * dx + s * dz], -1), -1)
    wz = torch.cumsum(torch.cat([zero, -s * dx + c * dz], -1), -1)
    tr = torch.stack([wx, x[..., 1], wz], -1)  # (..., T, 3)
    rig = skeleton.rig()
    want = list(range(skeleton.num_joints)) if joints is None else [int(j) for j in joints]
    chain: list[int] = []  # the rig joints from the root to every wanted joint, parents first
    for j in want:
        path = []
        while j >= 0 and j not in chain and j not in path:
            path.append(j)
            j = rig.parents[j]
        chain.extend(reversed(path))
    chain.sort(key=lambda j: _depth(rig.parents, j))
    rot = {j: k for k, j in enumerate(lay.rot_joints)}
    need = [j for j in chain if j in rot]
    mats = dict(zip(need, rotation_6d_to_matrix(torch.stack([x[..., 6 + 6 * rot[j]: 12 + 6 * rot[j]] for j in need], -2))
                    .unbind(-3), strict=True)) if need else {}
    offsets = torch.tensor(np.array(rig.offsets), dtype=x.dtype, device=x.device)
    glob: dict[int, torch.Tensor] = {}
    pos: dict[int, torch.Tensor] = {}
    for j in chain:
        p = rig.parents[j]
        if p < 0:
            glob[j] = euler_angles_to_matrix(torch.stack([heading, x[..., 4], x[..., 5]], -1), "YXZ")
            pos[j] = tr
            continue
        pos[j] = pos[p] + (glob[p] @ offsets[j, :, None])[..., 0]
        glob[j] = glob[p] @ mats[j] if j in mats else glob[p]
    return torch.stack([pos[j] for j in want], -2)


def _depth(parents, j: int) -> int:
    d = 0
    while parents[j] >= 0:
        j, d = parents[j], d + 1
    return d
