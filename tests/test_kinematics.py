"""Forward / inverse kinematics: known answers, exact recovery on rigid motion, real tang2018 dances."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.motion import get_skeleton
from dancekit.motion.formats import read_tang2018
from dancekit.motion.kinematics import (
    forward_kinematics,
    ik_residual,
    inverse_kinematics,
    normalize_bone_lengths,
)
from dancekit.motion.rotations import axis_angle_to_matrix

F64 = torch.float64
DANCES = ["DANCE_C_2", "DANCE_R_2", "DANCE_T_5", "DANCE_W_1"]


def _rest_positions(sk) -> np.ndarray:
    out = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        p = sk.parents[j]
        out[j] = 0.0 if p < 0 else out[p] + sk.offsets[j]
    return out


def _random_rigid_motion(sk, rng, T=40):
    aa = torch.from_numpy(rng.normal(scale=0.6, size=(T, sk.num_joints, 3)))
    R = axis_angle_to_matrix(aa)
    tr = torch.from_numpy(rng.normal(scale=50.0, size=(T, 3)))
    return R, tr, forward_kinematics(R, tr, offsets=sk.offsets, parents=sk.parents)


@pytest.mark.parametrize("name", ["tang2018", "smpl"])
def test_fk_identity_is_rest_pose(name):
    sk = get_skeleton(name)
    eye = torch.eye(3, dtype=F64).expand(3, sk.num_joints, 3, 3)
    tr = torch.tensor([[0.0, 0, 0], [1.0, 2, 3], [-5.0, 0, 7]], dtype=F64)
    pos = forward_kinematics(eye, tr, offsets=sk.offsets, parents=sk.parents)
    rest = _rest_positions(sk)
    for t in range(3):
        assert np.allclose(pos[t].numpy(), rest + tr[t].numpy(), atol=1e-12)


def test_fk_known_answer_chain():
    # root -> a (offset +x 1) -> b (offset +x 2); rotate root by 90 deg about z, a by 90 deg about z
    offsets = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    R = torch.eye(3, dtype=F64).repeat(1, 3, 1, 1)
    rz = axis_angle_to_matrix(torch.tensor([0, 0, math.pi / 2], dtype=F64))
    R[0, 0] = rz
    R[0, 1] = rz
    pos = forward_kinematics(R, torch.tensor([[10.0, 0, 0]], dtype=F64), offsets=offsets, parents=[-1, 0, 1])
    expected = np.array([[10.0, 0, 0], [10.0, 1, 0], [8.0, 1, 0]])
    assert np.allclose(pos[0].numpy(), expected, atol=1e-12)


def test_fk_shape_errors():
    sk = get_skeleton("tang2018")
    with pytest.raises(ParameterError, match="rotations"):
        forward_kinematics(torch.zeros(5, 22, 3, 3), torch.zeros(5, 3), offsets=sk.offsets, parents=sk.parents)
    with pytest.raises(ParameterError, match="root_translation"):
        forward_kinematics(torch.zeros(5, 23, 3, 3), torch.zeros(4, 3), offsets=sk.offsets, parents=sk.parents)
    with pytest.raises(ParameterError, match="tree"):
        forward_kinematics(torch.zeros(1, 2, 3, 3), torch.zeros(1, 3), offsets=np.zeros((2, 3)), parents=[1, 0])


@pytest.mark.parametrize("name", ["tang2018", "smpl"])
def test_ik_recovers_rigid_motion_exactly(name, rng):
    sk = get_skeleton(name)
    _, _, pos = _random_rigid_motion(sk, rng)
    R2, tr2 = inverse_kinematics(pos, sk)
    back = forward_kinematics(R2, tr2, offsets=sk.offsets, parents=sk.parents)
    assert torch.allclose(back, pos, atol=1e-8)
    # leaves get the identity
    leaves = [j for j in range(sk.num_joints) if j not in set(sk.parents)]
    assert torch.allclose(R2[:, leaves], torch.eye(3, dtype=F64).expand_as(R2[:, leaves]), atol=1e-12)


def test_ik_single_child_is_smallest_rotation():
    # a 2-joint chain bent by 90 degrees about z: the IK rotation is exactly that, no twist
    from dancekit.motion.skeleton import Skeleton

    sk = Skeleton(name="chain", joint_names=("r", "a", "b"), parents=(-1, 0, 1),
                  offsets=np.array([[0.0, 0, 0], [0.0, 1, 0], [0.0, 1, 0]]))
    pos = np.array([[[0.0, 0, 0], [0.0, 1, 0], [-1.0, 1, 0]]])
    R, tr = inverse_kinematics(pos, sk)
    rz = axis_angle_to_matrix(torch.tensor([0, 0, math.pi / 2], dtype=F64)).numpy()
    assert isinstance(R, np.ndarray)
    assert np.allclose(R[0, 0], np.eye(3), atol=1e-12)
    assert np.allclose(R[0, 1], rz, atol=1e-12)
    assert np.allclose(tr, [[0.0, 0, 0]])


def test_ik_handles_degenerate_bones():
    sk = get_skeleton("tang2018")
    R, _ = inverse_kinematics(np.zeros((2, 23, 3)), sk)  # every bone has zero length
    assert np.allclose(R, np.eye(3))
    # a bone pointing exactly opposite its rest direction: a rotation by pi reproduces it
    from dancekit.motion.skeleton import Skeleton

    chain = Skeleton(name="chain", joint_names=("r", "a", "b"), parents=(-1, 0, 1),
                     offsets=np.array([[0.0, 0, 0], [0.0, 1, 0], [0.0, 1, 0]]))
    pos = np.array([[[0.0, 0, 0], [0.0, 1, 0], [0.0, 0, 0]]])
    R, tr = inverse_kinematics(pos, chain)
    back = forward_kinematics(torch.from_numpy(R), torch.from_numpy(tr), offsets=chain.offsets, parents=chain.parents)
    assert np.allclose(back.numpy(), pos, atol=1e-12)


def test_ik_rejects_2d_and_bad_shapes():
    with pytest.raises(ParameterError, match="3D"):
        inverse_kinematics(np.zeros((3, 25, 2)), get_skeleton("body25"))
    with pytest.raises(ParameterError, match="shape"):
        inverse_kinematics(np.zeros((3, 22, 3)), get_skeleton("tang2018"))


def test_normalize_bone_lengths_known_answer(rng):
    sk = get_skeleton("tang2018")
    pos = rng.normal(scale=40.0, size=(5, 23, 3))
    out = normalize_bone_lengths(pos, sk)
    for p, j in sk.bones:
        v_in, v_out = pos[:, j] - pos[:, p], out[:, j] - out[:, p]
        assert np.allclose(np.linalg.norm(v_out, axis=-1), np.linalg.norm(sk.offsets[j]))
        cos = (v_in * v_out).sum(-1) / np.linalg.norm(v_in, axis=-1) / np.linalg.norm(v_out, axis=-1)
        assert np.allclose(cos, 1.0)
    assert np.allclose(out[:, sk.root], pos[:, sk.root])


@pytest.mark.shared
def test_fk_ik_on_real_tang2018_dances(tang2018_dir):
    """FK(IK(p)) against p with rest bone lengths, on four real dances (one per genre).

    Every bone whose parent has a single child is reproduced exactly; the
    pelvis (children: both hips, both shoulders, head) can only be fitted in
    the least-squares sense, since the data has no spine joint and the torso
    bends: that residual shifts each whole limb by the same vector. Measured:
    2.3-3.5 cm mean per joint (see docs/MOTION.md).
    """
    sk = get_skeleton("tang2018")
    single = [j for j in range(23) if sk.parents[j] >= 0 and len(sk.children(sk.parents[j])) == 1]
    assert len(single) == 17  # every bone below the first level
    for name in DANCES:
        motion, _ = read_tang2018(tang2018_dir / name)
        pos = motion.positions.astype(np.float64)
        R, tr = inverse_kinematics(torch.from_numpy(pos), sk)
        fk = forward_kinematics(R, tr, offsets=sk.offsets, parents=sk.parents).numpy()
        ref = normalize_bone_lengths(pos, sk)
        # exact where exactness is possible: bone vectors of single-child parents
        par = np.asarray(sk.parents)[single]
        bone_err = np.linalg.norm((fk[:, single] - fk[:, par]) - (ref[:, single] - ref[:, par]), axis=-1)
        assert bone_err.max() < 1e-6, name
        # the root is exact, and the least-squares residual stays small
        err = np.linalg.norm(fk - ref, axis=-1)
        assert err[:, sk.root].max() < 1e-9
        assert err.mean() < 4.0, (name, err.mean())
        assert np.median(err) < 4.0, (name, np.median(err))
        assert np.allclose(ik_residual(pos[:50], sk), err[:50], atol=1e-6)
