"""Memory bounded by the chunk (issue 18, 60-minute songs): the motion steps that work piece by piece (the
BVH export's inverse kinematics and Euler angles, the smoothing stage's Savitzky-Golay filter and jitter
ratio) give the whole-song numbers. The chunk size is made small (97 frames: 13+ pieces on a 1,300-frame
dance, some pieces shorter than others) so that every piece boundary and the song's two ends are crossed."""

from __future__ import annotations

import numpy as np
import pytest

import dancekit.motion.filters as filters
import dancekit.motion.jitter as jitter
import dancekit.motion.motion as motion_mod
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats.bvh import write_bvh
from dancekit.motion.kinematics import inverse_kinematics
from dancekit.pipelines.base import DanceResult
from dancekit.pipelines.stages import smooth

SK = get_skeleton("tang2018")
FPS = 25.0
T = 1300
SMALL = 97


@pytest.fixture(scope="module")
def dance() -> np.ndarray:
    """(T, 23, 3) float32: the rest pose swinging and travelling, each joint wobbling, plus frame noise (a
    jittery dance, so that the smoothing stage filters it)."""
    rng = np.random.default_rng(3)
    rest = np.zeros((SK.num_joints, 3))
    for j in SK.topological_order:
        if SK.parents[j] >= 0:
            rest[j] = rest[SK.parents[j]] + SK.offsets[j]
    t = np.arange(T)[:, None, None] / FPS
    freq = rng.uniform(0.3, 2.0, size=(1, SK.num_joints, 3))
    wobble = 6.0 * np.sin(2 * np.pi * freq * t + rng.uniform(0, 6, size=freq.shape))
    travel = np.concatenate([30 * np.sin(0.2 * t), 0 * t, 20 * np.cos(0.13 * t)], axis=-1)
    p = rest[None] + wobble + travel + rng.normal(scale=1.5, size=(T, SK.num_joints, 3))
    return p.astype(np.float32)


def _old_jitter_ratio(p: np.ndarray) -> float:
    """The whole-song jitter ratio as it was computed before the pieces (one pass over float64 copies)."""
    from scipy.ndimage import uniform_filter1d

    p = np.asarray(p, np.float64)
    rel = p - p[:, SK.root: SK.root + 1]
    raw = np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean()
    sm = uniform_filter1d(rel, size=5, axis=0, mode="nearest")
    sm_speed = np.linalg.norm(np.diff(sm, axis=0), axis=-1).mean()
    return float((raw - sm_speed) / sm_speed)


def test_with_rotations_in_pieces_equals_one_pass(dance, monkeypatch):
    monkeypatch.setattr(motion_mod, "IK_CHUNK", SMALL)
    m = Motion(skeleton=SK, fps=FPS, positions=dance).with_rotations()
    rot, tr = inverse_kinematics(dance.astype(np.float64), SK)  # the whole song in one call
    assert m.rotations.dtype == np.float32 and m.rotations.shape == (T, SK.rig().num_joints, 3, 3)
    np.testing.assert_array_equal(m.rotations, rot.astype(np.float32))
    np.testing.assert_array_equal(m.root_translation, tr.astype(np.float32))


def test_bvh_in_pieces_is_the_same_file(dance, tmp_path, monkeypatch):
    m = Motion(skeleton=SK, fps=FPS, positions=dance)
    monkeypatch.setattr(motion_mod, "IK_CHUNK", 10**9)
    write_bvh(tmp_path / "whole.bvh", m)
    monkeypatch.setattr(motion_mod, "IK_CHUNK", SMALL)
    write_bvh(tmp_path / "pieces.bvh", m)
    whole = (tmp_path / "whole.bvh").read_text()
    assert whole.count("\n") > T
    assert (tmp_path / "pieces.bvh").read_text() == whole


@pytest.mark.parametrize("window", [5, 7, 13, 21])
def test_savgol_rows_equal_the_whole_filter(dance, window):
    whole = filters.savgol(dance.astype(np.float64), window, 3)
    pieces = [filters.savgol_rows(dance, window, 3, a, b) for a, b in filters.chunks(T, SMALL)]
    np.testing.assert_array_equal(np.concatenate(pieces), whole)


def test_chunks_cover_the_range_once():
    for n, size in ((1, 97), (96, 97), (97, 97), (98, 97), (1300, 97), (90_000, 4096)):
        cut = filters.chunks(n, size)
        assert cut[0][0] == 0 and cut[-1][1] == n
        assert all(b0 == a1 for (_, b0), (a1, _) in zip(cut[:-1], cut[1:]))
        assert all(size // 2 <= b - a <= size for a, b in cut) or len(cut) == 1


@pytest.mark.parametrize("window", [None, 7, 15])
def test_jitter_ratio_in_pieces_equals_one_pass(dance, monkeypatch, window):
    monkeypatch.setattr(filters, "CHUNK", SMALL)
    x = dance if window is None else filters.savgol(dance.astype(np.float64), window, 3)
    got = jitter.jitter_ratio(dance, SK, FPS, window=window)
    assert got > 0.05
    assert got == pytest.approx(_old_jitter_ratio(x), rel=1e-12, abs=0)


def test_smoothing_stage_in_pieces_equals_one_pass(dance, monkeypatch):
    result = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=dance), model="m", seed=0)
    monkeypatch.setattr(filters, "CHUNK", 10**9)
    whole = smooth(result)
    monkeypatch.setattr(filters, "CHUNK", SMALL)
    pieces = smooth(result)
    assert whole.notes == pieces.notes and whole.notes[-1].startswith("smoothed (")
    assert pieces.motion.positions.dtype == np.float32
    np.testing.assert_array_equal(pieces.motion.positions, whole.motion.positions)
    assert not np.array_equal(pieces.motion.positions, dance)  # it did filter


def test_html_quantised_positions_in_pieces_equal_one_pass(dance, monkeypatch):
    import dancekit.render.html as html

    monkeypatch.setattr(html, "_CHUNK", SMALL)
    got, offset, scale = html._quantise(dance)
    lo = dance.reshape(-1, 3).min(axis=0).astype(np.float64)  # the one-pass formula
    step = np.maximum(dance.reshape(-1, 3).max(axis=0) - lo, 1e-6) / 65535.0
    ref = np.clip(np.rint((dance - lo) / step), 0, 65535).astype("<u2")
    assert got == ref.tobytes() and offset == lo.tolist() and scale == step.tolist()


@pytest.mark.parametrize("up_axis", ["y", "z"])
def test_scene_positions_in_pieces_equal_one_pass(up_axis):
    from dancekit.render._scene import _TO_Y_UP, prepare_scene

    rng = np.random.default_rng(5)
    pos = (rng.normal(size=(9000, 4, 3)) * 40 + 100).astype(np.float32)  # 9,000 frames: three 4,096-frame pieces
    scene = prepare_scene(pos, parents=[-1, 0, 1, 1], fps=FPS, up_axis=up_axis, unit_scale=0.01, follow_ground=False)
    ref = (pos.astype(np.float64) * 0.01) @ _TO_Y_UP[up_axis].T
    ref[:, :, 1] -= np.percentile(ref[:, :, 1].min(axis=1), 5)
    np.testing.assert_array_equal(scene.positions, ref.astype(np.float32))


def test_render_arrays_in_pieces_equal_one_pass(dance, monkeypatch):
    import dancekit.render._motion as rm

    m = Motion(skeleton=SK, fps=FPS, positions=dance)
    monkeypatch.setattr(rm, "_CHUNK", 10**9)
    whole = rm.motion_arrays(m)
    monkeypatch.setattr(rm, "_CHUNK", SMALL)
    pieces = rm.motion_arrays(m)
    assert pieces.keys() == whole.keys() and pieces["positions"].shape == whole["positions"].shape
    for key, value in whole.items():
        np.testing.assert_array_equal(pieces[key], value)


def test_camera_distance_in_pieces_equals_one_pass():
    from dancekit.render._scene import camera_basis, fit_distance, prepare_scene

    rng = np.random.default_rng(6)
    pos = (rng.normal(size=(9000, 4, 3)) * 40 + 100).astype(np.float32)
    pos[7000, 2] += 900  # the farthest joint in the last piece
    scene = prepare_scene(pos, parents=[-1, 0, 1, 1], fps=FPS, up_axis="y", unit_scale=0.01)
    basis = right, up, fwd = camera_basis(0.4, 0.2)
    rel = scene.positions - scene.target[:, None, :]
    need = np.maximum(np.abs(rel @ right) / (0.88 * 0.5), np.abs(rel @ up) / (0.88 * 0.3)) - rel @ fwd
    assert fit_distance(scene, basis, tan_half_x=0.5, tan_half_y=0.3) == max(float(need.max()), 0.5 * scene.height)
