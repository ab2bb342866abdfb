"""The standard humanoid BVH rig: Mixamo-like names, no zero-length bones, the dance's limb directions."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.errors import MotionFormatError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import read_motion, write_motion
from dancekit.motion.formats.bvh import HUMANOID_NAMES, parse_bvh
from dancekit.motion.kinematics import rig_forward_kinematics
from dancekit.motion.rotations import axis_angle_to_matrix

LIMBS = [(f"{s}_{a}", f"{s}_{b}") for s in ("left", "right")
         for a, b in (("hip", "knee"), ("knee", "ankle"), ("shoulder", "elbow"), ("elbow", "wrist"))]


def dance(frames: int = 15, seed: int = 1) -> Motion:
    sk = get_skeleton("tang2018")
    rng = np.random.default_rng(seed)
    rot = axis_angle_to_matrix(torch.from_numpy(rng.normal(scale=0.3, size=(frames, sk.rig().num_joints, 3)))).numpy()
    tr = np.cumsum(rng.normal(scale=3.0, size=(frames, 3)), axis=0) + [0.0, 90.0, 0.0]
    return Motion(sk, 25.0, positions=rig_forward_kinematics(rot, tr, sk).numpy().astype(np.float32))


def test_humanoid_bvh_names_and_no_zero_length_bone(tmp_path):
    m = dance()
    write_motion(tmp_path / "h.bvh", m, rig="humanoid")
    data = parse_bvh(tmp_path / "h.bvh")
    assert data.names[0] == "Hips" and set(data.names) == set(HUMANOID_NAMES.values())
    for chain in (["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head"],
                  ["Spine2", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"],
                  ["Hips", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"]):
        for parent, child in zip(chain, chain[1:]):
            assert data.parents[data.names.index(child)] == data.names.index(parent), (parent, child)
    lengths = np.linalg.norm(data.offsets, axis=1)[1:]
    print(f"humanoid BVH: {len(data.names)} joints, shortest bone {lengths.min():.2f} cm")
    assert lengths.min() > 1.0  # cm: no zero-length bone
    assert all(np.linalg.norm(o) > 1.0 for sites in data.end_sites.values() for o in sites)


def test_humanoid_bvh_rereads_with_roles_and_the_dance(tmp_path):
    m = dance()
    write_motion(tmp_path / "h.bvh", m, rig="humanoid")
    back = read_motion(tmp_path / "h.bvh")
    sk = back.skeleton
    assert sk.units == "cm" and sk.up_axis == "y" and back.num_frames == m.num_frames and back.fps == 25
    assert sk.index("left_knee") == sk.index("LeftLeg") and sk.index("spine") == sk.index("Spine")
    errs = []
    for a, b in LIMBS:
        src = (m.positions[:, m.skeleton.index(b)] - m.positions[:, m.skeleton.index(a)]).astype(np.float64)
        got = (back.positions[:, sk.index(b)] - back.positions[:, sk.index(a)]).astype(np.float64)
        errs.append(np.degrees(np.arctan2(np.linalg.norm(np.cross(src, got), axis=-1), np.sum(src * got, -1))))
    err = np.concatenate(errs)
    print(f"humanoid BVH limb directions vs the dance: mean {err.mean():.4f} deg, max {err.max():.4f} deg")
    assert err.max() < 0.05  # float32 input positions, 6 decimals of degrees in the file
    # the body stays where the dance is (hips' midpoint, cm)
    mid = lambda mm, s: 0.5 * (mm.positions[:, s.index("left_hip")] + mm.positions[:, s.index("right_hip")])  # noqa: E731
    assert np.abs(mid(back, sk) - mid(m, m.skeleton)).max() < 0.01


def test_default_rig_stays_exact(tmp_path):
    m = dance(frames=3)
    write_motion(tmp_path / "e.bvh", m)
    assert "pelvis_to_left_hip" in parse_bvh(tmp_path / "e.bvh").names
    with pytest.raises(MotionFormatError, match="rig"):
        write_motion(tmp_path / "x.bvh", m, rig="mixamo")
