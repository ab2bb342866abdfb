"""Skeleton and Motion: built-ins, roles, validation, resampling, mirroring, 2D projection."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from dancekit.errors import MotionFormatError, ParameterError
from dancekit.motion import CANONICAL_ROLES, Motion, Skeleton, get_skeleton, smpl_skeleton
from dancekit.motion.rotations import axis_angle_to_matrix, geodesic_distance

LIMB_ROLES = [r for r in CANONICAL_ROLES if r.startswith(("left_", "right_"))]


# --------------------------------------------------------------- skeletons
@pytest.mark.parametrize(("name", "J", "dims", "units"), [("tang2018", 23, 3, "cm"), ("body25", 25, 2, "px"),
                                                         ("smpl", 24, 3, "m")])
def test_builtin_skeletons(name, J, dims, units):
    sk = get_skeleton(name)
    assert sk.num_joints == J and sk.dims == dims and sk.units == units
    assert sk.parents[sk.root] == -1
    assert len(sk.bones) == J - 1
    for role in LIMB_ROLES + ["pelvis", "head"]:
        assert sk.has(role), (name, role)
    perm = sk.mirror_permutation()
    assert np.array_equal(perm[perm], np.arange(J))
    back = Skeleton.from_dict(json.loads(json.dumps(sk.to_dict())))
    assert back.same_as(sk) and back.name == name


def test_tang2018_structure():
    sk = get_skeleton("tang2018")
    assert sk.root == 2 and sk.joint_names[2] == "pelvis"
    assert sk.unit_scale == 0.01 and sk.up_axis == "y"
    assert not sk.has("neck")  # the neck is virtual in this data
    # sides as derived from the data: 16-20 and 12-15 are the left side
    assert [sk.index(f"left_{p}") for p in ("hip", "knee", "ankle", "heel", "toe")] == [16, 17, 18, 19, 20]
    assert [sk.index(f"right_{p}") for p in ("hip", "knee", "ankle", "heel", "toe")] == [7, 8, 9, 10, 11]
    assert [sk.index(f"left_{p}") for p in ("shoulder", "elbow", "wrist")] == [12, 13, 15]
    assert [sk.index(f"right_{p}") for p in ("shoulder", "elbow", "wrist")] == [3, 4, 6]
    assert sk.mirror_permutation()[[16, 3, 21, 0]].tolist() == [7, 12, 22, 1]
    # rest pose: left joints on +x, head above, feet below (x = left, y = up, z = forward)
    assert sk.offsets[16, 0] > 0 > sk.offsets[7, 0]
    assert sk.offsets[0, 1] > 40 and sk.offsets[8, 1] < -40
    assert sk.offsets[11, 2] > 0  # toe ahead of the heel


def test_index_by_name_and_role_and_errors():
    sk = get_skeleton("smpl")
    assert sk.index("left_foot") == 10 and sk.index("left_toe") == 10
    assert sk.index("pelvis") == 0
    with pytest.raises(ParameterError, match="no_such_joint"):
        sk.index("no_such_joint")
    assert not sk.has("no_such_joint")


def test_skeleton_validation():
    off = np.zeros((3, 3))
    with pytest.raises(ParameterError, match="root"):
        Skeleton(name="x", joint_names=("a", "b", "c"), parents=(-1, -1, 0), offsets=off)
    with pytest.raises(ParameterError, match="cycle"):
        Skeleton(name="x", joint_names=("a", "b", "c"), parents=(-1, 2, 1), offsets=off)
    with pytest.raises(ParameterError, match="duplicate"):
        Skeleton(name="x", joint_names=("a", "a", "c"), parents=(-1, 0, 0), offsets=off)
    with pytest.raises(ParameterError, match="offsets"):
        Skeleton(name="x", joint_names=("a", "b", "c"), parents=(-1, 0, 0), offsets=np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="nope"):
        Skeleton(name="x", joint_names=("a", "b", "c"), parents=(-1, 0, 0), offsets=off, roles={"head": "nope"})
    with pytest.raises(ParameterError, match="up_axis"):
        Skeleton(name="x", joint_names=("a", "b", "c"), parents=(-1, 0, 0), offsets=off, up_axis="x")
    with pytest.raises(ParameterError, match="unknown skeleton"):
        get_skeleton("mixamo")
    # frozen
    with pytest.raises(AttributeError):
        get_skeleton("tang2018").name = "other"  # type: ignore[misc]


@pytest.mark.parametrize("suffix", [".npy", ".json", ".npz"])
def test_smpl_user_offsets(tmp_path, suffix):
    off = np.arange(72, dtype=np.float64).reshape(24, 3) / 100
    path = tmp_path / f"off{suffix}"
    if suffix == ".npy":
        np.save(path, off)
    elif suffix == ".npz":
        np.savez(path, offsets=off)
    else:
        path.write_text(json.dumps({"offsets": off.tolist()}))
    sk = smpl_skeleton(offsets_path=path)
    assert np.allclose(sk.offsets[1:], off[1:]) and np.all(sk.offsets[0] == 0)


def test_smpl_bad_offsets(tmp_path):
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((23, 3)))
    with pytest.raises(MotionFormatError, match="bad.npy"):
        smpl_skeleton(offsets_path=bad)
    with pytest.raises(MotionFormatError, match="missing.npy"):
        smpl_skeleton(offsets_path=tmp_path / "missing.npy")


@pytest.mark.shared
@pytest.mark.slow
def test_tang2018_sides_and_offsets_from_data(tang2018_dir):
    """Re-derive the side assignment and the hard-coded rest offsets from the data."""
    from dancekit.motion._tang2018_rest import measure_rest_offsets, side_evidence
    from dancekit.motion.formats import read_tang2018

    sk = get_skeleton("tang2018")
    folders = sorted(f for f in tang2018_dir.iterdir() if f.is_dir() and f.name.startswith("DANCE_"))
    all_pos = []
    for f in folders:
        m, _ = read_tang2018(f)
        ev = side_evidence(m.positions)
        assert ev["hip16_left_by_feet"] > 0.85 and ev["shoulder12_left_by_feet"] > 0.85, f.name
        assert ev["hip16_left_by_knees"] > 0.6, f.name
        all_pos.append(m.positions)
    off, mean_len, std_len = measure_rest_offsets(np.concatenate(all_pos))
    assert np.allclose(off, sk.offsets, atol=0.02)
    assert np.all(std_len[[j for j in range(23) if j != sk.root]] < 5.0)


# ------------------------------------------------------------------ Motion
def _motion(rng, T=30, rotations=False) -> Motion:
    sk = get_skeleton("tang2018")
    aa = torch.from_numpy(rng.normal(scale=0.3, size=(T, 23, 3)))
    R = axis_angle_to_matrix(aa).numpy()
    tr = np.cumsum(rng.normal(size=(T, 3)), axis=0) + [0.0, 100.0, 0.0]
    m = Motion(sk, 25, rotations=R, root_translation=tr)
    return m if rotations else Motion(sk, 25, positions=m.to_positions())


def test_motion_basics(rng):
    m = _motion(rng, T=50)
    assert m.num_frames == 50 and m.duration == 2.0
    assert np.allclose(m.times[:3], [0, 0.04, 0.08])
    assert "tang2018" in repr(m)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"fps": 0, "positions": np.zeros((4, 23, 3))}, "fps"),
        ({"fps": float("nan"), "positions": np.zeros((4, 23, 3))}, "fps"),
        ({"fps": 25}, "positions or rotations"),
        ({"fps": 25, "positions": np.zeros((4, 22, 3))}, r"\(T, 23, 3\)"),
        ({"fps": 25, "positions": np.zeros((4, 23, 2))}, r"\(T, 23, 3\)"),
        ({"fps": 25, "positions": np.full((4, 23, 3), np.nan)}, "NaN"),
        ({"fps": 25, "rotations": np.zeros((4, 23, 3, 3))}, "root_translation"),
        ({"fps": 25, "rotations": np.zeros((4, 23, 3, 3)), "root_translation": np.zeros((3, 3))}, "root_translation"),
        ({"fps": 25, "positions": np.zeros((4, 23, 3)), "rotations": np.zeros((5, 23, 3, 3))}, "frames"),
    ],
)
def test_motion_validation(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Motion(get_skeleton("tang2018"), **kwargs)


def test_to_positions_and_with_rotations(rng):
    m = _motion(rng, rotations=True)
    assert m.positions is None
    pos = m.to_positions()
    assert pos.shape == (30, 23, 3)
    m2 = Motion(m.skeleton, m.fps, positions=pos).with_rotations()
    assert m2.rotations.shape == (30, m.skeleton.rig().num_joints, 3, 3) == (30, 28, 3, 3) and m2.positions is pos
    # rigid motion: IK rotations reproduce the positions
    again = Motion(m.skeleton, m.fps, rotations=m2.rotations, root_translation=m2.root_translation)
    assert np.allclose(again.to_positions(), pos, atol=1e-8)
    assert m2.with_rotations() is m2


def test_resample_positions_linear_known_answer():
    sk = get_skeleton("tang2018")
    T = 11
    pos = np.zeros((T, 23, 3))
    pos[:, :, 0] = np.arange(T)[:, None] * 2.0  # x moves 2 units per frame at 10 fps
    m = Motion(sk, 10, positions=pos)
    up = m.resample(20)
    assert up.fps == 20 and up.num_frames == 21
    assert np.allclose(up.positions[:, 0, 0], np.arange(21) * 1.0)
    down = m.resample(5)
    assert down.num_frames == 6 and np.allclose(down.positions[:, 5, 0], np.arange(6) * 4.0)
    with pytest.raises(ParameterError, match="fps"):
        m.resample(-1)


def test_resample_rotations_slerp_halfway_is_45_degrees():
    sk = get_skeleton("tang2018")
    R = np.broadcast_to(np.eye(3), (2, 23, 3, 3)).copy()
    R[1, 5] = axis_angle_to_matrix(torch.tensor([0.0, math.pi / 2, 0.0], dtype=torch.float64)).numpy()
    m = Motion(sk, 1, rotations=R, root_translation=np.zeros((2, 3)))
    r = m.resample(2)
    assert r.num_frames == 3
    ang = geodesic_distance(torch.eye(3, dtype=torch.float64), torch.from_numpy(r.rotations[1, 5]))
    assert abs(float(ang) - math.pi / 4) < 1e-12
    assert np.allclose(r.rotations[1, 4], np.eye(3))


def test_slice(rng):
    m = _motion(rng, T=30).with_rotations()
    s = m.slice(10, 20)
    assert s.num_frames == 10 and np.array_equal(s.positions, m.positions[10:20])
    assert np.array_equal(s.rotations, m.rotations[10:20])
    assert m.slice(-5).num_frames == 5
    with pytest.raises(ParameterError, match="empty"):
        m.slice(20, 10)


MIRROR_X = np.diag([-1.0, 1.0, 1.0])  # the mirror: world x negated (the skeletons' left-right axis)


def _rot(axis: str, angle: float) -> np.ndarray:
    return axis_angle_to_matrix(torch.tensor(np.eye(3)["xyz".index(axis)] * angle)).numpy()


def test_mirror_known_answer_and_involution(rng):
    m = _motion(rng)
    sk = m.skeleton
    mm = m.mirror()
    li, ri = sk.index("left_hip"), sk.index("right_hip")
    assert np.allclose(mm.positions[:, li, 0], -m.positions[:, ri, 0])
    assert np.allclose(mm.positions[:, li, 1:], m.positions[:, ri, 1:])
    assert np.allclose(mm.mirror().positions, m.positions)
    # with rotations: they are the mirrored pose's, so their FK is the mirrored positions (tang2018 is not
    # left-right symmetric, so at its rest bone lengths: exactly what inverse kinematics promises)
    from dancekit.motion.kinematics import normalize_bone_lengths, rig_forward_kinematics

    mr = m.with_rotations().mirror()
    assert mr.rotations is not None and mr.rotations.shape == (m.num_frames, sk.rig().num_joints, 3, 3)
    assert np.allclose(mr.positions, mm.positions)
    fk = rig_forward_kinematics(mr.rotations, mr.root_translation, sk).numpy()
    np.testing.assert_allclose(fk, normalize_bone_lengths(mm.positions, sk), atol=1e-6)
    np.testing.assert_allclose(mr.root_translation, mm.positions[:, sk.root], atol=1e-9)


def test_mirror_of_rotations_known_answer():
    """On the symmetric SMPL skeleton: a body turned by theta about the up axis (y) turns by -theta in the
    mirror, a tilt about the mirror's normal (x) stays, and every other joint stays at rest."""
    sk = smpl_skeleton()
    J, theta, alpha = sk.num_joints, 0.7, 0.3
    R = np.broadcast_to(np.eye(3), (2, J, 3, 3)).copy()
    R[0, sk.root] = _rot("y", theta)
    R[1, sk.root] = _rot("x", alpha) @ _rot("y", theta)
    tr = np.array([[0.2, 0.9, -0.4], [-0.1, 0.95, 0.3]])
    m = Motion(sk, 30, positions=Motion(sk, 30, rotations=R, root_translation=tr).to_positions())
    mr = m.with_rotations().mirror()
    np.testing.assert_allclose(mr.rotations[0, sk.root], _rot("y", -theta), atol=1e-9)
    np.testing.assert_allclose(mr.rotations[1, sk.root], _rot("x", alpha) @ _rot("y", -theta), atol=1e-9)
    np.testing.assert_allclose(np.delete(mr.rotations, sk.root, axis=1), np.broadcast_to(np.eye(3), (2, J - 1, 3, 3)),
                               atol=1e-9)
    np.testing.assert_allclose(mr.root_translation, tr * [-1.0, 1.0, 1.0], atol=1e-12)


def test_mirror_conjugates_rotations_on_a_symmetric_skeleton(rng):
    """Any pose on SMPL: the mirror's rotations are M R[perm] M (M = diag(-1, 1, 1)), joint for joint."""
    sk = smpl_skeleton()
    aa = torch.from_numpy(rng.normal(scale=0.4, size=(6, sk.num_joints, 3)))
    pos = Motion(sk, 30, rotations=axis_angle_to_matrix(aa).numpy(), root_translation=rng.normal(size=(6, 3)))
    m = Motion(sk, 30, positions=pos.to_positions()).with_rotations()
    mr = m.mirror()
    perm = sk.mirror_permutation()
    assert not np.allclose(perm, np.arange(sk.num_joints))
    np.testing.assert_allclose(mr.rotations, MIRROR_X @ m.rotations[:, perm] @ MIRROR_X, atol=1e-9)
    np.testing.assert_allclose(mr.root_translation, m.root_translation @ MIRROR_X, atol=1e-12)


def test_project_2d(rng):
    sk = get_skeleton("tang2018")
    # the rest pose facing +z, standing with the floor at y = 0
    rest = np.zeros((23, 3))
    for j in sk.topological_order:
        p = sk.parents[j]
        rest[j] = 0 if p < 0 else rest[p] + sk.offsets[j]
    rest[:, 1] -= rest[:, 1].min()
    m = Motion(sk, 25, positions=np.repeat(rest[None], 4, axis=0).astype(np.float32))
    p2 = m.project_2d(width=640, height=480)
    b25 = get_skeleton("body25")
    assert p2.skeleton.name == "body25" and p2.positions.shape == (4, 25, 2)
    kp = p2.positions[0]
    idx = b25.index
    # front view: the dancer's left is on the image right; image y grows downwards
    assert kp[idx("LShoulder"), 0] > kp[idx("RShoulder"), 0]
    assert kp[idx("Nose"), 1] < kp[idx("Neck"), 1] < kp[idx("MidHip"), 1] < kp[idx("LAnkle"), 1]
    assert np.allclose(kp[idx("Neck")], 0.5 * (kp[idx("LShoulder")] + kp[idx("RShoulder")]), atol=1e-3)
    # scale: 1 cm = 480 / 2.4 / 100 = 2 px, and the lowest point at 90 % of the height
    ppm = 480 / 2.4
    assert abs(kp[idx("Neck"), 1] - kp[idx("MidHip"), 1]) > 0.3 * ppm
    assert abs(p2.positions[..., 1].max() - 0.9 * 480) < 0.05 * ppm
    back = m.project_2d(view="back", width=640, height=480).positions[0]
    assert back[idx("LShoulder"), 0] < back[idx("RShoulder"), 0]
    with pytest.raises(ParameterError, match="view"):
        m.project_2d(view="top")
    with pytest.raises(ParameterError, match="3D"):
        p2.project_2d()


def test_keep_bone_lengths_known_answer():
    """A chain root → a → b: directions from the moved positions, lengths from the reference, parents first."""
    from dancekit.motion.skeleton import keep_bone_lengths

    sk = Skeleton(name="chain", joint_names=("root", "a", "b"), parents=(-1, 0, 1),
                  offsets=np.array([[0.0, 0, 0], [0, 1, 0], [0, 1, 0]]))
    x = np.array([[[0.0, 0, 0], [0, 3, 0], [0, 3, 4]]])  # reference: bones 3 and 4 long
    q = np.array([[[1.0, 1, 1], [3, 1, 1], [3, 1, 1.5]]])  # moved: a along +x, b along +z from a
    out = keep_bone_lengths(q, x, sk)
    np.testing.assert_allclose(out, [[[1, 1, 1], [4, 1, 1], [4, 1, 5]]], atol=1e-12)


def test_a_skeleton_survives_pickle():
    """A dance made in another process comes back pickled: its skeleton (read-only roles) rebuilt equal."""
    import pickle

    from dancekit.motion import get_skeleton

    for name in ("tang2018", "smpl", "body25"):
        sk = get_skeleton(name)
        back = pickle.loads(pickle.dumps(sk))
        assert back.same_as(sk) and back.name == sk.name and dict(back.roles) == dict(sk.roles)
        assert back.left_right == sk.left_right and back.feet == sk.feet and back.branch_joints == sk.branch_joints
        with pytest.raises(TypeError):
            back.roles["x"] = "y"  # still read-only
