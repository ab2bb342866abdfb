"""The planted-foot share, the lock held to a genre's share (issue 15 round 30) and checkpoint averaging.

Known answers are built independently of the code: a figure made by forward kinematics whose root stands
still and then slides at a chosen speed (central differences of a known ramp), a figure gliding faster or
slower than scaled contact speeds, weighted means of a few numbers worked out by hand, and the element-wise
mean of two small models' weights computed from their state dicts.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from dancekit.errors import CheckpointError, ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.floor import planted_share
from dancekit.motion.footlock import lock_feet, lock_feet_to_share
from dancekit.motion.kinematics import rig_forward_kinematics
from dancekit.motion.rotations import axis_angle_to_matrix

FPS = 25.0
SK = get_skeleton("tang2018")  # centimetres


def _figure(root_z_cm: np.ndarray) -> np.ndarray:
    """Knees bent 40°, hips flexed 20°, both feet on the floor; the root at ``root_z_cm`` (T,) along z."""
    T = len(root_z_cm)
    rot = np.tile(np.eye(3), (T, SK.rig().num_joints, 1, 1))
    for side in ("left", "right"):
        rot[:, SK.index(f"{side}_hip")] = axis_angle_to_matrix(torch.tensor([-0.35, 0.0, 0.0])).numpy()
        rot[:, SK.index(f"{side}_knee")] = axis_angle_to_matrix(torch.tensor([0.7, 0.0, 0.0])).numpy()
    root = np.zeros((T, 3))
    root[:, 2] = root_z_cm
    p = rig_forward_kinematics(torch.from_numpy(rot), torch.from_numpy(root), SK).numpy()
    p[..., 1] -= p[0, :, 1].min()
    return p


def test_planted_share_of_a_figure_that_stands_then_slides():
    """60 frames: still for frames 0-29, then 1 cm a frame (0.25 m/s at 25 fps). Central differences give
    frame 29 half a step (0.125 m/s, under 0.15: planted) and frame 30 on a full one: 30 of 60 planted."""
    z = np.maximum(np.arange(60) - 29, 0).astype(float)
    assert planted_share(_figure(z), skeleton=SK, fps=FPS) == pytest.approx(0.5)
    assert planted_share(_figure(np.zeros(40)), skeleton=SK, fps=FPS) == 1.0
    assert planted_share(_figure(0.5 * np.arange(40)), skeleton=SK, fps=FPS) == 1.0  # 0.125 m/s
    assert planted_share(_figure(0.7 * np.arange(40)), skeleton=SK, fps=FPS) == 0.0  # 0.175 m/s
    lifted = _figure(np.zeros(40))
    left = [SK.index(n) for n in ("left_ankle", "left_heel", "left_toe")]
    lifted[:, left, 1] += 5.0  # the left foot 5 cm up: only the right one is planted
    assert planted_share(lifted, skeleton=SK, fps=FPS) == pytest.approx(0.5)


def test_floor_contact_reports_the_float_the_near_floor_share_and_the_planted_share():
    """The standing figure lifted 3 cm in frames 10-19 of 40. The local floor (the lowest point within ±1 s)
    stays at 0, since every frame's window holds a frame on the floor: the gap is 3 cm in 10 frames and 0 in 30,
    so the float (median) is 0 and 30 of 40 frames are within 2 cm. Then frames 10-19 6 cm and 20-29 3 cm up:
    gaps (0 x 20, 3 x 10, 6 x 10), median 1.5 cm, 20 of 40 within 1 cm. The planted share is the motion
    module's (tested above)."""
    from dancekit.metrics import floor_contact

    p = _figure(np.zeros(40))
    p[10:20, :, 1] += 3.0
    got = floor_contact(p, skeleton=SK, fps=FPS)
    assert got["float_cm"] == pytest.approx(0.0, abs=1e-9)
    assert got["near_floor_share"] == pytest.approx(30 / 40)
    assert got["planted_share"] == pytest.approx(planted_share(p, skeleton=SK, fps=FPS))
    p[10:30, :, 1] += 3.0  # frames 10-19 6 cm up, 20-29 3 cm up: median gap of (0 x 20, 3 x 10, 6 x 10) = 1.5
    got = floor_contact(p, skeleton=SK, fps=FPS, near_cm=1.0)
    assert got["float_cm"] == pytest.approx(1.5, abs=1e-9) and got["near_floor_share"] == pytest.approx(0.5)


def test_the_lock_is_held_to_the_target_share():
    """A figure gliding at 0.35 m/s (1.4 cm a frame): the lock as set (contacts under 0.5 m/s) holds its feet,
    scaled by 0.8 (0.4 m/s) too, by 0.6 (0.3 m/s) no more. A target of 0 stops at 0.6 and leaves the dance as
    it was; a target of 1 keeps the lock as set (never more holding than without a target)."""
    p = _figure(1.4 * np.arange(80))
    assert planted_share(p, skeleton=SK, fps=FPS) == 0.0
    held = lock_feet(p, skeleton=SK, fps=FPS)
    assert planted_share(held, skeleton=SK, fps=FPS) > 0.3
    out, scale = lock_feet_to_share(p, skeleton=SK, fps=FPS, target=0.0)
    assert scale == 0.6
    np.testing.assert_allclose(out, p, atol=1e-9)
    out, scale = lock_feet_to_share(p, skeleton=SK, fps=FPS, target=1.0)
    assert scale == 1.0
    np.testing.assert_array_equal(out, held)
    # gliding at 0.45 m/s (1.8 cm a frame), then at 0.35 m/s: the 0.8 lock (0.4 m/s) holds the second half only
    two = _figure(np.concatenate([1.8 * np.arange(60), 1.8 * 59 + 1.4 * np.arange(1, 61)]))
    share_1 = planted_share(lock_feet(two, skeleton=SK, fps=FPS), skeleton=SK, fps=FPS)
    share_08 = planted_share(lock_feet(two, skeleton=SK, fps=FPS, speed_on=0.4, speed_off=0.72), skeleton=SK,
                             fps=FPS)
    assert share_1 > share_08 + 0.1 and share_08 > 0.1
    out, scale = lock_feet_to_share(two, skeleton=SK, fps=FPS, target=share_08 - 0.01)  # 0.6 holds nothing
    assert scale == 0.8 and planted_share(out, skeleton=SK, fps=FPS) == pytest.approx(share_08)
    out, scale = lock_feet_to_share(two, skeleton=SK, fps=FPS, target=0.02)  # nearer 0 than share_08
    assert scale == 0.6


@pytest.mark.parametrize(("kwargs", "match"), [({"target": 1.5}, "target"), ({"target": float("nan")}, "target"),
                                                ({"target": 0.2, "scales": (0.5, 1.0)}, "scales"),
                                                ({"target": 0.2, "scales": ()}, "scales")])
def test_bad_targets_and_scales_are_refused(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        lock_feet_to_share(_figure(np.zeros(10)), skeleton=SK, fps=FPS, **kwargs)


def _folder(tmp_path, entry) -> str:
    folder = tmp_path / "m"
    folder.mkdir(exist_ok=True)
    (folder / "config.json").write_text(json.dumps({"model": "revolution", **({"plant": entry} if entry else {})}))
    return str(folder)


def test_the_target_is_the_drawn_genres_share_or_the_posterior_mean(tmp_path):
    from dancekit.pipelines import stages
    from dancekit.pipelines.base import DanceResult

    table = {"waltz": 0.2, "rumba": 0.4}
    m = Motion(skeleton=SK, fps=FPS, positions=_figure(np.zeros(10)).astype(np.float32))
    r = DanceResult(motion=m, model="x", seed=0, genre="rumba", genre_probs={"waltz": 0.9, "rumba": 0.1})
    assert stages.plant_target(r, genre_share=table) == 0.4
    alone = DanceResult(motion=m, model="x", seed=0, genre=None, genre_probs={"waltz": 0.5, "rumba": 0.25, "tango": 0.25})
    assert stages.plant_target(alone, genre_share=table) == pytest.approx((0.5 * 0.2 + 0.25 * 0.4) / 0.75)
    assert stages.plant_target(DanceResult(motion=m, model="x", seed=0), genre_share=table) is None
    assert stages.plant_target(r) is None
    from dancekit.pipelines.config import read_stage_config

    config = read_stage_config(_folder(tmp_path, {"genre_share": table}))  # the old layout, converted
    assert config.foot_lock.plant and config.genre_stats.table("planted_share") == table
    (tmp_path / "plain").mkdir()
    assert not read_stage_config(_folder(tmp_path / "plain", None)).foot_lock.plant  # no entry: the lock as set


@pytest.mark.parametrize("entry", [{"genre_share": {"waltz": 0.0}}, {"genre_share": {"waltz": 1.2}},
                                   {"genre_share": {}}, {"genre_share": {"waltz": "a lot"}},
                                   {"genre_share": {"waltz": 0.3}, "scale": 1}, {"share": 0.3}, [0.3]])
def test_a_bad_plant_entry_is_a_checkpoint_error(tmp_path, entry):
    from dancekit.pipelines.config import read_stage_config

    with pytest.raises(CheckpointError, match=r"config\.json.*plant"):
        read_stage_config(_folder(tmp_path, entry))


def test_the_stage_holds_the_feet_only_as_long_as_the_genre_plants_them(tmp_path):
    """The gliding figure danced as a waltz: with a checkpoint whose waltz share is 0.01 the stage leaves its
    feet free (the 0.6 lock finds no contact), with a share of 1 it holds them as the lock as set does, and
    without the entry as well."""
    from dancekit.pipelines import stages
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import read_stage_config

    p = _figure(1.4 * np.arange(80)).astype(np.float32)
    motion = Motion(skeleton=SK, fps=FPS, positions=p)
    res = DanceResult(motion=motion, model="m", seed=0, genre="waltz")

    def lock(folder):
        config = read_stage_config(folder)
        return stages.foot_lock(res, config.foot_lock, config.genre_stats).motion.positions

    free = lock(_folder(tmp_path, {"genre_share": {"waltz": 0.01}}))
    np.testing.assert_allclose(free, p, atol=1e-4)
    held = lock(_folder(tmp_path, {"genre_share": {"waltz": 1.0}}))
    np.testing.assert_allclose(held, lock_feet(p, skeleton=SK, fps=FPS), atol=1e-4)
    assert np.abs(held - p).max() > 1.0
    (tmp_path / "plain").mkdir()
    plain = lock(_folder(tmp_path / "plain", None))
    np.testing.assert_array_equal(plain, held)
