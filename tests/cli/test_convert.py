"""`dancekit convert` and `render --fps`: every output format from any motion file the toolkit reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dancekit.cli.main import main
from dancekit.motion.formats import read_motion
from dancekit.motion.formats.bvh import parse_bvh


@pytest.fixture
def walk(fixtures_dir):
    return fixtures_dir / "bvh" / "pymo_walk.bvh"


def test_convert_to_every_format(tmp_path, walk):
    src = read_motion(walk)
    for name in ("w.npz", "w.bvh", "w.glb", "w.pkl", "w"):
        assert main(["convert", str(walk), "-o", str(tmp_path / name), "-q"]) == 0, name
    assert np.allclose(read_motion(tmp_path / "w.npz").positions, src.positions, atol=1e-3)
    assert np.allclose(read_motion(tmp_path / "w.bvh").positions, src.positions, atol=1e-3)
    assert read_motion(tmp_path / "w.pkl").skeleton.name == "smpl"
    frames = sorted((tmp_path / "w").glob("*_keypoints.json"))
    assert len(frames) == src.num_frames


def test_convert_options(tmp_path, walk):
    src = read_motion(walk)
    assert main(["convert", str(walk), "-o", str(tmp_path / "h.bvh"), "--bvh-rig", "humanoid", "-q"]) == 0
    names = parse_bvh(tmp_path / "h.bvh").names
    assert names[0] == "Hips" and {"Spine", "Spine1", "Neck", "Head", "LeftArm"} <= set(names)
    assert main(["convert", str(walk), "-o", str(tmp_path / "c"), "--keypoints", "coco18", "-q"]) == 0
    obj = json.loads(sorted((tmp_path / "c").glob("*.json"))[0].read_text())
    assert obj["keypoint_format"] == "coco18" and len(obj["people"][0]["pose_keypoints_2d"]) == 54
    assert main(["convert", str(walk), "-o", str(tmp_path / "f.npz"), "--fps", "10", "-q"]) == 0
    m = read_motion(tmp_path / "f.npz")
    assert m.fps == 10 and m.num_frames == int((src.num_frames - 1) * 10 / src.fps) + 1


def test_render_fps(tmp_path, walk, capsys):
    src = read_motion(walk)
    assert main(["render", str(walk), "-o", str(tmp_path / "w.html"), "--fps", "12", "-q"]) == 0
    assert (tmp_path / "w.html").stat().st_size > 0
    assert main(["render", str(walk), "-o", str(tmp_path / "x.html"), "--fps", "0"]) == 2
    assert "--fps" in capsys.readouterr().err
    assert src.fps != 12
