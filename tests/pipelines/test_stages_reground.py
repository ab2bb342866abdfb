"""The second grounding after the foot lock (stages.reground, a checkpoint's "stages": {"reground": ...} entry)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import dancekit.pipelines.stages as stages
from dancekit.errors import CheckpointError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.analysis import rest_pose
from dancekit.pipelines.base import DanceResult
from dancekit.pipelines.config import JitterCapConfig, RegroundConfig, read_stage_config

FPS = 25.0
SK = get_skeleton("tang2018")
ASSETS = Path(stages.__file__).resolve().parent.parent / "assets" / "models"


def _standing(T: int = 100) -> np.ndarray:
    """A still rest pose with its lowest joint at height 0 (cm, y up), ``(T, J, 3)``."""
    rest = rest_pose(SK)
    rest[:, 1] -= rest[:, 1].min()
    return np.repeat(rest[None], T, axis=0)


def test_a_lift_longer_than_half_the_window_is_taken_down_and_a_short_one_stays():
    p = _standing()
    p[20:60, :, 1] += 5.0  # the whole figure 5 cm up for 1.6 s (a float)
    p[80:82, :, 1] += 3.0  # 0.08 s up (a hop): shorter than half of a 0.6-s window
    out = stages.reground(DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=None, seed=0),
                          window_s=0.6).motion.positions
    low = out[:, :, 1].min(axis=1)
    # by hand: a 15-frame running minimum (0.6 s) is 5 cm for frames 27-52 (7 frames inside the float's ends),
    # then Gaussian-smoothed (sigma 0.05 s = 1.25 frames), which blurs its steps over ~4 frames: frames 31-48
    # are put back down by the whole 5 cm; the hop is inside windows that reach the floor on both sides
    np.testing.assert_allclose(low[31:49], 0.0, atol=1e-3)
    assert 0.5 < low[27] < 4.5  # the blurred edge: part of the way down
    assert low[81] == pytest.approx(3.0, abs=0.05)
    np.testing.assert_allclose(low[:15], 0.0, atol=1e-6)  # already on the floor: unchanged
    # a vertical shift only: the pose within each frame and the horizontal path are those of the input
    np.testing.assert_allclose(out[..., [0, 2]], p[..., [0, 2]], atol=1e-5)
    np.testing.assert_allclose(out - out[:, :1], p - p[:, :1], atol=1e-4)


def _with_reground(folder: Path, entry) -> str:
    """The embedded default's config.json with ``"stages": {"reground": entry}`` (None: without one) in ``folder``."""
    folder.mkdir(exist_ok=True)
    cfg = json.loads((ASSETS / "revolution" / "config.json").read_text())
    cfg["stages"] = {k: v for k, v in cfg["stages"].items() if k != "reground"}
    if entry is not None:
        cfg["stages"]["reground"] = entry
    (folder / "config.json").write_text(json.dumps(cfg))
    return str(folder)


def test_the_reground_settings_come_from_the_checkpoint(tmp_path):
    assert read_stage_config(ASSETS / "revolution").reground == RegroundConfig(window_s=1.0)  # the default asks
    assert read_stage_config(ASSETS / "music2dance").reground is None
    assert read_stage_config(ASSETS / "dual").reground is None
    folder = tmp_path / "m"
    assert read_stage_config(_with_reground(folder, {"window_s": 0.6})).reground.reground_options() == {"window_s": 0.6}
    assert read_stage_config(_with_reground(folder, None)).reground is None
    assert "reground" not in read_stage_config(_with_reground(folder, None)).order()
    for bad in ({"window_s": 0}, {"window_s": "0.6"}, {"window": 0.6}):
        with pytest.raises(CheckpointError, match=f"{folder}: config.json: .*stages.reground.{next(iter(bad))}"):
            read_stage_config(_with_reground(folder, bad))


def test_finish_regrounds_last_in_the_lock_block_for_the_model_that_asks(tmp_path, monkeypatch):
    p = np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")["none_seed3"]
    folder = _with_reground(tmp_path / "m", {"window_s": 0.6})
    order = []
    for name in ("foot_lock", "settle", "reground"):
        real = getattr(stages, name)
        monkeypatch.setattr(stages, name, lambda r, *a, _real=real, _n=name, **kw: order.append(_n) or _real(r, *a, **kw))
    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=str(folder), seed=0)
    out = stages.finish(res, "unused.wav", read_stage_config(folder).switched(beat_sync=False))
    assert order == ["foot_lock", "settle", "reground"]
    order.clear()
    without = _with_reground(tmp_path / "without", None)
    plain = stages.finish(DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=without, seed=0),
                          "unused.wav", read_stage_config(without).switched(beat_sync=False))
    assert "reground" not in order
    # the grounded dance touches the floor in every 0.6-s window; the lowest joint is never under it
    low = out.motion.positions[..., 1].min(axis=1)
    assert low.min() >= -1e-3
    windows = np.lib.stride_tricks.sliding_window_view(low, 15).min(axis=1)
    assert np.all(windows < 0.5)  # cm (the offset's Gaussian smoothing leaves up to a few mm)
    before = np.lib.stride_tricks.sliding_window_view(plain.motion.positions[..., 1].min(axis=1), 15).min(axis=1)
    # without it the lock (its IK lowers the body) and the low-pass leave it under the floor or off it
    assert before.min() < -0.1 and before.max() > 0.5
    assert not np.array_equal(out.motion.positions, plain.motion.positions)


def test_a_motion_with_rotations_keeps_them_and_its_root_translation_follows():
    p = _standing(60)
    p[10:50, :, 1] += 4.0  # a 1.6-s float
    m = Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32)).with_rotations()
    out = stages.reground(DanceResult(motion=m, model=None, seed=0), window_s=0.6).motion
    np.testing.assert_array_equal(out.rotations, m.rotations)
    # forward kinematics of the kept rotations from the moved root translation gives the grounded positions
    fk = Motion(skeleton=SK, fps=FPS, rotations=out.rotations, root_translation=out.root_translation).to_positions()
    np.testing.assert_allclose(fk, out.positions, atol=1e-3)
    # the float is taken down where the 15-frame minimum is 4 cm (frames 17-42) beyond the Gaussian's reach
    assert out.positions[22:38, :, 1].min(axis=1).max() < 1e-3


def test_finish_traces_every_stage_it_runs_in_order_and_each_traced_dance_is_that_stage_applied():
    p = np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")["none_seed3"]
    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=str(ASSETS / "revolution"), seed=0)
    import dataclasses

    default = read_stage_config(ASSETS / "revolution")
    config = dataclasses.replace(default, jitter_cap=JitterCapConfig(max_jitter=1e-9)).switched(beat_sync=False)
    seen = []
    out = stages.finish(res, "unused.wav", config, trace=lambda name, r: seen.append((name, r)))
    assert seen[0] == ("input", res)
    names = [n for n, _ in seen[1:]]
    seen = seen[1:]
    assert names == ["clean_up", "smooth", "lift_energy", "jitter_cap", "foot_lock", "settle", "reground"]
    assert names == [n for n in stages.STAGE_NAMES if n != "beat_sync"]  # the default has a "ground" entry
    assert seen[-1][1] is out
    before, locked = seen[names.index("foot_lock") - 1][1], seen[names.index("foot_lock")][1]
    assert np.array_equal(locked.motion.positions,
                          stages.foot_lock(before, default.foot_lock, default.genre_stats).motion.positions)
    capped = seen[names.index("jitter_cap")][1]
    assert capped.notes[-1].startswith("calmed to the song's genres")
    plain = stages.finish(res, "unused.wav", config)
    assert np.array_equal(plain.motion.positions, out.motion.positions)  # the trace changes nothing
    after = []
    late = dataclasses.replace(config, jitter_cap=JitterCapConfig(max_jitter=1e-9, after_lock=True))
    stages.finish(res, "unused.wav", late, trace=lambda name, r: after.append(name))
    assert after == ["input", "clean_up", "smooth", "lift_energy", "foot_lock", "settle", "jitter_cap", "reground"]
    none = []
    stages.finish(res, "unused.wav", default.switched(beat_sync=False, cleanup=False),
                  trace=lambda name, r: none.append(name))
    assert none == ["input"]


def _touching_every(period: int, lift_cm: float, T: int = 240) -> np.ndarray:
    """The standing figure ``lift_cm`` up except at every ``period``-th frame, where it touches the floor."""
    p = _standing(T)
    lift = np.full(T, lift_cm)
    lift[::period] = 0.0
    p[:, :, 1] += lift[:, None]
    return p


def test_floor_float_is_the_median_height_over_the_lowest_point_within_one_second():
    from scipy.ndimage import minimum_filter1d

    from dancekit.motion.floor import floor_float_cm, floor_gap_cm

    # touching every 24 frames (< 1 s): every ±1 s window holds a touch, so the float is the lift itself
    assert floor_float_cm(_touching_every(24, 4.0), skeleton=SK, fps=FPS) == pytest.approx(4.0, abs=1e-6)
    # a random lowest-joint path, against SciPy's running minimum (51 frames = ±1 s at 25 fps, ends held)
    rng = np.random.default_rng(0)
    p = _standing(300)
    low = np.cumsum(rng.normal(0.0, 0.4, 300))  # cm
    p[:, :, 1] += low[:, None] - low.min()
    low = p[:, :, 1].min(axis=1)
    want = np.median(low - minimum_filter1d(low, 51, mode="nearest"))
    assert floor_float_cm(p, skeleton=SK, fps=FPS) == pytest.approx(want, abs=1e-5)
    above = floor_gap_cm(p, skeleton=SK, fps=FPS)  # the per-frame gap behind it, also for the within-2-cm share
    np.testing.assert_allclose(above, low - minimum_filter1d(low, 51, mode="nearest"), atol=1e-5)


def test_reground_tries_shorter_windows_only_while_the_dance_floats_over_the_bound():
    from dancekit.motion.floor import floor_float_cm

    def result(p):
        return DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32)), model=None, seed=0)

    floating = result(_touching_every(24, 4.0))
    # by hand: a 1-s window (25 frames) always holds a touch, so nothing moves and the float stays 4 cm; a
    # 0.6-s window (15 frames, ±7) takes down only the 9 frames 8-12 away from a touch (blurred by the 1.25-frame
    # Gaussian), so 12 of the 24 frames of a period stay 4 cm up and 2 more about 2.7 cm: the median is over 2;
    # a 0.4-s window (11 frames, ±5) leaves 10 of 24 up: the median is down near the floor
    plain = stages.reground(floating, window_s=1.0).motion.positions
    assert floor_float_cm(plain, skeleton=SK, fps=FPS) == pytest.approx(4.0, abs=1e-4)
    bounded = stages.reground(floating, window_s=1.0, max_float_cm=2.0).motion.positions
    assert floor_float_cm(stages.reground(floating, window_s=0.6).motion.positions, skeleton=SK, fps=FPS) > 2.0
    np.testing.assert_array_equal(bounded, stages.reground(floating, window_s=0.4).motion.positions)
    assert floor_float_cm(bounded, skeleton=SK, fps=FPS) <= 2.0
    # a dance that floats less than the bound keeps the checkpoint's window, bit for bit
    low = result(_touching_every(24, 1.5))
    np.testing.assert_array_equal(stages.reground(low, window_s=1.0, max_float_cm=2.0).motion.positions,
                                  stages.reground(low, window_s=1.0).motion.positions)
    # no window reaches the bound (0.25 s, ±3 frames, still leaves the blurred edges next to each touch up):
    # the shortest is kept
    np.testing.assert_array_equal(stages.reground(floating, window_s=1.0, max_float_cm=0.001).motion.positions,
                                  stages.reground(floating, window_s=0.25).motion.positions)


def test_the_reground_settings_read_the_float_bound(tmp_path):
    folder = tmp_path / "m"
    assert read_stage_config(_with_reground(folder, {"window_s": 1.0, "max_float_cm": 2})).reground.reground_options() == {"window_s": 1.0, "max_float_cm": 2.0}
    for bad in ({"window_s": 1.0, "max_float_cm": 0}, {"window_s": 1.0, "max_float_cm": "2"}):
        with pytest.raises(CheckpointError, match="stages.reground.max_float_cm"):
            read_stage_config(_with_reground(folder, bad))
