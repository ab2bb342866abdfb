"""Forward / inverse kinematics: known answers, the rig and its branch joints, exact recovery on rigid
motion and on real tang2018 dances, BVH fixtures and AIST++ unaffected."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.motion import Motion, Skeleton, get_skeleton
from dancekit.motion.formats import read_motion, read_tang2018
from dancekit.motion.kinematics import (
    forward_kinematics,
    ik_residual,
    inverse_kinematics,
    normalize_bone_lengths,
    rig_forward_kinematics,
    rig_rotations,
)
from dancekit.motion.rotations import axis_angle_to_matrix, geodesic_distance

F64 = torch.float64
DANCES = ["DANCE_C_2", "DANCE_R_2", "DANCE_T_5", "DANCE_W_1"]  # cha-cha, rumba, tango, waltz
TANG_BRANCHES = ("pelvis_to_head_right", "pelvis_to_right_shoulder", "pelvis_to_right_hip",
                 "pelvis_to_left_shoulder", "pelvis_to_left_hip")


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
    # root -> a (offset +x 1) -> b (offset +x 2) -> c (offset +y 3), each rotated by 90 degrees about
    # another axis: root about z, a about y, b about x (column vectors, right-handed: Rz: x->y, y->-x;
    # Ry: z->x, x->-z; Rx: y->z, z->-y). Global rotations are G_a = Rz Ry, G_b = Rz Ry Rx, so
    #   a = t + Rz (1,0,0)             = (10, 1, 0)
    #   b = a + Rz Ry (2,0,0)          = a + Rz (0,0,-2) = (10, 1, -2)
    #   c = b + Rz Ry Rx (0,3,0)       = b + Rz Ry (0,0,3) = b + Rz (3,0,0) = (10, 4, -2)
    # (the reversed product R_child @ R_parent would give b = (10, 3, 0) and c = (10, 0, 0)).
    offsets = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [0.0, 3, 0]])
    R = torch.eye(3, dtype=F64).repeat(1, 4, 1, 1)
    for j, axis in enumerate(torch.eye(3, dtype=F64).flip(0)):  # z, y, x
        R[0, j] = axis_angle_to_matrix(axis * (math.pi / 2))
    assert torch.allclose(R[0, 0] @ torch.tensor([1.0, 0, 0], dtype=F64), torch.tensor([0.0, 1, 0], dtype=F64))
    pos = forward_kinematics(R, torch.tensor([[10.0, 0, 0]], dtype=F64), offsets=offsets, parents=[-1, 0, 1, 2])
    expected = np.array([[10.0, 0, 0], [10.0, 1, 0], [10.0, 1, -2], [10.0, 4, -2]])
    assert np.allclose(pos[0].numpy(), expected, atol=1e-12)


def test_fk_shape_errors():
    sk = get_skeleton("tang2018")
    with pytest.raises(ParameterError, match="rotations"):
        forward_kinematics(torch.zeros(5, 22, 3, 3), torch.zeros(5, 3), offsets=sk.offsets, parents=sk.parents)
    with pytest.raises(ParameterError, match="root_translation"):
        forward_kinematics(torch.zeros(5, 23, 3, 3), torch.zeros(4, 3), offsets=sk.offsets, parents=sk.parents)
    with pytest.raises(ParameterError, match="tree"):
        forward_kinematics(torch.zeros(1, 2, 3, 3), torch.zeros(1, 3), offsets=np.zeros((2, 3)), parents=[1, 0])


# ------------------------------------------------------------------ the rig
def test_tang2018_rig_structure():
    sk = get_skeleton("tang2018")
    assert sk.branch_joints == ("pelvis",)
    rig = sk.rig()
    assert rig is sk.rig() and rig.rig() is rig and rig.branch_joints == ()
    assert rig.num_joints == 28 and rig.joint_names[:23] == sk.joint_names
    assert rig.joint_names[23:] == TANG_BRANCHES
    assert np.array_equal(rig.offsets[:23], sk.offsets) and not np.any(rig.offsets[23:])
    # pelvis -> pelvis_to_<child> -> child; everything below is the skeleton's own tree
    for b, c in zip(range(23, 28), (0, 3, 7, 12, 16)):
        assert rig.parents[b] == 2 and rig.parents[c] == b
    assert [rig.parents[j] for j in range(23) if j not in (0, 3, 7, 12, 16)] == \
           [sk.parents[j] for j in range(23) if j not in (0, 3, 7, 12, 16)]
    # every rig joint with a non-zero child bone has exactly one child
    assert all(len(rig.children(j)) <= 1 for j in range(28) if j != rig.root)
    assert rig.mirror_permutation()[[24, 25, 23]].tolist() == [26, 27, 23]
    assert dict(rig.roles) == dict(sk.roles)
    back = Skeleton.from_dict(sk.to_dict())
    assert back.branch_joints == ("pelvis",) and back.same_as(sk) and not back.same_as(sk.replace(branch_joints=()))


@pytest.mark.parametrize("name", ["smpl", "body25"])
def test_skeletons_without_branch_joints_are_their_own_rig(name):
    sk = get_skeleton(name)
    assert sk.branch_joints == () and sk.rig() is sk


def test_branch_joint_validation():
    off = np.ones((4, 3))
    kw = {"name": "x", "joint_names": ("r", "a", "b", "c"), "parents": (-1, 0, 0, 1), "offsets": off}
    assert Skeleton(**kw, branch_joints=("r",)).rig().joint_names[4:] == ("r_to_a", "r_to_b")
    with pytest.raises(ParameterError, match="'nope'"):
        Skeleton(**kw, branch_joints=("nope",))
    with pytest.raises(ParameterError, match="'a' needs at least 2 children"):
        Skeleton(**kw, branch_joints=("a",))
    clash = dict(kw, joint_names=("r", "a", "b", "r_to_a"))
    with pytest.raises(ParameterError, match="r_to_a"):
        Skeleton(**clash, branch_joints=("r",))


def test_rig_rotations_pads_identity_and_rejects_bad_shapes(rng):
    sk = get_skeleton("tang2018")
    R = axis_angle_to_matrix(torch.from_numpy(rng.normal(size=(4, 23, 3))))
    for arr in (R, R.numpy()):
        full = rig_rotations(arr, sk)
        assert type(full) is type(arr) and tuple(full.shape) == (4, 28, 3, 3)
        assert np.array_equal(np.asarray(full[:, :23]), np.asarray(arr))
        assert np.array_equal(np.asarray(full[:, 23:]), np.broadcast_to(np.eye(3), (4, 5, 3, 3)))
        assert rig_rotations(full, sk) is full
    # identity branch joints: the same pose as FK on the 23-joint tree
    tr = torch.zeros(4, 3, dtype=F64)
    assert torch.allclose(rig_forward_kinematics(R, tr, sk),
                          forward_kinematics(R, tr, offsets=sk.offsets, parents=sk.parents), atol=1e-12)
    with pytest.raises(ParameterError, match=r"\(\.\.\., 28, 3, 3\) or \(\.\.\., 23, 3, 3\)"):
        rig_rotations(np.zeros((4, 24, 3, 3)), sk)
    # Motion stores rotations on the rig
    m = Motion(sk, 25, rotations=R.numpy(), root_translation=np.zeros((4, 3)))
    assert m.rotations.shape == (4, 28, 3, 3)
    with pytest.raises(ParameterError, match=r"\(T, 28, 3, 3\)"):
        Motion(sk, 25, rotations=np.zeros((4, 27, 3, 3)), root_translation=np.zeros((4, 3)))


# ---------------------------------------------------------------- IK
@pytest.mark.parametrize("name", ["tang2018", "smpl"])
def test_ik_recovers_rigid_motion_exactly(name, rng):
    sk = get_skeleton(name)
    R, _, pos = _random_rigid_motion(sk, rng)
    R2, tr2 = inverse_kinematics(pos, sk)
    rig = sk.rig()
    assert tuple(R2.shape) == (40, rig.num_joints, 3, 3)
    back = rig_forward_kinematics(R2, tr2, sk)
    assert torch.allclose(back, pos, atol=1e-8)
    # the root rotation is recovered, and rigid input needs no branch correction
    assert torch.allclose(R2[:, sk.root], R[:, sk.root], atol=1e-8)
    eye = torch.eye(3, dtype=F64)
    assert torch.allclose(R2[:, sk.num_joints:], eye.expand_as(R2[:, sk.num_joints:]), atol=1e-8)
    # leaves get the identity
    leaves = [j for j in range(rig.num_joints) if j not in set(rig.parents)]
    assert torch.allclose(R2[:, leaves], eye.expand_as(R2[:, leaves]), atol=1e-12)


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
    assert R.shape == (2, 28, 3, 3) and np.allclose(R, np.eye(3))
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


def test_ik_branch_joints_fit_a_bent_torso_exactly():
    """Known answer: head and shoulders turned 30 degrees about the vertical, hips not.

    One pelvis rotation cannot fit both groups; the branch joints can.
    """
    sk = get_skeleton("tang2018")
    R = torch.eye(3, dtype=F64).repeat(1, 23, 1, 1)
    rest = rig_forward_kinematics(R, torch.zeros(1, 3, dtype=F64), sk)[0].numpy()
    twist = axis_angle_to_matrix(torch.tensor([0.0, math.pi / 6, 0.0], dtype=F64)).numpy()
    upper = [0, 1, 3, 4, 5, 6, 12, 13, 14, 15, 21, 22]
    pos = rest.copy()
    pos[upper] = rest[upper] @ twist.T  # rotate about the pelvis (at the origin)
    R2, tr = inverse_kinematics(pos[None], sk)
    assert np.abs(rig_forward_kinematics(R2, tr, sk).numpy()[0] - pos).max() < 1e-9
    # without branch joints: the 23-joint Kabsch fit leaves centimetres of error
    flat = sk.replace(branch_joints=())
    assert ik_residual(pos[None], flat).max() > 2.0
    # the pelvis takes part of the turn (the weighted best fit of its five bones, as without branch
    # joints), and each branch joint the rest for its own bone
    R_flat, _ = inverse_kinematics(pos[None], flat)
    assert np.allclose(R2[0, sk.root], R_flat[0, sk.root], atol=1e-12)
    ang = np.degrees(geodesic_distance(torch.eye(3, dtype=F64), torch.from_numpy(R2[0, [2, 23, 24, 25, 26, 27]])).numpy())
    assert 5.0 < ang[0] < 25.0 and np.all((0.5 < ang[1:]) & (ang[1:] < 30.0)), ang


def _errors(fk: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, float]:
    err = np.linalg.norm(fk - ref, axis=-1)  # (T, J)
    return err.mean(0), float(np.percentile(err, 99))


@pytest.mark.shared
@pytest.mark.slow
def test_fk_ik_on_real_tang2018_dances(tang2018_dir):
    """FK(IK(p)) against p with rest bone lengths, on four real dances (one per genre), in float64.

    Acceptance: within 1 cm per joint (the worst joint's mean and the 99th
    percentile). With the rig's branch joints it is exact to float precision;
    without them (one pelvis rotation for hips, shoulders and head) it is not
    (2-3.5 cm mean, see docs/MOTION.md), which this test checks too.
    """
    sk = get_skeleton("tang2018")
    flat = sk.replace(branch_joints=())
    for name in DANCES:
        motion, _ = read_tang2018(tang2018_dir / name)
        pos = motion.positions.astype(np.float64)
        R, tr = inverse_kinematics(torch.from_numpy(pos), sk)
        assert R.dtype == F64 and tuple(R.shape) == (len(pos), 28, 3, 3)
        fk = rig_forward_kinematics(R, tr, sk).numpy()
        ref = normalize_bone_lengths(pos, sk)
        joint_mean, p99 = _errors(fk, ref)
        assert joint_mean.max() < 1.0 and p99 < 1.0, (name, joint_mean.max(), p99)
        assert np.abs(fk - ref).max() < 1e-6, name  # in fact exact
        # bone directions are the observed ones
        for p, j in sk.bones:
            v, w = fk[:, j] - fk[:, p], pos[:, j] - pos[:, p]
            cos = (v * w).sum(-1) / np.linalg.norm(v, axis=-1) / np.linalg.norm(w, axis=-1)
            assert cos.min() > 1 - 1e-12, (name, sk.joint_names[j])
        assert np.allclose(ik_residual(pos[:50], sk), np.linalg.norm(fk[:50] - ref[:50], axis=-1), atol=1e-9)
        # the pelvis keeps the least-squares body orientation; the branch joints are small corrections
        R_flat, tr_flat = inverse_kinematics(torch.from_numpy(pos), flat)
        assert torch.allclose(R[:, sk.root], R_flat[:, sk.root], atol=1e-12)
        ang = geodesic_distance(torch.eye(3, dtype=F64), R[:, 23:]).numpy()
        assert np.degrees(np.median(ang)) < 15.0, name
        # without branch joints the criterion fails: the reason they exist
        fk_flat = forward_kinematics(R_flat, tr_flat, offsets=sk.offsets, parents=sk.parents).numpy()
        flat_mean, _ = _errors(fk_flat, ref)
        assert flat_mean.max() > 3.0 and flat_mean.mean() > 1.0, (name, flat_mean.max())


@pytest.mark.shared
@pytest.mark.parametrize("name", ["bvh/bandai_namco_dance_short_001.bvh", "bvh/pymo_walk.bvh",
                                  "aistpp/sample_smpl.pkl"])
def test_ik_exact_on_rigid_fixtures(fixtures_dir, name):
    """BVH and SMPL skeletons have no branch joints; their IK is exact (their layouts are rigid)."""
    m = read_motion(fixtures_dir / name)
    sk = m.skeleton
    assert sk.branch_joints == () and sk.rig() is sk
    R, tr = inverse_kinematics(m.positions.astype(np.float64), sk)
    assert R.shape == m.rotations.shape
    height = np.ptp(m.positions[..., sk.up_index], axis=-1).max()
    assert ik_residual(m.positions, sk).max() < 1e-6 * height
    fk = rig_forward_kinematics(R, tr, sk).numpy()
    assert np.abs(fk - m.positions).max() < 1e-6 * height
