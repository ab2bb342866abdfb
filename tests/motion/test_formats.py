"""Motion file formats: real fixtures, round trips (rig rotations with branch joints included), known answers,
malformed input, `dancekit info`."""

from __future__ import annotations

import json
import math
import pickle
import shutil

import numpy as np
import pytest
import torch

from dancekit.cli.main import main
from dancekit.errors import MotionFormatError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import detect_format, read_motion, read_tang2018, write_motion
from dancekit.motion.formats.aistpp import read_aistpp
from dancekit.motion.formats.bvh import format_bvh, guess_roles, parse_bvh, read_bvh, write_bvh
from dancekit.motion.formats.openpose import interpolate_missing, read_openpose, write_openpose
from dancekit.motion.kinematics import normalize_bone_lengths
from dancekit.motion.rotations import axis_angle_to_matrix

BVH_FIXTURES = ["bandai_namco_dance_short_001.bvh", "pymo_walk.bvh"]
DANCES = ["DANCE_C_2", "DANCE_R_2", "DANCE_T_5", "DANCE_W_1"]  # cha-cha, rumba, tango, waltz


def _tang_motion(rng, T=20) -> Motion:
    """Random rotations on the tang2018 rig (28 joints: branch joints turned too)."""
    sk = get_skeleton("tang2018")
    R = axis_angle_to_matrix(torch.from_numpy(rng.normal(scale=0.4, size=(T, 28, 3)))).numpy()
    tr = np.cumsum(rng.normal(size=(T, 3)), axis=0) + [0, 95, 0]
    return Motion(sk, 25, rotations=R, root_translation=tr).with_positions()


# ---------------------------------------------------------------------- npz
def test_npz_round_trip(tmp_path, rng):
    m = _tang_motion(rng)
    path = tmp_path / "m.npz"
    write_motion(path, m)
    back = read_motion(path)
    assert back.fps == 25 and back.skeleton.same_as(m.skeleton)
    assert dict(back.skeleton.roles) == dict(m.skeleton.roles)
    assert back.positions.dtype == np.float32 and back.rotations.dtype == np.float32
    assert np.allclose(back.positions, m.positions, atol=1e-4)
    assert np.allclose(back.rotations, m.rotations, atol=1e-6)
    assert np.allclose(back.root_translation, m.root_translation, atol=1e-4)
    with np.load(path, allow_pickle=False) as z:
        assert list(z["joint_names"]) == list(m.skeleton.joint_names)
        assert z["parents"].tolist() == list(m.skeleton.parents)
        assert json.loads(str(z["skeleton"]))["name"] == "tang2018"
        assert json.loads(str(z["skeleton"]))["branch_joints"] == ["pelvis"]
        # rotations are on the rig, which the file spells out
        assert z["rotations"].shape == (20, 28, 3, 3) and int(z["version"]) == 2
        assert tuple(z["rig_joint_names"]) == m.skeleton.rig().joint_names
        assert z["rig_parents"].tolist() == list(m.skeleton.rig().parents)
        # FK on (rig_parents, skeleton offsets + zeros) without dancekit's Motion gives the positions
        from dancekit.motion.kinematics import forward_kinematics

        offsets = np.concatenate([np.asarray(json.loads(str(z["skeleton"]))["offsets"]), np.zeros((5, 3))])
        fk = forward_kinematics(torch.from_numpy(z["rotations"].astype(np.float64)),
                                torch.from_numpy(z["root_translation"].astype(np.float64)),
                                offsets=offsets, parents=z["rig_parents"].tolist())
        assert np.abs(fk.numpy()[:, :23] - z["positions"]).max() < 1e-3
    # positions-only motions (and 2D motions) too
    p2 = m.project_2d()
    write_motion(tmp_path / "p2.npz", p2)
    b2 = read_motion(tmp_path / "p2.npz")
    assert b2.rotations is None and b2.skeleton.dims == 2 and np.allclose(b2.positions, p2.positions)


# ----------------------------------------------------------------- tang2018
@pytest.mark.shared
def test_read_tang2018_known_answer(tang2018_dir):
    folder = tang2018_dir / "DANCE_C_2"
    m, audio = read_tang2018(folder)
    raw = json.loads((folder / "skeletons.json").read_text())
    cfg = json.loads((folder / "config.json").read_text())
    assert m.fps == 25 and m.num_frames == raw["length"] and m.skeleton.name == "tang2018"
    expected = np.asarray(raw["skeletons"][7]) + np.asarray(raw["center"][7])
    assert np.allclose(m.positions[7], expected, atol=1e-4)
    assert audio.path == folder / "audio.mp3"
    assert audio.start == cfg["start_position"] / 25
    assert math.isclose(audio.end, audio.start + m.num_frames / 25)
    path, start, end = audio
    assert start == audio.start
    assert detect_format(folder) == "tang2018" and read_motion(folder).num_frames == m.num_frames


# ---------------------------------------------------------------------- BVH
@pytest.mark.shared
@pytest.mark.parametrize("name", BVH_FIXTURES)
def test_bvh_fixture_reads_and_is_plausible(fixtures_dir, name):
    m = read_bvh(fixtures_dir / "bvh" / name)
    sk = m.skeleton
    assert m.num_frames > 100 and m.fps in (30.0, 120.0)
    assert m.rotations is not None and m.positions is not None
    for role in ("pelvis", "head", "left_ankle", "right_ankle", "left_toe", "right_toe", "left_wrist", "right_knee"):
        assert sk.has(role), role
    assert sk.up_axis == "y"
    up = sk.up_index
    p = m.positions
    head, hips = p[:, sk.index("head"), up], p[:, sk.index("pelvis"), up]
    assert np.mean(head > hips) > 0.95
    feet = np.minimum(p[:, sk.index("left_toe"), up], p[:, sk.index("right_toe"), up])
    height = np.median(head - feet)
    floor = p[..., up].min()
    # feet near the floor: the lower foot is within 10 % of the body height from the lowest point
    assert np.median(feet - floor) < 0.1 * height
    # FK of the rotations reproduces the positions (static root folded for Bandai-Namco)
    fk = Motion(sk, m.fps, rotations=m.rotations, root_translation=m.root_translation).to_positions()
    assert np.abs(fk - p).max() < 1e-3 * height


@pytest.mark.shared
@pytest.mark.parametrize("name", BVH_FIXTURES)
def test_bvh_raw_round_trip(fixtures_dir, tmp_path, name):
    data = parse_bvh(fixtures_dir / "bvh" / name)
    out = tmp_path / "rt.bvh"
    format_bvh(data, out)
    again = parse_bvh(out)
    assert again.names == data.names and again.parents == data.parents and again.channels == data.channels
    assert np.abs(again.values - data.values).max() <= 1e-6
    assert np.abs(again.offsets - data.offsets).max() <= 1e-6
    assert math.isclose(again.frame_time, data.frame_time, rel_tol=1e-6)


@pytest.mark.shared
@pytest.mark.parametrize("name", BVH_FIXTURES)
def test_bvh_motion_round_trip(fixtures_dir, tmp_path, name):
    m = read_bvh(fixtures_dir / "bvh" / name)
    out = tmp_path / "out.bvh"
    write_motion(out, m)
    back = read_motion(out)
    assert back.skeleton.joint_names == m.skeleton.joint_names
    assert back.fps == m.fps and back.num_frames == m.num_frames
    assert np.abs(back.rotations - m.rotations).max() < 1e-6
    assert np.abs(back.root_translation - m.root_translation).max() <= 1e-6
    assert np.allclose(back.skeleton.offsets, m.skeleton.offsets, atol=1e-6)


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YZX"])
def test_bvh_write_read_any_order(tmp_path, rng, order):
    m = _tang_motion(rng)
    out = tmp_path / "t.bvh"
    write_bvh(out, m, rotation_order=order)
    text = out.read_text()
    assert f"{order[0]}rotation {order[1]}rotation {order[2]}rotation" in text
    assert text.count("OFFSET 0.000000 0.000000 0.000000") == 6  # the root and 5 branch joints
    back = read_bvh(out)
    assert back.skeleton.branch_joints == ("pelvis",)
    names = list(m.skeleton.joint_names)
    perm = [names.index(n) for n in back.skeleton.joint_names]
    rig_names = list(m.skeleton.rig().joint_names)
    assert sorted(back.skeleton.rig().joint_names) == sorted(rig_names)
    rig_perm = [rig_names.index(n) for n in back.skeleton.rig().joint_names]
    assert np.abs(back.rotations - m.rotations[:, rig_perm]).max() < 1e-6
    assert np.abs(back.positions - m.positions[:, perm]).max() < 1e-4
    fk = Motion(back.skeleton, back.fps, rotations=back.rotations, root_translation=back.root_translation)
    assert np.abs(fk.to_positions() - back.positions).max() < 1e-4  # FK on the re-read rig
    assert back.skeleton.units == "cm" and back.skeleton.index("left_knee") == perm.index(17)


def test_bvh_from_positions_only_uses_ik(tmp_path, rng):
    m = _tang_motion(rng)
    pos_only = Motion(m.skeleton, m.fps, positions=m.positions)
    write_motion(tmp_path / "p.bvh", pos_only)
    back = read_motion(tmp_path / "p.bvh")
    perm = [list(m.skeleton.joint_names).index(n) for n in back.skeleton.joint_names]
    assert np.abs(back.positions - m.positions[:, perm]).max() < 1e-4  # rigid input: IK is exact


@pytest.mark.shared
def test_bvh_from_real_dance_positions_rereads_the_joints(tang2018_dir, tmp_path):
    """positions -> write_bvh -> read_bvh: the 23 joints equal the bone-length-normalised input (1e-3 cm)."""
    sk = get_skeleton("tang2018")
    for name in DANCES:
        motion, _ = read_tang2018(tang2018_dir / name)
        pos = motion.positions[:400].astype(np.float64)
        out = tmp_path / f"{name}.bvh"
        write_bvh(out, Motion(sk, motion.fps, positions=pos))
        data = parse_bvh(out)
        assert len(data.names) == 28 and "pelvis_to_left_hip" in data.names
        back = read_bvh(out)
        assert back.fps == 25 and back.num_frames == 400
        assert sorted(back.skeleton.joint_names) == sorted(sk.joint_names)
        assert back.skeleton.branch_joints == ("pelvis",) and back.rotations.shape == (400, 28, 3, 3)
        ref = normalize_bone_lengths(pos, sk)
        idx = [sk.index(n) for n in back.skeleton.joint_names]
        err = np.abs(back.positions - ref[:, idx]).max()
        assert err < 1e-3, (name, err)


def _branch_bvh(second_child: str) -> str:
    return f"""HIERARCHY
ROOT P
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT P_to_A
  {{
    OFFSET 0 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT A
    {{
      OFFSET 1 0 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {{
        OFFSET 1 0 0
      }}
    }}
  }}
  JOINT {second_child}
  {{
    OFFSET 0 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT B
    {{
      OFFSET -1 0 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {{
        OFFSET -1 0 0
      }}
    }}
  }}
}}
MOTION
Frames: 1
Frame Time: 0.04
0 0 0 0 0 0 90 0 0 0 0 0 0 0 0 0 0 0
"""


def test_bvh_branch_joints_known_answer(tmp_path):
    p = tmp_path / "branch.bvh"
    p.write_text(_branch_bvh("P_to_B"))
    m = read_bvh(p)
    assert m.skeleton.joint_names == ("P", "A", "B") and m.skeleton.parents == (-1, 0, 0)
    assert m.skeleton.branch_joints == ("P",) and m.skeleton.rig().joint_names == ("P", "A", "B", "P_to_A", "P_to_B")
    # P_to_A turns A by 90 degrees about z; B is unaffected
    assert np.allclose(m.positions[0], [[0, 0, 0], [0, 1, 0], [-1, 0, 0]], atol=1e-12)
    assert np.allclose(m.rotations[0, 3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    assert np.allclose(m.rotations[0, [0, 1, 2, 4]], np.eye(3), atol=1e-12)
    write_bvh(tmp_path / "again.bvh", m)
    assert parse_bvh(tmp_path / "again.bvh").names == ["P", "P_to_A", "A", "P_to_B", "B"]
    # a zero-offset joint that is not named as a branch joint stays an ordinary joint
    q = tmp_path / "plain.bvh"
    q.write_text(_branch_bvh("Spacer"))
    m2 = read_bvh(q)
    assert m2.skeleton.joint_names == ("P", "P_to_A", "A", "Spacer", "B") and m2.skeleton.branch_joints == ()
    assert np.allclose(m2.positions[0, [0, 2, 4]], m.positions[0], atol=1e-12)


def test_guess_roles_common_names():
    names = ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Neck", "mixamorig:Head",
             "mixamorig:LeftShoulder", "mixamorig:LeftArm", "mixamorig:LeftForeArm", "mixamorig:LeftHand",
             "mixamorig:RightUpLeg", "mixamorig:RightLeg", "mixamorig:RightFoot", "mixamorig:RightToeBase",
             "LHip", "lShldr", "Foot_L", "Toes_L"]
    roles, pairs = guess_roles(names)
    assert roles["pelvis"] == "mixamorig:Hips" and roles["head"] == "mixamorig:Head"
    assert roles["left_shoulder"] == "mixamorig:LeftArm"  # LeftShoulder is the clavicle
    assert roles["left_elbow"] == "mixamorig:LeftForeArm" and roles["left_wrist"] == "mixamorig:LeftHand"
    assert roles["right_hip"] == "mixamorig:RightUpLeg" and roles["right_knee"] == "mixamorig:RightLeg"
    assert roles["right_ankle"] == "mixamorig:RightFoot" and roles["right_toe"] == "mixamorig:RightToeBase"
    assert roles["left_hip"] == "LHip" and roles["left_ankle"] == "Foot_L" and roles["left_toe"] == "Toes_L"
    _, pairs = guess_roles(["Hips", "LeftArm", "RightArm", "Spine", "LeftUpLeg", "RightUpLeg", "LeftEye"])
    assert pairs == (("LeftArm", "RightArm"), ("LeftUpLeg", "RightUpLeg"))


# ------------------------------------------------------------------- AIST++
@pytest.mark.shared
def test_aistpp_fixture(fixtures_dir):
    path = fixtures_dir / "aistpp" / "sample_smpl.pkl"
    m = read_motion(path)
    assert m.num_frames == 127 and m.fps == 60 and m.skeleton.name == "smpl"
    with open(path, "rb") as f:
        raw = pickle.load(f)
    R0 = axis_angle_to_matrix(torch.from_numpy(np.asarray(raw["smpl_poses"][0, :3], np.float64))).numpy()
    assert np.allclose(m.rotations[0, 0], R0, atol=1e-12)
    sk = m.skeleton
    assert np.mean(m.positions[:, sk.index("head"), 1] > m.positions[:, sk.index("pelvis"), 1]) > 0.95
    assert read_aistpp(path, fps=30).fps == 30


def test_aistpp_scaling_and_bad_shapes(tmp_path):
    T = 5
    good = {"smpl_poses": np.zeros((T, 72)), "smpl_trans": np.tile([[0.0, 93.0, 0.0]], (T, 1)),
            "smpl_scaling": np.array([93.0])}
    p = tmp_path / "ok.pkl"
    p.write_bytes(pickle.dumps(good))
    m = read_aistpp(p)
    assert np.allclose(m.root_translation[:, 1], 1.0 - 0.24)
    bad = dict(good, smpl_poses=np.zeros((T, 70)))
    pb = tmp_path / "bad_shape.pkl"
    pb.write_bytes(pickle.dumps(bad))
    with pytest.raises(MotionFormatError, match="bad_shape.pkl"):
        read_motion(pb)
    nan = dict(good, smpl_trans=np.full((T, 3), np.nan))
    pn = tmp_path / "nan.pkl"
    pn.write_bytes(pickle.dumps(nan))
    with pytest.raises(MotionFormatError, match="nan.pkl"):
        read_motion(pn)


def test_aistpp_refuses_arbitrary_objects(tmp_path):
    p = tmp_path / "evil.pkl"
    p.write_bytes(pickle.dumps({"smpl_poses": shutil.rmtree}))
    with pytest.raises(MotionFormatError, match="evil.pkl"):
        read_aistpp(p)


# ----------------------------------------------------------------- OpenPose
def _write_frames(folder, frames):
    folder.mkdir(parents=True, exist_ok=True)
    for i, people in enumerate(frames):
        (folder / f"clip_{i:012d}_keypoints.json").write_text(json.dumps({"version": 1.3, "people": people}))


def _person(xy, conf):
    flat = np.concatenate([xy, conf[:, None]], axis=1).reshape(-1)
    return {"pose_keypoints_2d": flat.tolist()}


def test_openpose_interpolation_known_answer(tmp_path):
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 500, size=(4, 25, 2))
    conf = np.ones((4, 25))
    conf[1, 5] = 0.0   # missing keypoint in frame 1
    conf[2, 7] = 0.05  # below the default threshold 0.1
    frames = [[_person(xy[i], conf[i])] for i in range(4)]
    frames[3] = []     # nobody detected in the last frame: held from frame 2
    _write_frames(tmp_path / "op", frames)
    m = read_motion(tmp_path / "op", fps=30)
    assert m.skeleton.name == "body25" and m.fps == 30 and m.num_frames == 4
    assert np.allclose(m.positions[1, 5], 0.5 * (xy[0, 5] + xy[2, 5]), atol=1e-3)
    # frame 3 is empty too, so keypoint 7 is held from frame 1 (no valid frame after it)
    assert np.allclose(m.positions[2, 7], xy[1, 7], atol=1e-3)
    assert np.allclose(m.positions[3], m.positions[2], atol=1e-3)
    assert np.allclose(m.positions[0], xy[0], atol=1e-3)
    # with a lower threshold the low-confidence point is kept
    assert np.allclose(read_openpose(tmp_path / "op", confidence_threshold=0.01).positions[2, 7], xy[2, 7], atol=1e-3)


def test_interpolate_missing_middle_is_mean():
    pts = np.array([[[0.0, 0.0]], [[99.0, 99.0]], [[4.0, 8.0]]])
    valid = np.array([[True], [False], [True]])
    assert np.allclose(interpolate_missing(pts, valid)[1, 0], [2.0, 4.0])


def test_openpose_round_trip(tmp_path, rng):
    m = _tang_motion(rng).project_2d()
    write_openpose(tmp_path / "out", m)
    assert len(list((tmp_path / "out").glob("*.json"))) == m.num_frames
    back = read_openpose(tmp_path / "out", fps=m.fps)
    assert np.allclose(back.positions, m.positions, atol=1e-3)
    # a 3D motion is projected on the way out
    write_motion(tmp_path / "out3d", _tang_motion(rng))
    assert read_motion(tmp_path / "out3d").skeleton.name == "body25"


# --------------------------------------------------------- malformed input
def _tang_folder(tmp_path, skeletons, center=None, text=None):
    folder = tmp_path / "DANCE_W_99"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"start_position": 0, "end_position": 10}))
    T = len(skeletons)
    body = text if text is not None else json.dumps(
        {"length": T, "skeletons": skeletons, "center": center if center is not None else [[0, 0, 0]] * T}
    )
    (folder / "skeletons.json").write_text(body)
    return folder


def test_malformed_tang2018(tmp_path):
    good = np.zeros((3, 23, 3)).tolist()
    f = _tang_folder(tmp_path, good, text=json.dumps({"length": 3, "skeletons": good})[:-40])
    with pytest.raises(MotionFormatError, match="skeletons.json"):
        read_tang2018(f)
    shutil.rmtree(f)
    f = _tang_folder(tmp_path, np.zeros((3, 22, 3)).tolist())
    with pytest.raises(MotionFormatError, match=r"skeletons.json.*\(T, 23, 3\)"):
        read_tang2018(f)
    shutil.rmtree(f)
    nan = np.zeros((3, 23, 3))
    nan[1, 4, 2] = np.nan
    f = _tang_folder(tmp_path, nan.tolist())
    with pytest.raises(MotionFormatError, match="skeletons.json.*NaN"):
        read_tang2018(f)
    shutil.rmtree(f)
    f = _tang_folder(tmp_path, good, center=[[0, 0, 0]] * 2)
    with pytest.raises(MotionFormatError, match="skeletons.json.*center"):
        read_tang2018(f)
    (f / "config.json").unlink()
    with pytest.raises(MotionFormatError, match="config.json"):
        read_tang2018(f)
    with pytest.raises(MotionFormatError, match="DANCE_missing"):
        read_tang2018(tmp_path / "DANCE_missing")


def test_malformed_openpose(tmp_path):
    xy, conf = np.ones((25, 2)), np.ones(25)
    _write_frames(tmp_path / "trunc", [[_person(xy, conf)]])
    bad = tmp_path / "trunc" / "clip_000000000001_keypoints.json"
    bad.write_text('{"people": [{"pose_keypoints_2d": [1, 2')
    with pytest.raises(MotionFormatError, match="clip_000000000001_keypoints.json"):
        read_openpose(tmp_path / "trunc")
    _write_frames(tmp_path / "short", [[{"pose_keypoints_2d": [0.0] * 74}]])
    with pytest.raises(MotionFormatError, match=r"clip_000000000000_keypoints.json.*75"):
        read_openpose(tmp_path / "short")
    nanxy = xy.copy()
    nanxy[3, 0] = np.nan
    _write_frames(tmp_path / "nan", [[_person(nanxy, conf)]])
    with pytest.raises(MotionFormatError, match="clip_000000000000_keypoints.json.*NaN"):
        read_openpose(tmp_path / "nan")
    _write_frames(tmp_path / "nobody", [[], []])
    with pytest.raises(MotionFormatError, match="nobody"):
        read_openpose(tmp_path / "nobody")
    with pytest.raises(MotionFormatError, match="nowhere"):
        read_openpose(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(MotionFormatError, match="empty"):
        read_openpose(tmp_path / "empty")


def test_npz_rotations_must_fit_the_rig(tmp_path, rng):
    m = _tang_motion(rng)
    write_motion(tmp_path / "m.npz", m)
    with np.load(tmp_path / "m.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    # a version-1 file: rotations of the 23 joints (branch joints at the identity), no rig keys
    v1 = {k: v for k, v in arrays.items() if not k.startswith("rig_")}
    v1["rotations"] = v1["rotations"][:, :23]
    v1["version"] = np.int64(1)
    np.savez(tmp_path / "v1.npz", **v1)
    back = read_motion(tmp_path / "v1.npz")
    assert back.rotations.shape == (20, 28, 3, 3) and np.allclose(back.rotations[:, 23:], np.eye(3))
    # rig keys that disagree with the stored skeleton
    bad = dict(arrays, rig_joint_names=arrays["rig_joint_names"][::-1])
    np.savez(tmp_path / "badrig.npz", **bad)
    with pytest.raises(MotionFormatError, match="badrig.npz.*rig"):
        read_motion(tmp_path / "badrig.npz")
    wrong = dict(arrays, rotations=arrays["rotations"][:, :27])
    np.savez(tmp_path / "wrong.npz", **wrong)
    with pytest.raises(MotionFormatError, match=r"wrong.npz.*\(T, 28, 3, 3\)"):
        read_motion(tmp_path / "wrong.npz")


def test_malformed_npz(tmp_path):
    sk = get_skeleton("tang2018")
    good = {"fps": np.float64(25), "skeleton": np.asarray(json.dumps(sk.to_dict()))}
    np.savez(tmp_path / "shape.npz", positions=np.zeros((4, 22, 3), np.float32), **good)
    with pytest.raises(MotionFormatError, match=r"shape.npz.*\(T, 23, 3\)"):
        read_motion(tmp_path / "shape.npz")
    pos = np.zeros((4, 23, 3), np.float32)
    pos[2, 2, 2] = np.nan
    np.savez(tmp_path / "nan.npz", positions=pos, **good)
    with pytest.raises(MotionFormatError, match="nan.npz.*NaN"):
        read_motion(tmp_path / "nan.npz")
    np.savez(tmp_path / "nofps.npz", positions=np.zeros((4, 23, 3)))
    with pytest.raises(MotionFormatError, match="nofps.npz.*fps"):
        read_motion(tmp_path / "nofps.npz")
    (tmp_path / "trunc.npz").write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(MotionFormatError, match="trunc.npz"):
        read_motion(tmp_path / "trunc.npz")
    with pytest.raises(MotionFormatError, match="missing.npz"):
        read_motion(tmp_path / "missing.npz")


_MINI_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.04
0 90 0 0 0 0 10 0 0
1 90 0 0 0 0 20 0 0
"""


def test_bvh_mini_known_answer(tmp_path):
    p = tmp_path / "mini.bvh"
    p.write_text(_MINI_BVH)
    m = read_bvh(p)
    assert m.fps == 25 and m.num_frames == 2 and m.skeleton.joint_names == ("Hips", "Spine")
    assert np.allclose(m.root_translation[1], [1, 90, 0])
    assert np.allclose(m.positions[0, 1], [0, 100, 0])
    ang = math.radians(20)
    assert np.allclose(m.rotations[1, 1], [[math.cos(ang), -math.sin(ang), 0], [math.sin(ang), math.cos(ang), 0],
                                           [0, 0, 1]])


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda t: t.replace("    CHANNELS 3 Zrotation Xrotation Yrotation\n", ""), "Spine.*CHANNELS"),
        (lambda t: t.replace("1 90 0 0 0 0 20 0 0\n", "1 90 0 0\n"), "truncated"),
        (lambda t: t.replace("1 90 0 0 0 0 20 0 0", "1 nan 0 0 0 0 20 0 0"), "NaN"),
        (lambda t: t.replace("1 90 0 0 0 0 20 0 0", "1 abc 0 0 0 0 20 0 0"), "non-numeric"),
        (lambda t: t.replace("MOTION\n", ""), "MOTION"),
        (lambda t: t.replace("Zrotation Xrotation Yrotation\n  JOINT", "Zrotation Xrotation Wrotation\n  JOINT"),
         "Wrotation"),
        (lambda t: t.replace("    }\n  }\n}", "    }\n  }\n"), "hierarchy"),
        (lambda t: "nothing to see", "HIERARCHY"),
    ],
)
def test_malformed_bvh(tmp_path, edit, match):
    p = tmp_path / "broken.bvh"
    p.write_text(edit(_MINI_BVH))
    with pytest.raises(MotionFormatError, match=match) as info:
        read_motion(p)
    assert "broken.bvh" in str(info.value)


def test_missing_files_and_unknown_formats(tmp_path):
    for name in ("a.bvh", "a.pkl", "a.npz", "folder"):
        with pytest.raises(MotionFormatError, match=name):
            read_motion(tmp_path / name)
    with pytest.raises(MotionFormatError, match="a.bvh"):
        read_bvh(tmp_path / "a.bvh")
    with pytest.raises(MotionFormatError, match="a.pkl"):
        read_aistpp(tmp_path / "a.pkl")
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(MotionFormatError, match="x.txt"):
        read_motion(tmp_path / "x.txt")
    with pytest.raises(MotionFormatError, match="x.abc"):
        write_motion(tmp_path / "x.abc", _tang_motion(np.random.default_rng(0)))


# --------------------------------------------------------------- CLI: info
@pytest.mark.shared
def test_info_on_bvh(fixtures_dir, capsys):
    assert main(["info", str(fixtures_dir / "bvh" / "pymo_walk.bvh")]) == 0
    out = capsys.readouterr().out
    assert "bvh" in out and "1064 at 120 fps" in out and "23 joints" in out


def test_info_on_npz_and_audio_and_missing(tmp_path, rng, capsys):
    m = _tang_motion(rng, T=50)
    write_motion(tmp_path / "m.npz", m)
    assert main(["info", str(tmp_path / "m.npz")]) == 0
    out = capsys.readouterr().out
    assert "50 at 25 fps = 2.00 s" in out and "tang2018 (23 joints" in out and "rotations" in out
    assert main(["info", "--json", str(tmp_path / "m.npz")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames"] == 50 and info["joints"] == 23 and info["duration_s"] == 2.0
    import soundfile as sf

    sf.write(tmp_path / "tone.wav", np.zeros((22050, 2), np.float32), 22050)
    assert main(["info", str(tmp_path / "tone.wav")]) == 0
    out = capsys.readouterr().out
    assert "1.00 s" in out and "22050 Hz" in out and "2 channels" in out
    assert main(["info", str(tmp_path / "nope.bvh")]) == 2
    assert "nope.bvh" in capsys.readouterr().err
