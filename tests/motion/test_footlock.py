"""Foot locking, two-bone IK and the smoothing stage (issue 15: planted feet that do not skate, jitter).

Known answers are built independently of the code under test: random legs and targets drawn inside the
reach (law of cosines), a figure made by forward kinematics of chosen joint rotations whose root slides at
a known speed while a foot is on the floor, and cubic motions that a Savitzky-Golay filter must keep.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.motion import Motion, get_skeleton
from dancekit.motion.footlock import (
    _hysteresis,
    foot_contacts,
    leg_chains,
    leg_rotations,
    lock_feet,
    two_bone_ik,
)
from dancekit.motion.jitter import smooth_positions, smoothing_window
from dancekit.motion.kinematics import rig_forward_kinematics
from dancekit.motion.rotations import axis_angle_to_matrix

FPS = 25.0
SK = get_skeleton("tang2018")


def _random_legs(n: int, rng: np.random.Generator):
    hip = rng.normal(size=(n, 3)) * 10
    l1, l2 = rng.uniform(30, 50, n), rng.uniform(30, 50, n)
    knee = hip + l1[:, None] * _unit(rng.normal(size=(n, 3)))
    ankle = knee + l2[:, None] * _unit(rng.normal(size=(n, 3)))
    d = rng.uniform(np.abs(l1 - l2) + 1.0, l1 + l2 - 1.0)  # strictly inside the reach
    target = hip + d[:, None] * _unit(rng.normal(size=(n, 3)))
    return hip, knee, ankle, target, l1, l2


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_two_bone_ik_reaches_a_reachable_target_and_keeps_bone_lengths():
    rng = np.random.default_rng(0)
    hip, knee, ankle, target, l1, l2 = _random_legs(500, rng)
    k, a = two_bone_ik(hip, knee, ankle, target)
    np.testing.assert_allclose(a, target, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(k - hip, axis=-1), l1, rtol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(a - k, axis=-1), l2, rtol=1e-10)
    # the knee bends toward the original knee's side of the hip -> target axis (the pole)
    u = _unit(target - hip)
    pole = (knee - hip) - ((knee - hip) * u).sum(-1, keepdims=True) * u
    side = ((k - hip) * pole).sum(-1)
    assert np.all(side >= -1e-9)
    # and stays in the plane of hip, target and the original knee
    normal = np.cross(u, _unit(pole))
    np.testing.assert_allclose(((k - hip) * normal).sum(-1), 0.0, atol=1e-8)


def test_two_bone_ik_stretches_toward_an_unreachable_target():
    hip = np.zeros((1, 3))
    knee = np.array([[0.0, -40.0, 5.0]])
    ankle = np.array([[0.0, -80.0, 0.0]])
    l1, l2 = np.linalg.norm(knee - hip), np.linalg.norm(ankle - knee)
    target = np.array([[0.0, -200.0, 0.0]])
    k, a = two_bone_ik(hip, knee, ankle, target)
    np.testing.assert_allclose(a, [[0.0, -(l1 + l2), 0.0]], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(k - hip), l1, rtol=1e-10)


def test_hysteresis_and_minimum_duration():
    on = np.array([0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 1, 1, 0], bool)
    stay = np.array([0, 1, 1, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1], bool)
    got = _hysteresis(on, stay, min_len=3)
    # run 1..3 (starts on, stays 3 frames), run 7..8 too short, run 10..13
    want = np.array([0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1], bool)
    np.testing.assert_array_equal(got, want)


def _sliding_figure(T: int = 60, speed_cm: float = 0.5):
    """A figure made by FK: knees bent 40°, hips flexed 20°, the root sliding forward ``speed_cm`` per frame,
    both feet on the floor (their lowest joint at height 0). Returns (rotations, root, positions)."""
    rig = SK.rig()
    rot = np.tile(np.eye(3), (T, rig.num_joints, 1, 1))
    for side in ("left", "right"):
        rot[:, SK.index(f"{side}_hip")] = axis_angle_to_matrix(torch.tensor([-0.35, 0.0, 0.0])).numpy()
        rot[:, SK.index(f"{side}_knee")] = axis_angle_to_matrix(torch.tensor([0.7, 0.0, 0.0])).numpy()
    root = np.zeros((T, 3))
    root[:, 2] = speed_cm * np.arange(T)
    p = rig_forward_kinematics(torch.from_numpy(rot), torch.from_numpy(root), SK).numpy()
    lift = p[0, :, 1].min()
    root[:, 1] -= lift
    p[..., 1] -= lift
    return rot, root, p


def test_locked_foot_does_not_move_and_the_upper_body_is_untouched():
    rot, root, p = _sliding_figure(speed_cm=0.2)
    legs = leg_chains(SK)
    assert len(legs) == 2
    contacts = np.zeros((len(p), 2), bool)
    contacts[10:40, 0] = True  # the left foot planted for 30 frames while the body slides 6 cm
    out = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts, blend_s=0.2)
    hip, knee, ankle, below = legs[0]
    foot = [ankle, *below]
    assert np.ptp(p[10:40, foot], axis=0).max() > 5  # before: the foot slid with the body
    np.testing.assert_allclose(out[10:40, foot], np.broadcast_to(out[10, foot], (30, len(foot), 3)), atol=1e-9)
    # only the left leg below the hip changed
    moved = [knee, *foot]
    others = [j for j in range(SK.num_joints) if j not in moved]
    np.testing.assert_array_equal(out[:, others], p[:, others])
    # bone lengths kept in every frame
    for child in moved:
        parent = SK.parents[child]
        np.testing.assert_allclose(np.linalg.norm(out[:, child] - out[:, parent], axis=-1),
                                   np.linalg.norm(p[:, child] - p[:, parent], axis=-1), rtol=1e-9)
    # held where it was planted, put down on the floor (its lowest joint at height 0)
    np.testing.assert_allclose(out[10, foot][:, [0, 2]], p[10, foot][:, [0, 2]], atol=1e-9)
    assert abs(out[10, foot, 1].min()) < 1e-9 and p[10, foot, 1].min() > 0.1
    # no pop: the correction at the contact's end (the 5.8-cm slide) is spread over the 5-frame blend (a
    # smoothstep's slope is at most 1.5), never applied in one frame
    step = np.linalg.norm(np.diff(out[:, ankle], axis=0), axis=-1)
    assert step.max() < 0.2 + 1.5 * 5.8 / 5
    # far from the contact the leg is the original one
    np.testing.assert_array_equal(out[:4, foot], p[:4, foot])
    np.testing.assert_array_equal(out[46:, foot], p[46:, foot])


def test_contacts_found_on_a_sliding_planted_foot_and_not_on_a_lifted_one():
    _, _, p = _sliding_figure()
    lifted = p.copy()
    legs = leg_chains(SK)
    _, knee, ankle, below = legs[1]
    lifted[20:40, [ankle, *below], 1] += 30.0  # the right foot 30 cm up for 0.8 s
    c = foot_contacts(lifted, skeleton=SK, fps=FPS)
    assert c[:, 0].all()  # slow (0.125 m/s) and on the floor all along
    assert not c[22:38, 1].any()
    assert c[:15, 1].all() and c[45:, 1].all()


def test_leg_rotations_follow_the_locked_positions():
    rot, root, p = _sliding_figure(speed_cm=0.2)
    contacts = np.zeros((len(p), 2), bool)
    contacts[5:50, :] = True
    out = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts)
    new_rot = leg_rotations(rot, p, out, skeleton=SK)
    fk = rig_forward_kinematics(torch.from_numpy(new_rot), torch.from_numpy(root), SK).numpy()
    np.testing.assert_allclose(fk, out, atol=1e-6)
    legs_below_hip = {j for h, k, a, b in leg_chains(SK) for j in (h, k, a, *b)}
    keep = [j for j in range(SK.rig().num_joints) if j not in legs_below_hip]
    np.testing.assert_allclose(new_rot[:, keep], rot[:, keep], atol=1e-12)


def test_smoothing_keeps_a_cubic_motion_and_removes_noise():
    T = 200
    t = np.arange(T) / FPS
    rng = np.random.default_rng(1)
    coef = rng.normal(size=(4, SK.num_joints, 3))
    cubic = sum(coef[k] * (t[:, None, None] / 8.0) ** k for k in range(4)) * 20.0
    out, _ = smooth_positions(cubic, skeleton=SK, fps=FPS, window=9)
    np.testing.assert_allclose(out, cubic, atol=1e-8)
    assert smoothing_window(cubic, skeleton=SK, fps=FPS, target=0.05) == 1  # already smooth: left alone
    noisy = cubic + rng.normal(scale=1.0, size=cubic.shape)
    w = smoothing_window(noisy, skeleton=SK, fps=FPS, target=0.1, windows=(5, 7, 9, 11, 13, 15, 21, 31))
    assert w > 1
    out, used = smooth_positions(noisy, skeleton=SK, fps=FPS, target=0.1)
    assert used > 1
    assert np.abs(out - cubic).mean() < 0.6 * np.abs(noisy - cubic).mean()


def test_the_stages_lock_feet_of_a_rotation_motion():
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.stages import foot_lock

    rot, root, p = _sliding_figure(speed_cm=0.1)
    m = Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32), rotations=rot.astype(np.float32),
               root_translation=root.astype(np.float32))
    res = DanceResult(motion=m, model="x", seed=0)
    out = foot_lock(res).motion
    legs = leg_chains(SK)
    for _, _, ankle, _ in legs:
        speed = np.linalg.norm(np.diff(out.positions[5:55, ankle], axis=0), axis=-1)
        assert speed.max() < 0.02  # both feet held: the body slides 0.1 cm a frame over them
    fk = rig_forward_kinematics(torch.from_numpy(out.rotations.astype(np.float64)),
                                torch.from_numpy(out.root_translation.astype(np.float64)), SK).numpy()
    np.testing.assert_allclose(fk, out.positions, atol=1e-3)


def test_a_gliding_foot_is_replanted_not_dragged():
    _, _, p = _sliding_figure(T=100, speed_cm=1.0)  # 1 m in 4 s: far beyond one hold
    contacts = np.ones((len(p), 2), bool)
    out = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts, max_drift_m=0.1, floor_on=False)
    _, _, ankle, _ = leg_chains(SK)[0]
    step = np.linalg.norm(np.diff(out[:, ankle], axis=0), axis=-1)
    held = step < 1e-9
    assert 0.4 < held.mean() < 0.9  # held most of the time, moved to a new hold in between
    # never farther from the original foot than the drift allows (plus a frame's slide)
    assert np.linalg.norm(out[:, ankle] - p[:, ankle], axis=-1).max() <= 10.0 + 1.0 + 1e-9


@pytest.mark.parametrize("bad", [np.zeros((5, 3)), np.zeros((0, 23, 3))])
def test_bad_shapes_are_refused(bad):
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError):
        lock_feet(bad, skeleton=SK, fps=FPS)


def test_savgol_equals_scipy_interp_mode():
    """The NumPy Savitzky-Golay filter (no scipy.signal import in a dance process) is scipy's, edges included."""
    from scipy.signal import savgol_filter

    from dancekit.motion.filters import savgol as _savgol

    rng = np.random.default_rng(3)
    for T, window, order in [(100, 7, 3), (40, 21, 3), (21, 21, 3), (9, 5, 2), (60, 5, 3)]:
        p = rng.normal(size=(T, 4, 3)).cumsum(axis=0)
        np.testing.assert_allclose(_savgol(p, window, order), savgol_filter(p, window, order, axis=0, mode="interp"),
                                   rtol=0, atol=1e-10)
    p = rng.normal(size=(4, 2, 3))
    np.testing.assert_array_equal(_savgol(p, 7, 3), p)  # a window longer than the dance: unfiltered


def test_position_blend_keeps_the_foot_velocity_continuous_at_a_hold():
    """The foot glides at 1 cm a frame; held over frames 20-29. An offset blend starts the held foot at the
    original's full speed (1 cm in the first frame out, a jump from rest); the position blend eases it in
    and out: the first step is the smoothstep's first weight times the distance to cover."""
    from dancekit.motion.footlock import _offsets, _wanted, smoothstep

    T, blend = 60, 8
    orig = np.zeros((T, 1, 3))
    orig[:, 0, 0] = np.arange(T, dtype=float)  # 1 cm / frame along x
    held = np.zeros(T, bool)
    held[20:30] = True
    target = orig.copy()
    target[20:30] = orig[20]
    want, weight = _wanted(target, orig, held, blend)
    step = np.diff(want[:, 0, 0])
    np.testing.assert_array_equal(want[20:30], np.broadcast_to(orig[20], (10, 1, 3)))  # still in the hold
    w1 = float(smoothstep(np.array(1 / (blend + 1))))
    # into the hold: from the frame before it (weight w1 on the original, 1 cm behind) -> w1 cm
    assert step[19] == pytest.approx(w1 * 1.0)
    # out of it: the original is 10 cm ahead after the first frame -> w1 * 10 cm, under half the glide speed
    assert step[29] == pytest.approx(w1 * 10.0)
    assert step[19] < 0.05 and step[29] < 0.5
    # the hand-over ends on the original foot at its own speed, the weight 0 from there on
    np.testing.assert_array_equal(want[:20 - blend], orig[:20 - blend])
    np.testing.assert_array_equal(want[30 + blend:], orig[30 + blend:])
    assert weight[25] == 1.0 and weight[0] == 0.0 and weight[-1] == 0.0
    # the offset blend: the foot arrives at the hold at the original's full speed and stops dead
    old = np.diff((orig + _offsets(target, orig, held, blend))[:, 0, 0])
    assert old[19] == pytest.approx(1.0) and old[20] == 0.0


def test_a_short_swing_between_holds_starts_and_ends_at_rest():
    """Two holds 6 frames apart (a re-plant): the foot goes from one to the other with zero speed at both
    ends, and keeps the original swing's lift in the middle (sin² weight, exactly at the centre)."""
    from dancekit.motion.footlock import _wanted, smoothstep

    T = 40
    orig = np.zeros((T, 1, 3))
    orig[:, 0, 0] = np.arange(T, dtype=float)
    lift = np.zeros(T)
    lift[15:22] = np.sin(np.pi * np.arange(1, 8) / 8) * 4.0  # a 4-cm lift over the swing
    orig[:, 0, 1] = lift
    held = np.zeros(T, bool)
    held[5:15] = held[22:32] = True
    target = orig.copy()
    target[5:15] = orig[5]
    target[22:32] = orig[22]
    want, _ = _wanted(target, orig, held, 8)
    x = want[:, 0, 0]
    first = float(smoothstep(np.array(1 / 8))) * 17.0  # 7 swing frames: x = 1/8 .. 7/8 of the 17-cm step
    assert x[15] - x[14] == pytest.approx(first) and x[22] - x[21] == pytest.approx(first)
    assert first < 0.4 * 17.0 / 8  # leaves and arrives at under 0.4 of the mean swing speed (from rest)
    assert np.all(np.diff(x[14:23]) >= 0)  # monotone: no foot going back
    # the swing's centre (frame 18, x = 1/2) keeps the original lift exactly; elsewhere sin²-weighted
    assert want[18, 0, 1] == pytest.approx(lift[18])
    np.testing.assert_allclose(want[15:22, 0, 1], np.sin(np.pi * np.arange(1, 8) / 8) ** 2 * lift[15:22])


def test_stops_shorter_than_the_minimum_hold_are_not_held():
    _, _, p = _sliding_figure(T=60, speed_cm=0.2)
    contacts = np.zeros((len(p), 2), bool)
    contacts[10:16, 0] = True  # 6 frames = 0.24 s
    contacts[30:50, 0] = True  # 20 frames
    _, rep = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts, min_hold_s=0.32, return_report=True)
    assert not rep.held[10:16, 0].any()
    assert rep.held[30:50, 0].all()
    _, rep = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts, min_hold_s=0.2, return_report=True)
    assert rep.held[10:16, 0].all()


def test_the_knee_meets_the_original_one_where_the_lock_ends():
    """Feet turned 90° from the knees (the toe nudge then swivels the knee's plane by about 36°): the
    former pole (nudge on wherever the leg changed) swung the knee back in one frame where the lock ended,
    an 11-cm jump; with the nudge faded by the lock's weight the knee swivels over several frames."""
    _, _, p = _sliding_figure(T=60, speed_cm=0.2)
    hip, knee, ankle, below = leg_chains(SK)[0]
    for j in below:  # toes turned a quarter about the vertical
        d = p[:, j] - p[:, ankle]
        p[:, j] = p[:, ankle] + np.stack([d[:, 2], d[:, 1], -d[:, 0]], axis=-1)
    contacts = np.zeros((len(p), 2), bool)
    contacts[10:30, 0] = True

    def knee_steps(**kw):
        out = lock_feet(p, skeleton=SK, fps=FPS, contacts=contacts, **kw)
        return np.linalg.norm(np.diff(out[:, knee] - out[:, hip], axis=0), axis=-1), out

    new, out = knee_steps()
    old, _ = knee_steps(c1_blend=False)
    assert old.max() > 10.0
    assert new.max() < 0.4 * old.max()
    np.testing.assert_array_equal(out[45:, knee], p[45:, knee])  # after the hand-over: the original knee


def test_the_revolution_stage_uses_its_own_minimum_hold():
    from pathlib import Path

    import dancekit.pipelines.stages as stages
    from dancekit.pipelines.config import read_stage_config

    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    assert read_stage_config(folder / "revolution").foot_lock.lock_options() == {"min_hold_s": 0.4}
    assert read_stage_config(folder / "music2dance").foot_lock.lock_options() == {}


def test_the_smoothing_stage_takes_a_named_genres_target_from_the_checkpoint(tmp_path):
    """A dance whose genre was asked for by name is smoothed to the checkpoint's target for that genre
    (``"stages": {"smooth": {"genre_targets": [...]}}`` with ``"genre_stats": {"smoothing": ...}``); "auto",
    "none", another genre or a checkpoint without the entry keep the stage's own targets."""
    import dataclasses
    import json

    from dancekit.errors import CheckpointError
    from dancekit.motion.jitter import jitter_ratio as _jitter_ratio
    from dancekit.pipelines import stages
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import SmoothConfig, read_stage_config

    T = 200
    t = np.arange(T) / FPS
    rng = np.random.default_rng(3)
    p = (np.sin(2 * np.pi * 1.5 * t)[:, None, None] * rng.normal(size=(1, SK.num_joints, 3)) * 10.0
         + rng.normal(scale=1.3, size=(T, SK.num_joints, 3)))
    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"model": "music2dance",
                                                    "stages": {"smooth": {"genre_targets": ["chacha"]}},
                                                    "genre_stats": {"smoothing": {"chacha": 0.25, "waltz": 0.1}}}))
    config = read_stage_config(folder)
    named = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32)), model=str(folder),
                        seed=0, genre_requested="chacha", genre="chacha")
    assert _jitter_ratio(p, SK, FPS) > 0.4  # jittery: the stage filters it either way
    assert stages.smoothing_target(named, config.smooth, config.genre_stats) == 0.25
    others = [dataclasses.replace(named, genre_requested="auto"), dataclasses.replace(named, genre_requested="none"),
              dataclasses.replace(named, genre_requested="waltz", genre="waltz")]
    assert [stages.smoothing_target(r, config.smooth, config.genre_stats) for r in others] == [None] * 3
    assert stages.smoothing_target(named, SmoothConfig(), config.genre_stats) is None  # no entry
    mine = stages.smooth(named, config=config.smooth, genre_stats=config.genre_stats)
    np.testing.assert_array_equal(mine.motion.positions, stages.smooth(others[0], target=0.25).motion.positions)
    plain = stages.smooth(others[0], config=config.smooth, genre_stats=config.genre_stats)  # the stage's own
    # target (0.065 for a dance this jittery): a longer filter

    def window(r):
        return int(r.notes[-1].split("(")[1].split("-")[0])

    assert 1 < window(mine) < window(plain)
    (folder / "config.json").write_text(json.dumps({"model": "x", "smoothing": {"genre_targets": {"chacha": "a"}}}))
    with pytest.raises(CheckpointError, match="genre_stats.smoothing.chacha must be"):  # the old layout, checked
        read_stage_config(folder)


def test_a_drawn_genre_takes_the_scaled_target_when_the_entry_says_drawn(tmp_path):
    """With ``"drawn": true`` the target also applies to a genre read from the music or drawn by the seed
    (``genre_requested`` "auto" or None, ``genre`` the genre model that danced), times ``"scale"``: 0.2 × 1.5 =
    0.3 for cha-cha; the model alone (genre None), a genre without a target and "none" keep the stage's own
    targets; without ``"drawn"`` only a named genre takes it (unscaled 0.2 × 1.5 all the same). Malformed
    entries name the file."""
    import dataclasses
    import json

    from dancekit.errors import CheckpointError
    from dancekit.pipelines import stages
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import read_stage_config

    folder = tmp_path / "m"
    folder.mkdir()
    cfg = folder / "config.json"

    def write(entry):  # the old layout's entry (converted on reading)
        cfg.write_text(json.dumps({"model": "revolution", "smoothing": entry}))

    def target(result):
        config = read_stage_config(folder)
        return stages.smoothing_target(result, config.smooth, config.genre_stats)

    write({"genre_targets": {"chacha": 0.2, "waltz": 0.06}, "drawn": True, "scale": 1.5})
    p = np.zeros((10, SK.num_joints, 3), np.float32)
    drawn = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=str(folder), seed=1,
                        genre_requested="auto", genre="chacha")
    assert target(drawn) == pytest.approx(0.3)
    assert target(dataclasses.replace(drawn, genre_requested=None)) == pytest.approx(0.3)
    assert target(dataclasses.replace(drawn, genre="waltz")) == pytest.approx(0.09)
    for other in (dataclasses.replace(drawn, genre=None), dataclasses.replace(drawn, genre="tango"),
                  dataclasses.replace(drawn, genre_requested="none", genre=None)):
        assert target(other) is None
    write({"genre_targets": {"chacha": 0.2}, "scale": 1.5})  # not drawn: a named genre only
    assert target(drawn) is None
    assert target(dataclasses.replace(drawn, genre_requested="chacha")) == pytest.approx(0.3)
    for bad in ({"genre_targets": {"chacha": 0.2}, "drawn": "yes"}, {"genre_targets": {"chacha": 0.2}, "scale": 0},
                {"genre_targets": {"chacha": 0.2}, "speed": 1}):
        write(bad)
        with pytest.raises(CheckpointError, match=r"config\.json.*stages\.smooth\.(drawn|scale|speed)"):
            target(drawn)


@pytest.mark.parametrize(("speed_cm", "planted"), [(3.8, True), (4.2, False)])
def test_a_faster_contact_speed_finds_a_gliding_foot(speed_cm, planted):
    """Both feet on the floor, sliding at 0.95 m/s (3.8 cm a frame at 25 fps) or 1.05 m/s (4.2 cm): with a
    1.0-m/s contact speed (1.4 m/s to leave) the slower foot is a contact all along and the faster one never;
    with the default 0.5 m/s neither is."""
    _, _, p = _sliding_figure(T=40, speed_cm=speed_cm)
    c = foot_contacts(p, skeleton=SK, fps=FPS, speed_on=1.0, speed_off=1.4)
    assert c.all() if planted else not c.any()
    assert not foot_contacts(p, skeleton=SK, fps=FPS).any()


def _checkpoint(tmp_path, entry):
    import json

    folder = tmp_path / "m"
    folder.mkdir(exist_ok=True)
    (folder / "config.json").write_text(json.dumps({"model": "dual", **({"foot_lock": entry} if entry else {})}))
    return str(folder)


def test_the_stage_reads_contact_thresholds_from_the_checkpoint(tmp_path):
    """A checkpoint's ``"foot_lock": {"speed_on": 1.0, "speed_off": 1.4}`` reaches the lock: a figure gliding
    at 0.95 m/s has its feet held (the ankle still over the hold) where a checkpoint without the entry
    leaves the dance as it was; the embedded dual carries its entry, music2dance none."""
    from pathlib import Path

    from dancekit.pipelines import stages
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import read_stage_config

    _, _, p = _sliding_figure(T=60, speed_cm=3.8)
    motion = Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32))
    plain = stages.foot_lock(DanceResult(motion=motion, model="m", seed=0),
                             read_stage_config(_checkpoint(tmp_path, None)).foot_lock)
    np.testing.assert_array_equal(plain.motion.positions, motion.positions)
    fast = read_stage_config(_checkpoint(tmp_path, {"speed_on": 1.0, "speed_off": 1.4})).foot_lock
    assert fast.lock_options() == {"speed_on": 1.0, "speed_off": 1.4}
    locked = stages.foot_lock(DanceResult(motion=motion, model="m", seed=0), fast).motion.positions
    ankle = leg_chains(SK)[0][2]
    step = np.linalg.norm(np.diff(locked[:, ankle], axis=0), axis=-1)
    assert (step < 1e-3).sum() >= 3  # held: frames in which the ankle does not move (it slid 3.8 cm a frame)
    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    assert set(read_stage_config(folder / "dual").foot_lock.lock_options()) & {"speed_on", "height_on", "max_drift_m"}


@pytest.mark.parametrize("entry", [{"speed_on": 1.5}, {"speed_on": 1.0, "speed_off": 0.9}, {"height_on": -0.01},
                                   {"height_off": 0.02}, {"speed_on": "fast"}, {"contact": 1.0}, [1.0]])
def test_a_bad_foot_lock_entry_is_a_checkpoint_error(tmp_path, entry):
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.config import read_stage_config

    folder = _checkpoint(tmp_path, entry)
    with pytest.raises(CheckpointError, match="config.json.*foot_lock"):
        read_stage_config(folder)


def _segments_frame_by_frame(p, contact, hip, ankle, knee, limit, gap, min_len):
    """The holds' rule as a loop over frames (the reference for :func:`_segments`): a hold planted at frame t0
    lasts while the ankle stays within ``limit`` (x, z) of its planted position and that position within 99.5 %
    of thigh + shin from the hip."""
    reach = np.linalg.norm(p[:, knee] - p[:, hip], axis=-1) + np.linalg.norm(p[:, ankle] - p[:, knee], axis=-1)
    out, edges = [], np.flatnonzero(np.diff(np.concatenate([[0], contact.astype(int), [0]])))
    for s, e in zip(edges[::2], edges[1::2] - 1):
        t0 = s
        while t0 <= e:
            anchor, t = p[t0, ankle], t0
            while t + 1 <= e and np.hypot(*(p[t + 1, ankle, [0, 2]] - anchor[[0, 2]])) <= limit \
                    and np.linalg.norm(anchor - p[t + 1, hip]) <= 0.995 * reach[t + 1]:
                t += 1
            if t - t0 + 1 >= min_len:
                out.append((int(t0), int(t)))
            t0 = t + 1 + gap
    return out


def test_holds_follow_the_frame_by_frame_rule_exactly_even_on_the_bound():
    """The holds (computed for all frames of a contact at once) are those of the frame-by-frame rule, including
    frames whose drift is exactly the limit (kept: the rule is <=) and a hair above it."""
    from dancekit.motion.footlock import _segments

    rng = np.random.default_rng(3)
    hip, knee, ankle = (SK.index(n) for n in ("left_hip", "left_knee", "left_ankle"))
    foot = [ankle, *[j for j in range(SK.num_joints) if SK.parents[j] == ankle]]
    limit = 0.06 / SK.unit_scale
    for trial in range(30):
        T = 200
        p = np.cumsum(rng.normal(0, 0.6, (T, SK.num_joints, 3)), axis=0) + np.array([0.0, 90.0, 0.0])
        p[:, ankle] = p[:, hip] + np.array([0.0, -70.0, 0.0]) + np.cumsum(rng.normal(0, 1.5, (T, 3)), axis=0)
        if trial % 3 == 0:  # ankles exactly on the bound (and one ulp over) of the hold planted at frame 0
            p[:40, ankle, 1] = p[0, ankle, 1]
            p[:40, ankle, 0] = p[0, ankle, 0] + np.where(np.arange(40) % 7 == 3, limit, 0.5 * limit)
            p[:40, ankle, 2] = p[0, ankle, 2]
            p[29, ankle, 0] = np.nextafter(p[0, ankle, 0] + limit, np.inf)
        contact = rng.uniform(size=T) < 0.8
        contact[:40] = True
        for gap, min_len in ((2, 1), (5, 10)):
            want = _segments_frame_by_frame(p, contact, hip, ankle, knee, limit, gap, min_len)
            assert _segments(p, contact, hip, foot, SK, 0.06, gap, min_len) == want, trial
    assert want  # holds were found
