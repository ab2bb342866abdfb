"""Rotation conversions in float64: round trips, identities, stability near 0 and π, known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.motion.rotations import (
    axis_angle_to_matrix,
    axis_angle_to_quaternion,
    euler_angles_to_matrix,
    geodesic_distance,
    matrix_to_axis_angle,
    matrix_to_euler_angles,
    matrix_to_quaternion,
    matrix_to_rotation_6d,
    quaternion_multiply,
    quaternion_slerp,
    quaternion_to_axis_angle,
    quaternion_to_matrix,
    rotation_6d_to_matrix,
    rotation_6d_to_matrix_procrustes,
)

F64 = torch.float64
ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "xyz", "xzy", "yxz", "yzx", "zxy", "zyx"]


@pytest.fixture
def rots(rng) -> torch.Tensor:
    q = torch.from_numpy(rng.standard_normal((500, 4)))
    return quaternion_to_matrix(q)


def _axis_angles(rng, angles) -> torch.Tensor:
    axes = rng.standard_normal((len(angles), 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    return torch.from_numpy(axes * np.asarray(angles)[:, None])


def _is_rotation(R: torch.Tensor, atol: float = 1e-10) -> bool:
    eye = torch.eye(3, dtype=R.dtype)
    return bool(
        torch.allclose(R.transpose(-1, -2) @ R, eye.expand_as(R), atol=atol)
        and torch.allclose(torch.linalg.det(R), torch.ones(R.shape[:-2], dtype=R.dtype), atol=atol)
    )


def test_random_matrices_are_rotations(rots):
    assert rots.dtype == F64
    assert _is_rotation(rots)


def test_matrix_axis_angle_round_trip(rots):
    back = axis_angle_to_matrix(matrix_to_axis_angle(rots))
    assert torch.allclose(back, rots, atol=1e-12)


def test_matrix_quaternion_round_trip(rots):
    q = matrix_to_quaternion(rots)
    assert torch.all(q[..., 0] >= 0)
    assert torch.allclose(q.norm(dim=-1), torch.ones(len(q), dtype=F64), atol=1e-12)
    assert torch.allclose(quaternion_to_matrix(q), rots, atol=1e-12)


def test_quaternion_axis_angle_round_trip(rng):
    aa = _axis_angles(rng, rng.uniform(0, math.pi * 0.999, 300))
    assert torch.allclose(quaternion_to_axis_angle(axis_angle_to_quaternion(aa)), aa, atol=1e-12)


def test_quaternion_to_axis_angle_matches_scipy_for_both_hemispheres(rng):
    """q and -q are the same rotation: w < 0 must give the short way round (angle <= pi), as scipy does."""
    from scipy.spatial.transform import Rotation

    q = rng.standard_normal((400, 4)) * rng.uniform(0.5, 2.0, (400, 1))  # not unit: it is normalised first
    q[:200, 0] = -np.abs(q[:200, 0])  # w < 0
    q[200:, 0] = np.abs(q[200:, 0])
    aa = quaternion_to_axis_angle(torch.from_numpy(q)).numpy()
    angles = np.linalg.norm(aa, axis=-1)
    assert angles.max() <= math.pi + 1e-12
    expected = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_rotvec()  # scipy: scalar last
    np.testing.assert_allclose(aa, expected, atol=1e-12)
    # a known answer: 300 degrees about +z written with w = cos(150 deg) < 0 is -60 degrees about +z
    half = math.radians(150.0)
    q300 = torch.tensor([math.cos(half), 0.0, 0.0, math.sin(half)], dtype=F64)
    assert torch.allclose(quaternion_to_axis_angle(q300), torch.tensor([0.0, 0.0, -math.pi / 3], dtype=F64),
                          atol=1e-12)


def test_rotation_6d_round_trip(rots):
    assert torch.allclose(rotation_6d_to_matrix(matrix_to_rotation_6d(rots)), rots, atol=1e-12)
    assert torch.equal(matrix_to_rotation_6d(rots)[..., :3], rots[..., :, 0])


@pytest.mark.parametrize("order", ORDERS)
def test_euler_round_trip(rots, order):
    angles = matrix_to_euler_angles(rots, order)
    assert torch.allclose(euler_angles_to_matrix(angles, order), rots, atol=1e-12)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_gimbal_lock(order):
    angles = torch.tensor([[0.3, math.pi / 2, 0.5], [-1.0, -math.pi / 2, 0.2]], dtype=F64)
    R = euler_angles_to_matrix(angles, order)
    assert torch.allclose(euler_angles_to_matrix(matrix_to_euler_angles(R, order), order), R, atol=1e-12)


def test_euler_known_answers():
    a = torch.tensor([0.1, -0.7, 1.3], dtype=F64)

    def single(axis: str, angle: float) -> torch.Tensor:
        v = torch.zeros(3, dtype=F64)
        v["XYZ".index(axis)] = angle
        return axis_angle_to_matrix(v)

    Rz, Rx, Ry = single("Z", 0.1), single("X", -0.7), single("Y", 1.3)
    # intrinsic ZXY (BVH "Zrotation Xrotation Yrotation"): R = Rz Rx Ry
    assert torch.allclose(euler_angles_to_matrix(a, "ZXY"), Rz @ Rx @ Ry, atol=1e-14)
    # extrinsic zxy: first z, then x, then y about fixed axes: R = Ry Rx Rz
    assert torch.allclose(euler_angles_to_matrix(a, "zxy"), Ry @ Rx @ Rz, atol=1e-14)
    # 90 degrees about z maps x onto y
    R = euler_angles_to_matrix(torch.tensor([0.0, 0.0, math.pi / 2], dtype=F64), "XYZ")
    assert torch.allclose(R @ torch.tensor([1.0, 0, 0], dtype=F64), torch.tensor([0.0, 1, 0], dtype=F64), atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 1e-4, 0.5, math.pi - 1e-4, math.pi - 1e-8, math.pi])
def test_stable_near_zero_and_pi(rng, angle):
    aa = _axis_angles(rng, np.full(50, angle))
    R = axis_angle_to_matrix(aa)
    assert _is_rotation(R, atol=1e-12)
    # the matrix has the requested angle
    assert torch.allclose(geodesic_distance(torch.eye(3, dtype=F64).expand_as(R), R),
                          torch.full((50,), angle, dtype=F64), atol=1e-12)
    back = matrix_to_axis_angle(R)
    assert torch.all(torch.isfinite(back))
    assert torch.allclose(axis_angle_to_matrix(back), R, atol=1e-12)
    if angle < math.pi - 1e-6:  # at π the axis sign is ambiguous
        assert torch.allclose(back, aa, atol=1e-10)
    q = matrix_to_quaternion(R)
    assert torch.allclose(quaternion_to_matrix(q), R, atol=1e-12)


def test_axis_angle_gradient_finite_at_zero():
    x = torch.zeros(2, 3, dtype=F64, requires_grad=True)
    axis_angle_to_matrix(x).sum().backward()
    assert torch.all(torch.isfinite(x.grad))
    x = torch.tensor([[0.3, -0.2, 0.5]], dtype=F64, requires_grad=True)
    assert torch.autograd.gradcheck(axis_angle_to_matrix, (x,))


def test_6d_always_gives_proper_rotation(rng):
    d6 = torch.from_numpy(rng.standard_normal((400, 6)) * rng.uniform(1e-3, 1e3, (400, 1)))
    degenerate = torch.tensor(
        [[0.0] * 6, [1.0, 0, 0, 2.0, 0, 0], [0, 0, 0, 0, 1, 0], [1e-30, 0, 0, 0, 0, 0], [0, 0, 5.0, 0, 0, -1.0]],
        dtype=F64,
    )
    R = rotation_6d_to_matrix(torch.cat([d6, degenerate]))
    assert torch.all(torch.isfinite(R))
    assert _is_rotation(R, atol=1e-10)


def test_geodesic_distance_properties(rots):
    R1, R2 = rots[:250], rots[250:]
    assert torch.allclose(geodesic_distance(R1, R1), torch.zeros(250, dtype=F64), atol=1e-7)
    d12, d21 = geodesic_distance(R1, R2), geodesic_distance(R2, R1)
    assert torch.allclose(d12, d21, atol=1e-12)
    angle = matrix_to_axis_angle(R1.transpose(-1, -2) @ R2).norm(dim=-1)
    assert torch.allclose(d12, angle, atol=1e-10)
    assert torch.all((d12 >= 0) & (d12 <= math.pi + 1e-12))


def test_quaternion_multiply_matches_matrix_product(rng):
    a = torch.from_numpy(rng.standard_normal((50, 4)))
    b = torch.from_numpy(rng.standard_normal((50, 4)))
    a, b = a / a.norm(dim=-1, keepdim=True), b / b.norm(dim=-1, keepdim=True)
    assert torch.allclose(quaternion_to_matrix(quaternion_multiply(a, b)),
                          quaternion_to_matrix(a) @ quaternion_to_matrix(b), atol=1e-12)


def test_slerp_halfway_of_90_degrees_is_45():
    q0 = torch.tensor([1.0, 0, 0, 0], dtype=F64)
    q1 = axis_angle_to_quaternion(torch.tensor([0.0, 0.0, math.pi / 2], dtype=F64))
    half = quaternion_slerp(q0, q1, 0.5)
    assert torch.allclose(quaternion_to_axis_angle(half), torch.tensor([0.0, 0.0, math.pi / 4], dtype=F64), atol=1e-12)
    # endpoints, and a batch of t values moves at constant angular speed
    assert torch.allclose(quaternion_slerp(q0, q1, 0.0), q0, atol=1e-12)
    assert torch.allclose(quaternion_slerp(q0, q1, 1.0), q1, atol=1e-12)
    t = torch.linspace(0, 1, 9, dtype=F64)
    qs = quaternion_slerp(q0.expand(9, 4), q1.expand(9, 4), t)
    assert torch.allclose(quaternion_to_axis_angle(qs)[:, 2], t * math.pi / 2, atol=1e-12)


def test_slerp_takes_the_short_arc():
    q0 = torch.tensor([1.0, 0, 0, 0], dtype=F64)
    q1 = -axis_angle_to_quaternion(torch.tensor([0.2, 0.0, 0.0], dtype=F64))  # same rotation, other sign
    mid = quaternion_to_axis_angle(quaternion_slerp(q0, q1, 0.5))
    assert torch.allclose(mid, torch.tensor([0.1, 0.0, 0.0], dtype=F64), atol=1e-12)


def test_float32_kept():
    R = axis_angle_to_matrix(torch.tensor([[0.1, 0.2, 0.3]], dtype=torch.float32))
    assert R.dtype == torch.float32
    assert matrix_to_quaternion(R).dtype == torch.float32


@pytest.mark.parametrize(
    ("fn", "shape"),
    [
        (axis_angle_to_matrix, (4,)),
        (matrix_to_axis_angle, (3, 4)),
        (quaternion_to_matrix, (3,)),
        (matrix_to_quaternion, (2, 3)),
        (rotation_6d_to_matrix, (5,)),
        (matrix_to_rotation_6d, (3,)),
        (axis_angle_to_quaternion, (2,)),
        (quaternion_to_axis_angle, (3,)),
    ],
)
def test_bad_shapes_raise(fn, shape):
    with pytest.raises(ParameterError, match=r"shape"):
        fn(torch.zeros(shape, dtype=F64))
    with pytest.raises(ValueError):  # ParameterError is a ValueError
        fn(torch.zeros((7,) + shape, dtype=F64))


def test_bad_euler_order_and_geodesic_shape():
    with pytest.raises(ParameterError, match="order"):
        euler_angles_to_matrix(torch.zeros(3, dtype=F64), "XYX")
    with pytest.raises(ParameterError, match="order"):
        euler_angles_to_matrix(torch.zeros(3, dtype=F64), "XyZ")
    with pytest.raises(ParameterError):
        geodesic_distance(torch.eye(3, dtype=F64), torch.zeros(3, dtype=F64))


def test_6d_procrustes_matches_scipy_align_vectors(rng):
    """The nearest rotation to the two 6D columns, each weighted by its length: Wahba's problem, which
    scipy's ``Rotation.align_vectors`` solves on its own (unit columns onto the x and y axes)."""
    from scipy.spatial.transform import Rotation

    d6 = torch.from_numpy(rng.standard_normal((300, 6)) * np.array([0.2] * 3 + [3.0] * 3))
    R = rotation_6d_to_matrix_procrustes(d6).numpy()
    for k in range(len(R)):
        a1, a2 = d6[k, :3].numpy(), d6[k, 3:].numpy()
        n1, n2 = np.linalg.norm(a1), np.linalg.norm(a2)
        expected, _ = Rotation.align_vectors(np.stack([a1 / n1, a2 / n2]), np.eye(3)[:2], weights=[n1, n2])
        np.testing.assert_allclose(R[k], expected.as_matrix(), atol=1e-9)
    assert _is_rotation(torch.from_numpy(R), atol=1e-10)


def test_6d_procrustes_of_an_orthonormal_pair_is_gram_schmidt(rots):
    d6 = matrix_to_rotation_6d(rots) * torch.tensor([1.0, 1.0, 1.0, 2.5, 2.5, 2.5], dtype=F64)  # lengths 1, 2.5
    assert torch.allclose(rotation_6d_to_matrix_procrustes(d6), rots, atol=1e-10)
    # a short, wrong first column: Gram-Schmidt keeps its direction, Procrustes keeps the long second one
    lopsided = torch.tensor([[0.0, 0.1, 0.1, 0.0, 3.0, 0.0]], dtype=F64)  # a1 45 degrees up, a2 = 3 * up
    up = torch.tensor([0.0, 1.0, 0.0], dtype=F64)
    assert float(rotation_6d_to_matrix_procrustes(lopsided)[0, :, 1] @ up) > 0.99
    assert float(rotation_6d_to_matrix(lopsided)[0, :, 1] @ up) < 0.75
