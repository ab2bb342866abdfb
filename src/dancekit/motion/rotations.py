"""Rotation conversions: pure torch functions over arbitrary leading dimensions.

Conventions (one note for the whole module):

- Right-handed frames; rotation matrices act on **column vectors**
  (``v' = R @ v``) and compose right to left (``R = R2 @ R1`` applies R1 first).
- **Axis-angle** ``(..., 3)``: unit axis times angle in radians (angle in [0, π]).
- **Quaternions** ``(..., 4)`` are **w-first** ``(w, x, y, z)``, unit norm.
  Functions that return quaternions return the one with ``w >= 0``.
- **6D** ``(..., 6)``: the first two **columns** of the matrix, concatenated
  ``(R[:, 0], R[:, 1])`` (Zhou et al., "On the Continuity of Rotation
  Representations in Neural Networks", CVPR 2019). Decoding uses Gram-Schmidt,
  so any input with two non-parallel 3-vectors gives a proper rotation;
  :func:`rotation_6d_to_matrix_procrustes` decodes to the nearest rotation instead,
  both columns weighted by their length (see there why that matters).
- **Euler angles** ``(..., 3)`` in radians with an ``order`` string of three
  axes, e.g. ``"XYZ"``. Upper case = **intrinsic** (rotations about the moving
  axes, as BVH ``CHANNELS`` use them): ``R = R_X(a0) @ R_Y(a1) @ R_Z(a2)``,
  i.e. the angles compose left to right in channel order. Lower case
  = **extrinsic** (about the fixed axes): ``"xyz"`` means first x, then y, then z
  about the world axes, ``R = R_z(a2) @ R_y(a1) @ R_x(a0)``. Any of the six
  Tait-Bryan orders works (XYZ, XZY, YXZ, YZX, ZXY, ZYX and their lower-case
  versions). A BVH joint with ``CHANNELS 3 Zrotation Xrotation Yrotation``
  therefore has ``R = euler_angles_to_matrix(angles_in_that_order, "ZXY")``.

All functions accept float32 or float64 tensors and keep the dtype; float64 is
accurate to ~1e-12, including angles near 0 and near π. A wrong trailing shape
raises :class:`~dancekit.errors.ParameterError` (a ``ValueError``).
"""

from __future__ import annotations

import torch

from dancekit.errors import ParameterError

__all__ = [
    "axis_angle_to_matrix",
    "axis_angle_to_quaternion",
    "euler_angles_to_matrix",
    "geodesic_distance",
    "matrix_to_axis_angle",
    "matrix_to_euler_angles",
    "matrix_to_quaternion",
    "matrix_to_rotation_6d",
    "quaternion_multiply",
    "quaternion_slerp",
    "quaternion_to_axis_angle",
    "quaternion_to_matrix",
    "rotation_6d_to_matrix",
    "rotation_6d_to_matrix_procrustes",
]


def _check(x: torch.Tensor, shape: tuple[int, ...], name: str) -> None:
    if not isinstance(x, torch.Tensor):
        raise ParameterError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if tuple(x.shape[x.dim() - len(shape):]) != shape or x.dim() < len(shape):
        raise ParameterError(f"{name} must have shape (..., {', '.join(map(str, shape))}), got {tuple(x.shape)}")


def _eps(x: torch.Tensor) -> float:
    return 1e-12 if x.dtype == torch.float64 else 1e-6


# --------------------------------------------------------------- quaternions
def quaternion_to_matrix(quaternions: torch.Tensor) -> torch.Tensor:
    """Quaternions ``(..., 4)`` (w, x, y, z; normalised here) → matrices ``(..., 3, 3)``."""
    _check(quaternions, (4,), "quaternions")
    q = quaternions / quaternions.norm(dim=-1, keepdim=True).clamp_min(_eps(quaternions))
    w, x, y, z = q.unbind(-1)
    two = 2.0
    m = torch.stack(
        [
            1 - two * (y * y + z * z), two * (x * y - z * w), two * (x * z + y * w),
            two * (x * y + z * w), 1 - two * (x * x + z * z), two * (y * z - x * w),
            two * (x * z - y * w), two * (y * z + x * w), 1 - two * (x * x + y * y),
        ],
        dim=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quaternion(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` → unit quaternions ``(..., 4)`` (w-first, w >= 0).

    Uses the numerically best of the four Shepperd candidates per matrix, so it
    is stable for every angle including π.
    """
    _check(matrix, (3, 3), "matrix")
    m = matrix
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 q_i^2 for each component
    sq = torch.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], dim=-1
    )
    q_abs = sq.clamp_min(0).sqrt()  # 2 |q_i|
    # candidates: each row is 2 q_i * (w, x, y, z) for pivot i, divided by 2 |q_i| later
    cand = torch.stack(
        [
            torch.stack([sq[..., 0], m21 - m12, m02 - m20, m10 - m01], dim=-1),
            torch.stack([m21 - m12, sq[..., 1], m10 + m01, m02 + m20], dim=-1),
            torch.stack([m02 - m20, m10 + m01, sq[..., 2], m12 + m21], dim=-1),
            torch.stack([m10 - m01, m20 + m02, m21 + m12, sq[..., 3]], dim=-1),
        ],
        dim=-2,
    )
    cand = cand / (2.0 * q_abs[..., None].clamp_min(0.1))
    best = q_abs.argmax(dim=-1)
    q = torch.gather(cand, -2, best[..., None, None].expand(best.shape + (1, 4))).squeeze(-2)
    q = q / q.norm(dim=-1, keepdim=True)
    return torch.where(q[..., :1] < 0, -q, q)


def quaternion_multiply(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product ``a ⊗ b`` of quaternions ``(..., 4)`` (w-first; broadcasts).

    ``quaternion_to_matrix(a ⊗ b) == quaternion_to_matrix(a) @ quaternion_to_matrix(b)``.
    """
    _check(a, (4,), "a")
    _check(b, (4,), "b")
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


def axis_angle_to_quaternion(axis_angle: torch.Tensor) -> torch.Tensor:
    """Axis-angle ``(..., 3)`` (radians) → unit quaternions ``(..., 4)`` (w-first).

    Stable at zero angle (Taylor expansion of ``sin(θ/2)/θ``).
    """
    _check(axis_angle, (3,), "axis_angle")
    angle = axis_angle.norm(dim=-1, keepdim=True)
    half = 0.5 * angle
    small = angle < 1e-4
    safe = torch.where(small, torch.ones_like(angle), angle)
    s = torch.where(small, 0.5 - angle * angle / 48.0, torch.sin(half) / safe)
    return torch.cat([torch.cos(half), axis_angle * s], dim=-1)


def quaternion_to_axis_angle(quaternions: torch.Tensor) -> torch.Tensor:
    """Unit quaternions ``(..., 4)`` (w-first) → axis-angle ``(..., 3)`` with angle in [0, π]."""
    _check(quaternions, (4,), "quaternions")
    q = quaternions / quaternions.norm(dim=-1, keepdim=True).clamp_min(_eps(quaternions))
    q = torch.where(q[..., :1] < 0, -q, q)
    xyz = q[..., 1:]
    s = xyz.norm(dim=-1, keepdim=True)
    angle = 2.0 * torch.atan2(s, q[..., :1])
    small = s < 1e-6
    safe = torch.where(small, torch.ones_like(s), s)
    # angle / sin(angle/2) → 2 + angle^2 / 12 near 0 (w ≈ 1 there)
    factor = torch.where(small, 2.0 / q[..., :1] + angle * angle / 12.0, angle / safe)
    return xyz * factor


def axis_angle_to_matrix(axis_angle: torch.Tensor) -> torch.Tensor:
    """Axis-angle ``(..., 3)`` (radians) → rotation matrices ``(..., 3, 3)`` (Rodrigues)."""
    _check(axis_angle, (3,), "axis_angle")
    return quaternion_to_matrix(axis_angle_to_quaternion(axis_angle))


def matrix_to_axis_angle(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` → axis-angle ``(..., 3)``, angle in [0, π]."""
    _check(matrix, (3, 3), "matrix")
    return quaternion_to_axis_angle(matrix_to_quaternion(matrix))


# ------------------------------------------------------------------------ 6D
def rotation_6d_to_matrix(d6: torch.Tensor) -> torch.Tensor:
    """6D ``(..., 6)`` (first two columns) → rotation matrices ``(..., 3, 3)`` by Gram-Schmidt.

    Always returns an orthonormal matrix with determinant +1 (degenerate
    inputs, e.g. zeros or parallel columns, are completed with a fixed axis).
    """
    _check(d6, (6,), "d6")
    eps = _eps(d6)
    a1, a2 = d6[..., :3], d6[..., 3:]
    n1 = a1.norm(dim=-1, keepdim=True)
    ex = torch.zeros_like(a1)
    ex[..., 0] = 1.0
    b1 = torch.where(n1 > eps, a1 / n1.clamp_min(eps), ex)
    a2 = a2 - (b1 * a2).sum(-1, keepdim=True) * b1
    n2 = a2.norm(dim=-1, keepdim=True)
    # fallback: any unit vector perpendicular to b1
    alt = torch.where(b1[..., :1].abs() < 0.9, ex, torch.roll(ex, 1, dims=-1))
    alt = alt - (b1 * alt).sum(-1, keepdim=True) * b1
    alt = alt / alt.norm(dim=-1, keepdim=True)
    b2 = torch.where(n2 > eps, a2 / n2.clamp_min(eps), alt)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def rotation_6d_to_matrix_procrustes(d6: torch.Tensor) -> torch.Tensor:
    """6D ``(..., 6)`` → the rotation whose first two columns fit it best: ``(..., 3, 3)``.

    ``R = argmax_R tr(R^T [a1 a2 0])`` over proper rotations (orthogonal Procrustes / Wahba's problem,
    solved by SVD with a determinant correction): each column pulls on ``R`` in proportion to its length.
    For an orthonormal pair it is the Gram-Schmidt result. It differs where a network's output is
    lopsided: Gram-Schmidt keeps ``a1``'s direction exactly, however short and noisy ``a1`` is, and
    bends ``a2`` to it; here a long ``a2`` wins. A model that cannot tell a root's heading (its ``a1``,
    for a y-up body) regresses it towards a short average vector, and Gram-Schmidt then tilts the
    well-known up axis ``a2`` to fit whatever direction that average has.
    Equal to ``scipy.spatial.transform.Rotation.align_vectors`` of the unit columns onto the first two
    axes, weighted by the columns' lengths. Degenerate input (zeros) gives some proper rotation.
    """
    _check(d6, (6,), "d6")
    a1, a2 = d6[..., :3], d6[..., 3:]
    m = torch.stack([a1, a2, torch.zeros_like(a1)], dim=-1)  # (..., 3, 3): columns a1, a2, 0
    u, _, vh = torch.linalg.svd(m)
    d = torch.linalg.det(u @ vh)
    fix = torch.ones(d.shape + (3,), dtype=d6.dtype, device=d6.device)
    fix[..., 2] = torch.where(d < 0, -1.0, 1.0).to(d6.dtype)
    return u @ (fix[..., :, None] * vh)


def matrix_to_rotation_6d(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` → 6D ``(..., 6)``: columns 0 and 1 concatenated."""
    _check(matrix, (3, 3), "matrix")
    return torch.cat([matrix[..., :, 0], matrix[..., :, 1]], dim=-1)


# --------------------------------------------------------------------- Euler
_TAIT_BRYAN = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


def _parse_order(order: str) -> tuple[str, bool]:
    if not isinstance(order, str) or order.upper() not in _TAIT_BRYAN or not (order.isupper() or order.islower()):
        raise ParameterError(
            f"order must be one of {_TAIT_BRYAN} (intrinsic) or their lower-case (extrinsic) forms, got {order!r}"
        )
    return order.upper(), order.isupper()


def _axis_matrix(axis: str, angle: torch.Tensor) -> torch.Tensor:
    c, s = torch.cos(angle), torch.sin(angle)
    o, z = torch.ones_like(angle), torch.zeros_like(angle)
    if axis == "X":
        flat = (o, z, z, z, c, -s, z, s, c)
    elif axis == "Y":
        flat = (c, z, s, z, o, z, -s, z, c)
    else:
        flat = (c, -s, z, s, c, z, z, z, o)
    return torch.stack(flat, dim=-1).reshape(angle.shape + (3, 3))


def euler_angles_to_matrix(angles: torch.Tensor, order: str) -> torch.Tensor:
    """Euler angles ``(..., 3)`` (radians, in ``order``'s axis order) → matrices ``(..., 3, 3)``.

    Parameters
    ----------
    angles : torch.Tensor, shape (..., 3)
        ``angles[..., i]`` is the angle about axis ``order[i]``.
    order : str
        Upper case (``"ZXY"``): intrinsic, ``R = R_Z(a0) @ R_X(a1) @ R_Y(a2)``
        (BVH channel order). Lower case (``"zxy"``): extrinsic,
        ``R = R_y(a2) @ R_x(a1) @ R_z(a0)``.
    """
    _check(angles, (3,), "angles")
    axes, intrinsic = _parse_order(order)
    mats = [_axis_matrix(a, angles[..., i]) for i, a in enumerate(axes)]
    if intrinsic:
        return mats[0] @ mats[1] @ mats[2]
    return mats[2] @ mats[1] @ mats[0]


def matrix_to_euler_angles(matrix: torch.Tensor, order: str) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` → Euler angles ``(..., 3)`` for ``order``.

    Inverse of :func:`euler_angles_to_matrix`: the middle angle lies in
    [-π/2, π/2], the others in (-π, π]. At gimbal lock (middle angle ±π/2) the
    last angle is set to 0 and the first absorbs the rotation.
    """
    _check(matrix, (3, 3), "matrix")
    axes, intrinsic = _parse_order(order)
    if not intrinsic:
        # extrinsic abc == intrinsic cba with reversed angles
        rev = matrix_to_euler_angles(matrix, axes[::-1])
        return rev.flip(-1)
    i, j, k = ("XYZ".index(a) for a in axes)
    # sign of the permutation (i, j, k): +1 for cyclic (XYZ, YZX, ZXY)
    sign = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    m = matrix
    # intrinsic R = R_i(a) R_j(b) R_k(c): R[i, k] = sign * sin(b)
    sb = (sign * m[..., i, k]).clamp(-1.0, 1.0)
    b = torch.asin(sb)
    # cos(b) > 0 branch
    a = torch.atan2(-sign * m[..., j, k], m[..., k, k])
    c = torch.atan2(-sign * m[..., i, j], m[..., i, i])
    locked = sb.abs() > 1 - 1e-10 if m.dtype == torch.float64 else sb.abs() > 1 - 1e-6
    if bool(locked.any()):
        # c = 0; R = R_i(a) R_j(±π/2): solve a from the j-row/k-row of column j
        a_lock = torch.atan2(sign * m[..., k, j], m[..., j, j])
        a = torch.where(locked, a_lock, a)
        c = torch.where(locked, torch.zeros_like(c), c)
    return torch.stack([a, b, c], dim=-1)


# ------------------------------------------------------------------ distance
def geodesic_distance(R1: torch.Tensor, R2: torch.Tensor) -> torch.Tensor:
    """Angle in radians ``(...)`` of the relative rotation ``R1ᵀ R2`` (in [0, π]).

    Computed with ``atan2(|skew|, trace)`` so it is accurate near 0 and π.
    """
    _check(R1, (3, 3), "R1")
    _check(R2, (3, 3), "R2")
    R = R1.transpose(-1, -2) @ R2
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    skew = torch.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    return torch.atan2(0.5 * skew.norm(dim=-1), 0.5 * (tr - 1.0))


def quaternion_slerp(q0: torch.Tensor, q1: torch.Tensor, t: torch.Tensor | float) -> torch.Tensor:
    """Spherical linear interpolation between unit quaternions ``(..., 4)`` (w-first).

    ``t`` broadcasts against the leading dimensions (a float, or a tensor of
    shape ``(...)``); ``t = 0`` gives ``q0``, ``t = 1`` gives ``q1`` (up to
    sign). Takes the shorter arc; falls back to normalised linear
    interpolation for nearly equal quaternions.
    """
    _check(q0, (4,), "q0")
    _check(q1, (4,), "q1")
    if not isinstance(t, torch.Tensor):
        t = torch.tensor(t, dtype=q0.dtype, device=q0.device)
    t = t.to(q0.dtype)[..., None]
    q0 = q0 / q0.norm(dim=-1, keepdim=True)
    q1 = q1 / q1.norm(dim=-1, keepdim=True)
    dot = (q0 * q1).sum(-1, keepdim=True)
    q1 = torch.where(dot < 0, -q1, q1)
    dot = dot.abs().clamp(max=1.0)
    theta = torch.acos(dot)
    sin_t = torch.sin(theta)
    near = sin_t < 1e-6
    safe = torch.where(near, torch.ones_like(sin_t), sin_t)
    w0 = torch.where(near, 1.0 - t, torch.sin((1.0 - t) * theta) / safe)
    w1 = torch.where(near, t, torch.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / q.norm(dim=-1, keepdim=True)
