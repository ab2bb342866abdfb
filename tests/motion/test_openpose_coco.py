"""COCO-17 / COCO-18 keypoints beside BODY_25; invented points flagged by a low confidence."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dancekit.errors import MotionFormatError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import read_motion, write_motion
from dancekit.motion.formats.openpose import (
    COCO17_NAMES,
    COCO18_NAMES,
    INVENTED_CONFIDENCE,
    keypoint_confidence,
)


def rest_dance(frames: int = 4) -> Motion:
    sk = get_skeleton("tang2018")
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    pos = np.repeat(rest[None], frames, axis=0)
    pos[:, :, 0] += np.arange(frames)[:, None]
    return Motion(sk, 25.0, positions=pos.astype(np.float32))


def _frame(folder, i=0) -> tuple[dict, np.ndarray]:
    files = sorted(folder.glob("*_keypoints.json"))
    obj = json.loads(files[i].read_text())
    return obj, np.asarray(obj["people"][0]["pose_keypoints_2d"]).reshape(-1, 3)


@pytest.mark.parametrize("layout, names", [("coco17", COCO17_NAMES), ("coco18", COCO18_NAMES)])
def test_coco_layouts_pick_the_body25_points(tmp_path, layout, names):
    m = rest_dance()
    write_motion(tmp_path / "b25", m)
    write_motion(tmp_path / layout, m, keypoints=layout)
    b25 = get_skeleton("body25")
    obj, kp = _frame(tmp_path / layout, 2)
    _, ref = _frame(tmp_path / "b25", 2)
    assert obj["keypoint_format"] == layout and kp.shape == (len(names), 3)
    assert np.allclose(kp, ref[[b25.index(n) for n in names]])
    assert len(list((tmp_path / layout).glob("*.json"))) == m.num_frames
    # COCO-17 is in MMPose order
    if layout == "coco17":
        assert names[5] == "LShoulder" and names[16] == "RAnkle"


def test_invented_points_are_flagged(tmp_path):
    m = rest_dance()
    write_motion(tmp_path / "b25", m)
    _, kp = _frame(tmp_path / "b25")
    b25 = get_skeleton("body25")
    c = dict(zip(b25.joint_names, kp[:, 2]))
    for joint in ("LShoulder", "RElbow", "LWrist", "RHip", "LKnee", "RAnkle", "LBigToe", "LHeel"):
        assert c[joint] == 1.0, joint  # tang2018 has heel markers
    for invented in ("LEye", "REye", "LEar", "REar", "LSmallToe", "RSmallToe"):
        assert c[invented] == INVENTED_CONFIDENCE, invented
    assert 0 < c["Neck"] < 1 and 0 < c["MidHip"] < 1 and 0 < c["Nose"] < 1  # derived: no such joint
    smpl = keypoint_confidence(get_skeleton("smpl"))
    assert smpl[b25.index("Neck")] == 1.0 and smpl[b25.index("LHeel")] == INVENTED_CONFIDENCE
    # the default reader threshold still reads every point back
    back = read_motion(tmp_path / "b25")
    assert back.num_frames == m.num_frames and np.isfinite(back.positions).all()


def test_unknown_layout(tmp_path):
    with pytest.raises(MotionFormatError, match="keypoints"):
        write_motion(tmp_path / "x", rest_dance(), keypoints="coco19")
