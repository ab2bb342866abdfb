"""Editing a finished dance (dancekit.motion.edit and the "edit" stage): known answers on synthetic dances."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dancekit.errors import ParameterError
from dancekit.motion import get_skeleton
from dancekit.motion import edit

SK = get_skeleton("tang2018")  # centimetres, y up
FPS = 25.0


def _dance(T: int = 200, seed: int = 0) -> np.ndarray:
    """A smooth synthetic dance (T, 23, 3) cm: the rest pose swaying, walking slowly along x."""
    rng = np.random.default_rng(seed)
    rest = np.asarray(SK.rest_positions() if hasattr(SK, "rest_positions") else np.cumsum(SK.offsets, 0), float)
    t = np.arange(T)[:, None, None] / FPS
    amp = rng.uniform(1, 5, (1, SK.num_joints, 3))
    ph = rng.uniform(0, 6, (1, SK.num_joints, 3))
    p = rest[None] + amp * np.sin(2 * math.pi * 1.3 * t + ph)
    p[..., 0] += 20.0 * t[..., 0]
    p[..., 1] += 100.0
    return p


def _write(tmp_path, name, obj):
    f = tmp_path / name
    f.write_text(json.dumps(obj))
    return f


def test_keys_exact_smooth_and_local(tmp_path):
    p = _dance()
    wrist = SK.joint_names.index("left_wrist")
    k1 = (p[50, wrist] + [10.0, -5.0, 8.0]).tolist()
    k2 = (p[70, wrist] + [-6.0, 9.0, 0.0]).tolist()  # 0.8 s apart: the two bumps overlap
    f = _write(tmp_path, "keys.json", [{"time": 2.0, "pose": {"left_wrist": k1}},
                                       {"frame": 70, "pose": {"left_wrist": k2}}])
    keys = edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    out = edit.apply_keyframes(p, keys=keys, fps=FPS)
    np.testing.assert_allclose(out[50, wrist], k1, atol=1e-9)
    np.testing.assert_allclose(out[70, wrist], k2, atol=1e-9)
    corr = out - p
    # untouched: other joints everywhere, the wrist farther than 1 s (25 frames) from both keys
    others = [j for j in range(SK.num_joints) if j != wrist]
    assert np.array_equal(out[:, others], p[:, others])
    assert np.array_equal(out[:25, wrist], p[:25, wrist]) and np.array_equal(out[96:, wrist], p[96:, wrist])
    # smooth: the correction's second difference stays small (a C2 bump of half-width 25 frames: bound by hand,
    # |w| * max|phi''| / 25^2 with phi'' <= 20 at the centre; the weights are below 3 * the residual here)
    d2 = np.abs(np.diff(corr[:, wrist], 2, axis=0)).max()
    assert d2 < 3 * 13.0 * 20 / 25**2
    assert np.abs(corr[:, wrist]).max() > 5  # the correction did something


def test_wendland_bump_known_values():
    np.testing.assert_allclose(edit.wendland(np.array([0.0, 0.5, 1.0, 2.0])), [1.0, 0.0625 * 3.0, 0.0, 0.0])


def test_keys_refused(tmp_path):
    p = _dance()
    w = p[10, 0].tolist()
    far = (p[10, 0] + [300.0, 0, 0]).tolist()  # 3 m in 0.2 s: 15 m/s
    f = _write(tmp_path, "fast.json", [{"frame": 10, "pose": {"head_right": w}},
                                       {"frame": 15, "pose": {"head_right": far}}])
    with pytest.raises(ParameterError, match="fast.json.*m/s"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    f = _write(tmp_path, "late.json", [{"time": 9.0, "pose": {"head_right": w}}])
    with pytest.raises(ParameterError, match="late.json.*outside the dance"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    f = _write(tmp_path, "name.json", [{"time": 1.0, "pose": {"nose": w}}])
    with pytest.raises(ParameterError, match="name.json.*nose"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))


def test_path_followed_sway_kept(tmp_path):
    p = _dance(T=250)
    f = _write(tmp_path, "path.json", {"points": [[0, 0], [2, 0], [2, 2]]})
    pts, times = edit.read_path(f)
    out = edit.follow_path(p, skeleton=SK, fps=FPS, points=pts, times=times)
    target = edit.path_positions(pts, times, num_frames=len(p), fps=FPS)
    root = out[:, SK.root][:, [0, 2]] * SK.unit_scale
    rms = float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1))))
    assert rms < 0.10
    # a rigid horizontal shift per frame: heights and the pose relative to the root unchanged
    np.testing.assert_allclose(out[..., 1], p[..., 1], atol=1e-9)
    np.testing.assert_allclose(out - out[:, SK.root:SK.root + 1], p - p[:, SK.root:SK.root + 1], atol=1e-9)
    # the constant-speed walk: 4 m over 9.96 s, the corner at the middle
    np.testing.assert_allclose(target[len(p) // 2 - 1], [2.0, 0.0], atol=0.02)


def test_path_refused(tmp_path):
    f = _write(tmp_path, "far.json", {"points": [[0, 0], [5, 0]]})
    with pytest.raises(ParameterError, match="far.json.*dance floor"):
        edit.read_path(f)
    f = _write(tmp_path, "times.json", {"points": [[0, 0], [1, 0]], "times": [1.0, 0.5]})
    with pytest.raises(ParameterError, match="times.json"):
        edit.read_path(f)


def test_keep_upper_equals_take():
    p, take = _dance(seed=0), _dance(seed=1) + [50.0, 3.0, -20.0]
    joints = edit.body_part_joints(SK, "upper")
    assert SK.root not in joints and SK.joint_names.index("left_knee") not in joints
    assert SK.joint_names.index("left_wrist") in joints
    out = edit.keep_joints(p, take, skeleton=SK, joints=joints)
    r = SK.root
    np.testing.assert_allclose(out[:, joints] - out[:, r:r + 1], take[:, joints] - take[:, r:r + 1], atol=1e-3)
    rest = [j for j in range(SK.num_joints) if j not in joints]
    assert np.array_equal(out[:, rest], p[:, rest])
    with pytest.raises(ParameterError, match="nose"):
        edit.body_part_joints(SK, "left_wrist,nose")


def test_prefix_kept_and_seam_continuous():
    p, pre = _dance(T=200, seed=0), _dance(T=60, seed=2) + [30.0, 0.0, 40.0]
    out = edit.continue_from(pre, p, skeleton=SK, fps=FPS)
    np.testing.assert_allclose(out[:60], pre, atol=1e-4)
    # no jump at the seam: the step at the seam no larger than the largest step of the two dances around it
    step = np.linalg.norm(out[60] - out[59], axis=-1).max()
    assert step <= 1.5 * max(np.linalg.norm(np.diff(pre, axis=0), axis=-1).max(),
                             np.linalg.norm(np.diff(p, axis=0), axis=-1).max())
    # after the fade: the dance's own motion, moved rigidly (pairwise joint distances equal)
    a, b = out[150], p[150]
    np.testing.assert_allclose(np.linalg.norm(a[:, None] - a[None], axis=-1),
                               np.linalg.norm(b[:, None] - b[None], axis=-1), atol=1e-6)
    with pytest.raises(ParameterError, match="shorter"):
        edit.continue_from(p, pre, skeleton=SK, fps=FPS)
