"""SMPL / AIST++ output: FK with the documented rest skeleton reproduces the dance's bone directions; the pkl re-reads."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import torch

from dancekit.errors import MotionFormatError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import read_motion, write_motion
from dancekit.motion.formats.aistpp import SMPL_PELVIS_REST, read_aistpp, write_aistpp
from dancekit.motion.kinematics import rig_forward_kinematics
from dancekit.motion.retarget import (
    SMPL_BONE_SOURCES,
    retarget_to_smpl,
    smpl_bone_directions,
    source_bone_directions,
)
from dancekit.motion.rotations import axis_angle_to_matrix


def dance(name: str = "tang2018", frames: int = 20, seed: int = 0, scale: float = 0.35) -> Motion:
    """A random but human-ish dance: small random local rotations about the rest pose, FK positions."""
    sk = get_skeleton(name)
    rng = np.random.default_rng(seed)
    J = sk.rig().num_joints
    aa = rng.normal(scale=scale, size=(frames, J, 3))
    rot = axis_angle_to_matrix(torch.from_numpy(aa)).numpy()
    tr = np.cumsum(rng.normal(scale=3.0 if sk.units == "cm" else 0.03, size=(frames, 3)), axis=0)
    pos = rig_forward_kinematics(rot, tr, sk).numpy()
    return Motion(sk, 30.0, positions=pos.astype(np.float32))


def angular_errors_deg(motion: Motion, smpl_positions: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
    src = source_bone_directions(motion)
    got = smpl_bone_directions(smpl_positions)
    return {b: np.degrees(np.arccos(np.clip(np.sum(src[b] * got[b], -1), -1, 1))) for b in src}


@pytest.mark.parametrize("name", ["tang2018", "smpl"])
def test_smpl_fk_reproduces_the_bone_directions(name):
    m = dance(name)
    smpl, scaling = retarget_to_smpl(m)
    # FK with the documented rest skeleton, from the rotations alone
    fk = rig_forward_kinematics(smpl.rotations, smpl.root_translation, get_skeleton("smpl")).numpy()
    err = angular_errors_deg(m, fk)
    assert len(err) == 13  # every limb bone, the neck, the hip and shoulder lines
    mean = float(np.mean([e.mean() for e in err.values()]))
    worst = max(float(e.max()) for e in err.values())
    # the trunk (hips' midpoint -> neck) through SMPL's bent three-joint spine: close, not exact
    sk, ism = m.skeleton, {n: k for k, n in enumerate(get_skeleton("smpl").joint_names)}
    neck_src = (m.positions[:, sk.index("neck")] if sk.has("neck")
                else 0.5 * (m.positions[:, sk.index("left_shoulder")] + m.positions[:, sk.index("right_shoulder")]))
    mid_src = 0.5 * (m.positions[:, sk.index("left_hip")] + m.positions[:, sk.index("right_hip")])
    trunk_src = neck_src - mid_src
    trunk_smpl = fk[:, ism["neck"]] - 0.5 * (fk[:, 1] + fk[:, 2])
    cos = np.sum(trunk_src * trunk_smpl, -1) / np.linalg.norm(trunk_src, axis=-1) / np.linalg.norm(trunk_smpl, axis=-1)
    trunk = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    print(f"SMPL retarget from {name}: mean angular error {mean:.2e} deg, max {worst:.2e} deg over "
          f"{len(err)} bones; trunk mean {trunk.mean():.2f} deg, max {trunk.max():.2f} deg; scaling {scaling:.3f}")
    assert worst < 0.01  # limbs, neck, hip and shoulder lines: exact
    overall = (mean * len(err) + trunk.mean()) / (len(err) + 1)
    print(f"  mean over the 14 directions, trunk included: {overall:.2f} deg")
    assert overall < 3.0 and trunk.mean() < 15.0  # random shoulder/hip twists of 0.35 rad per joint
    # the body keeps its place: the SMPL hips' midpoint is the dance's, in dance units
    mid_smpl = 0.5 * (fk[:, 1] + fk[:, 2]) * scaling
    assert np.abs(mid_smpl - mid_src).max() < 1e-3 * np.abs(mid_src).max() + 1e-6


def test_smpl_retarget_is_exact_on_a_pose_it_can_see():
    """A known answer: the SMPL rest pose itself retargets to (nearly) zero rotations."""
    sk = get_skeleton("smpl")
    m = Motion(sk, 30.0, rotations=np.tile(np.eye(3), (2, 24, 1, 1)), root_translation=np.zeros((2, 3)))
    smpl, scaling = retarget_to_smpl(m.with_positions())
    assert scaling == pytest.approx(1.0)
    assert np.abs(smpl.rotations - np.eye(3)).max() < 1e-9
    assert np.abs(smpl.positions - m.with_positions().positions).max() < 1e-9


def test_aistpp_pkl_layout_and_reread(tmp_path):
    m = dance(frames=15)
    path = tmp_path / "d.pkl"
    scaling = write_aistpp(path, m, fps=None)
    obj = pickle.loads(path.read_bytes())
    assert set(obj) == {"smpl_poses", "smpl_trans", "smpl_scaling"}
    assert obj["smpl_poses"].shape == (15, 72) and obj["smpl_trans"].shape == (15, 3)
    assert obj["smpl_scaling"].shape == (1,) and obj["smpl_scaling"][0] == pytest.approx(scaling)
    back = read_aistpp(path, fps=30.0)
    assert back.skeleton.name == "smpl" and back.num_frames == 15
    err = angular_errors_deg(m, back.positions)
    mean = float(np.mean([e.mean() for e in err.values()]))
    print(f"AIST++ pkl re-read: mean angular error {mean:.3f} deg (float32 axis-angle)")
    assert mean < 0.1
    # the AIST++ convention: joints * scaling are the dance at its own size and place
    sk = m.skeleton
    mid_src = 0.5 * (m.positions[:, sk.index("left_hip")] + m.positions[:, sk.index("right_hip")])
    mid_back = 0.5 * (back.positions[:, 1] + back.positions[:, 2]) * obj["smpl_scaling"][0]
    assert np.abs(mid_back - mid_src).max() < 0.05  # cm
    assert np.allclose(back.root_translation, obj["smpl_trans"] / scaling + SMPL_PELVIS_REST, atol=1e-5)


def test_write_motion_pkl_resamples_to_60_fps(tmp_path):
    m = dance(frames=31)  # 1 s at 30 fps
    write_motion(tmp_path / "d.pkl", m)
    back = read_motion(tmp_path / "d.pkl")
    assert back.fps == 60 and back.num_frames == 61


def test_smpl_export_needs_limbs(tmp_path):
    with pytest.raises(MotionFormatError, match="d.pkl"):
        write_aistpp(tmp_path / "d.pkl", dance().project_2d())
    assert not (tmp_path / "d.pkl").exists()


def test_bone_table_names_smpl_joints():
    names = set(get_skeleton("smpl").joint_names)
    assert all(a in names and b in names for a, b in SMPL_BONE_SOURCES)


@pytest.mark.shared
def test_smpl_retarget_real_dance(tang2018_dir):
    from dancekit.motion.formats import read_tang2018

    name = sorted(p.name for p in tang2018_dir.iterdir() if p.is_dir())[0]
    m, _ = read_tang2018(tang2018_dir / name)
    m = m.slice(0, 300)
    smpl, scaling = retarget_to_smpl(m)
    err = angular_errors_deg(m, smpl.positions)
    sk = m.skeleton
    neck = 0.5 * (m.positions[:, sk.index("left_shoulder")] + m.positions[:, sk.index("right_shoulder")])
    trunk_src = neck - 0.5 * (m.positions[:, sk.index("left_hip")] + m.positions[:, sk.index("right_hip")])
    trunk_smpl = smpl.positions[:, 12] - 0.5 * (smpl.positions[:, 1] + smpl.positions[:, 2])
    cos = np.sum(trunk_src * trunk_smpl, -1) / np.linalg.norm(trunk_src, axis=-1) / np.linalg.norm(trunk_smpl, axis=-1)
    trunk = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    mean = (sum(e.mean() for e in err.values()) + trunk.mean()) / (len(err) + 1)
    print(f"SMPL retarget of tang2018 {name} (300 frames): mean angular error {mean:.3f} deg over 14 directions, "
          f"trunk mean {trunk.mean():.2f} deg, scaling {scaling:.1f}")
    assert mean < 3.0
