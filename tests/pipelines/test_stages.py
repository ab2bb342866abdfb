"""The shared pipeline stages: the beat-synchronous time warp and the physical clean-up (issue 15).

Known answers are built independently of the code under test: a synthetic dance whose speed minima are
at chosen times (a phase that passes integer values at those times, position ``x(φ) = φ - sin(2πφ)/2π``
so the speed ``dx/dφ · dφ/dt = 1 - cos 2πφ`` is zero exactly there), music beats at chosen times, and a
figure that floats and drifts in a straight line at a known height and speed.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dancekit.motion import Motion, get_skeleton
from dancekit.motion.analysis import kinematic_beats
from dancekit.motion.cleanup import clean_up, contain_root_path, ground_contact
from dancekit.motion.timewarp import (
    DEFAULT_MAX_RATE_CHANGE,
    beat_warp,
    match_beats,
    warp_frames,
    warp_motion,
    warp_rates,
)

FPS = 25.0


def _dance_with_minima(minima: np.ndarray, duration: float, *, fps: float = FPS) -> np.ndarray:
    """(T, 2, 3) positions whose mean joint speed is zero exactly at ``minima`` (seconds)."""
    T = int(round(duration * fps)) + 1
    t = np.arange(T) / fps
    knots_t = np.concatenate([[0.0], minima, [(T - 1) / fps]])
    phase = np.interp(t, knots_t, np.arange(len(knots_t)))  # integer at every minimum
    x = phase - np.sin(2 * np.pi * phase) / (2 * np.pi)
    p = np.zeros((T, 2, 3))
    p[:, 0, 0] = 20.0 * x
    p[:, 1, 0] = 20.0 * x
    p[:, 1, 1] = 10.0
    return p


def test_warp_moves_known_minima_onto_known_beats():
    # beats every second; the dance's speed minima early or late by up to 0.15 s, an offset that drifts
    # slowly (≤ 6 % of a beat from one beat to the next, plus ≤ 4 % for the frame grid), so every minimum
    # can be moved onto its beat within the DP's ±13 % between pairs
    beats = np.arange(1.0, 30.0, 1.0)
    minima = beats + 0.15 * np.sin(2 * np.pi * beats / 16.0 + 0.5)
    p = _dance_with_minima(minima, 30.5)
    found = kinematic_beats(p, fps=FPS, smooth=None)
    np.testing.assert_allclose(found, minima, atol=1.0 / FPS)  # the construction is right (to a frame)
    source, pairs = beat_warp(p, music_beats=beats, fps=FPS, smooth=0)
    warped = warp_frames(p, source_frames=source)
    after = kinematic_beats(warped, fps=FPS, smooth=None)
    near = np.array([np.abs(after - b).min() for b in beats])
    before = np.array([np.abs(found - b).min() for b in beats])
    assert np.mean(before <= 1.0 / FPS) < 0.35  # before the warp most minima are off their beat
    assert len(pairs) >= 0.9 * len(beats)
    assert np.mean(near <= 1.0 / FPS) >= 0.9  # after it, they land on the beats within a frame
    # with the default speed smoothing of the beat metrics too
    after_smoothed = kinematic_beats(warped, fps=FPS)
    assert np.mean([np.abs(after_smoothed - b).min() <= 1.0 / FPS for b in beats]) >= 0.8
    # monotone, same length, ends fixed, the local speed change within the stated bound
    rate = np.diff(source)
    assert len(source) == len(p) and source[0] == 0 and source[-1] == pytest.approx(len(p) - 1, abs=1e-6)
    assert rate.min() >= 1 - DEFAULT_MAX_RATE_CHANGE - 1e-9 and rate.max() <= 1 + DEFAULT_MAX_RATE_CHANGE + 1e-9
    # no speed jumps: the rate changes by less than 2 % from one frame to the next
    assert np.abs(np.diff(rate)).max() < 0.02


def test_matched_pairs_land_on_their_beats_exactly():
    pairs = np.array([[1.0, 1.1], [2.0, 2.05], [3.2, 3.1]])
    source = warp_rates(pairs=pairs, n_frames=126, fps=FPS)
    at = np.interp(pairs[:, 0] * FPS, np.arange(126), source)
    np.testing.assert_allclose(at, pairs[:, 1] * FPS, atol=1e-3)


def test_dp_respects_the_pair_rate_bound_and_order():
    kin = np.array([0.5, 1.0, 1.4, 2.6, 3.0])
    mus = np.array([0.55, 1.05, 1.5, 2.0, 2.5, 3.0])
    pairs = match_beats(kinematic=kin, music=mus, duration=4.0, pair_rate_change=0.1, max_shift=0.3)
    chain = np.concatenate([[[0, 0]], pairs, [[4.0, 4.0]]])
    assert np.all(np.diff(chain[:, 0]) > 0) and np.all(np.diff(chain[:, 1]) > 0)
    rate = np.diff(chain[:, 1]) / np.diff(chain[:, 0])
    assert np.all(np.abs(rate - 1) <= 0.1 + 1e-9)
    # worked by hand: of the candidates A(0.55, 0.5) B(1.05, 1.0) C(1.5, 1.4) D(2.5, 2.6) E(3.0, 3.0) the chains
    # within ±10 % are A-B-E, A-C-E and A-D; A-B-E has the gentler rates (0.91, 1.0, 1.03 against 0.91, 0.95, 1.07)
    np.testing.assert_allclose(pairs, [[0.55, 0.5], [1.05, 1.0], [3.0, 3.0]])


def test_a_song_without_beats_leaves_the_dance_unchanged():
    p = _dance_with_minima(np.arange(0.7, 9.0, 0.7), 10.0)
    source, pairs = beat_warp(p, music_beats=np.zeros(0), fps=FPS)
    assert len(pairs) == 0
    np.testing.assert_array_equal(warp_frames(p, source_frames=source), p)


def test_warp_motion_slerps_rotations():
    sk = get_skeleton("tang2018")
    rng = np.random.default_rng(1)
    T = 30
    import torch

    from dancekit.motion.rotations import axis_angle_to_matrix

    aa = torch.from_numpy(rng.normal(scale=0.3, size=(T, sk.rig().num_joints, 3)))
    m = Motion(skeleton=sk, fps=FPS, rotations=axis_angle_to_matrix(aa).numpy(),
               root_translation=rng.normal(size=(T, 3)))
    out = warp_motion(m, source_frames=np.arange(T, dtype=np.float64))  # identity warp
    np.testing.assert_allclose(out.rotations, m.rotations, atol=1e-6)
    half = warp_motion(m, source_frames=np.full(T, 2.5))
    np.testing.assert_allclose(half.root_translation[0], 0.5 * (m.root_translation[2] + m.root_translation[3]))


# ------------------------------------------------------------------------------------------ clean-up


def _floating_drifting(sk, *, seconds: float, speed_m_s: float = 0.3, float_cm: float = 6.0) -> np.ndarray:
    """The rest pose, bobbing ``float_cm`` ± 3 cm above the floor at 1 Hz and drifting in a straight line."""
    from dancekit.motion.analysis import rest_pose

    rest = rest_pose(sk)
    rest[:, 1] -= rest[:, 1].min()  # lowest joint at height 0
    T = int(seconds * FPS) + 1
    t = np.arange(T) / FPS
    p = np.repeat(rest[None], T, axis=0)
    p[..., 1] += float_cm + 3.0 * np.sin(2 * np.pi * t)[:, None]
    p[..., 0] += (speed_m_s / sk.unit_scale) * t[:, None]
    return p


def test_floating_figure_is_put_on_the_floor():
    sk = get_skeleton("tang2018")
    p = _floating_drifting(sk, seconds=10.0)
    low_before = p[..., 1].min(axis=1)
    assert np.median(low_before) > 5.0
    g = ground_contact(p, skeleton=sk, fps=FPS)
    low = g[..., 1].min(axis=1)
    assert low.min() >= -1e-9  # no penetration
    # a 1 Hz bob of ±3 cm rises at most 2π·3 cm/s: 1.9 cm in the 0.1 s half-window of the running minimum
    assert np.median(low) < 1.5 and np.mean(low <= 2.0) > 0.95
    np.testing.assert_allclose(g[..., [0, 2]], p[..., [0, 2]])  # only the height moved
    np.testing.assert_allclose(g - g[:, :1], p - p[:, :1], atol=1e-9)  # rigid: the pose is kept


def test_drifting_figure_stays_on_a_dance_floor_for_twenty_minutes():
    sk = get_skeleton("tang2018")
    p = _floating_drifting(sk, seconds=20 * 60.0, speed_m_s=0.3)
    root0 = p[:, sk.root][:, [0, 2]]
    assert np.hypot(*(root0[-1] - root0[0])) * sk.unit_scale > 300  # 360 m of straight drift
    c = contain_root_path(p, skeleton=sk, fps=FPS)
    root = c[:, sk.root][:, [0, 2]]
    dist = np.hypot(*(root - root[0]).T) * sk.unit_scale
    assert dist.max() < 15.0
    # the figure keeps moving (it travels and comes back, it is not frozen)
    step = np.hypot(*np.diff(root, axis=0).T) * sk.unit_scale * FPS
    np.testing.assert_allclose(step, 0.3, rtol=1e-6)
    # inside the radius nothing changes
    inside = dist < 4.0
    first_out = int(np.argmax(~inside))
    np.testing.assert_allclose(c[:first_out], p[:first_out], atol=1e-9)
    # the turning is smooth: at most 0.5 rad/s
    heading = np.unwrap(np.arctan2(*np.diff(root, axis=0).T[::-1]))
    assert np.abs(np.diff(heading)).max() * FPS <= 0.5 + 1e-6


def test_clean_up_keeps_bone_lengths():
    sk = get_skeleton("tang2018")
    p = _floating_drifting(sk, seconds=60.0, speed_m_s=0.5)
    c = clean_up(p, skeleton=sk, fps=FPS)
    for j, parent in enumerate(sk.parents):
        if parent >= 0:
            np.testing.assert_allclose(np.linalg.norm(c[:, j] - c[:, parent], axis=-1),
                                       np.linalg.norm(p[:, j] - p[:, parent], axis=-1), atol=1e-9)


# ------------------------------------------------------------------------------------------ the pipeline stage


def _dance_result(seconds: float, rng):
    from dancekit.motion.analysis import rest_pose
    from dancekit.pipelines import DanceResult

    sk = get_skeleton("tang2018")
    rest = rest_pose(sk)
    rest[:, 1] -= rest[:, 1].min()
    T = int(seconds * FPS) + 1
    t = np.arange(T) / FPS
    minima = np.cumsum(rng.uniform(0.5, 0.9, size=int(seconds)))  # speed minima every 0.5-0.9 s
    minima = minima[minima < seconds - 0.3]
    phase = np.interp(t, np.concatenate([[0], minima, [t[-1]]]), np.arange(len(minima) + 2))
    x = phase - np.sin(2 * np.pi * phase) / (2 * np.pi)
    p = np.repeat(rest[None], T, axis=0)
    p[:, 10:, 0] += 15.0 * x[:, None]  # the arms and legs sway; the root stays
    return DanceResult(motion=Motion(skeleton=sk, fps=FPS, positions=p.astype(np.float32)), model="synthetic", seed=0)


def test_pulse_clarity_separates_clicks_from_noise():
    from dancekit.audio.synth import click_track
    from dancekit.features.pulse import MIN_PULSE_CLARITY, song_beats

    sr = 22050
    clicks = song_beats(y=click_track(bpm=100.0, duration=12.0, sr=sr), sr=sr)
    noise = song_beats(y=np.random.default_rng(0).normal(scale=0.1, size=12 * sr).astype(np.float32), sr=sr)
    assert clicks.has_beat and clicks.clarity > 0.5 and abs(clicks.tempo - 100.0) < 2.0
    assert not noise.has_beat and noise.clarity < MIN_PULSE_CLARITY


def test_stage_warps_on_a_beat_and_leaves_a_beatless_song_alone(tmp_path):
    from dancekit.audio import save_wav
    from dancekit.audio.synth import click_track
    from dancekit.pipelines.stages import beat_sync, finish

    sr = 22050
    rng = np.random.default_rng(3)
    result = _dance_result(12.0, rng)
    clicks, noise = tmp_path / "clicks.wav", tmp_path / "noise.wav"
    save_wav(clicks, click_track(bpm=100.0, duration=12.04, sr=sr), sr=sr)
    save_wav(noise, rng.normal(scale=0.1, size=int(12.04 * sr)).astype(np.float32), sr=sr)
    left = beat_sync(result, noise)
    np.testing.assert_array_equal(left.motion.positions, result.motion.positions)
    assert "no clear beat" in left.summary()
    calm = beat_sync(dataclasses.replace(result, looks_like_music=False), clicks)  # the pipeline said: not music
    np.testing.assert_array_equal(calm.motion.positions, result.motion.positions)
    assert calm.notes[-1] == "not beat-synced"
    warped = beat_sync(result, clicks)
    import re

    found = re.fullmatch(r"beat-synced \((\d+) of (\d+) beats at (\d+) BPM\)", warped.summary())
    assert found and abs(int(found.group(3)) - 100) <= 2 and int(found.group(1)) >= 5
    assert warped.motion.num_frames == result.motion.num_frames
    from dancekit.metrics import beat_metrics
    from dancekit.pipelines.stages import song_beats_for

    beats = song_beats_for(clicks).times
    before = beat_metrics(result.motion.positions, beats, fps=FPS)
    after = beat_metrics(warped.motion.positions, beats, fps=FPS)
    assert after["bas_bailando"] > before["bas_bailando"] + 0.1
    # switched off, nothing changes; the clean-up alone is deterministic and keeps the frame count
    from dancekit.pipelines.config import StageConfig

    same = finish(result, clicks, StageConfig().switched(beat_sync=False, cleanup=False))
    np.testing.assert_array_equal(same.motion.positions, result.motion.positions)
    cleaned = finish(result, clicks, StageConfig().switched(beat_sync=False))
    assert cleaned.motion.num_frames == result.motion.num_frames and cleaned.notes == []


def test_warp_keeps_bone_lengths_of_a_positions_motion():
    from dancekit.motion.analysis import rest_pose
    from dancekit.motion.timewarp import warp_bones

    sk = get_skeleton("tang2018")
    rest = rest_pose(sk)
    T = 40
    angle = np.linspace(0, 3.0, T)  # the whole body turns 3 rad: 0.08 rad between frames
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    p = np.repeat(rest[None], T, axis=0)
    x, z = p[..., 0].copy(), p[..., 2].copy()
    p[..., 0], p[..., 2] = c * x - s * z, s * x + c * z
    frames = np.linspace(0, T - 1, 57)
    out = warp_bones(p, skeleton=sk, source_frames=frames)
    lerped = warp_frames(p, source_frames=frames)
    for j, parent in enumerate(sk.parents):
        if parent >= 0:
            want = np.linalg.norm(rest[j] - rest[parent])
            np.testing.assert_allclose(np.linalg.norm(out[:, j] - out[:, parent], axis=-1), want, atol=1e-9)
    # a plain lerp would shorten the long bones of the turning body; the positions stay close to it
    assert np.abs(out - lerped).max() < 0.5


def test_seed_distance_counts_the_seconds_until_seeds_converge():
    from dancekit.evaluation.stages import seed_distance
    from dancekit.motion.analysis import rest_pose

    sk = get_skeleton("tang2018")
    rest = rest_pose(sk)
    T = int(10 * FPS)

    def dance(arm_cm: np.ndarray, drift_cm: float = 0.0) -> Motion:
        p = np.repeat(rest[None], T, axis=0)
        wrist = sk.index("left_wrist")
        p[:, wrist, 0] += arm_cm
        p[:, :, 2] += drift_cm * np.arange(T)[:, None]  # travel does not count (poses relative to the root)
        return Motion(skeleton=sk, fps=FPS, positions=p.astype(np.float32))

    t = np.arange(T) / FPS
    J = sk.num_joints
    # song a: two seeds whose left wrist differs by 46 cm for the first 3 s, then not at all
    a0, a1 = dance(np.zeros(T)), dance(np.where(t < 3.0, 46.0, 0.0), drift_cm=2.0)
    # song b: the wrist 23 cm off throughout
    b0 = dance(np.full(T, 23.0))
    out = seed_distance({"a": [a0, a1], "b": [b0]})
    np.testing.assert_allclose(out["seed_cm"], [46.0 / J] * 3 + [0.0] * 7, atol=1e-4)
    np.testing.assert_allclose(out["song_cm"], [23.0 / J] * 10, atol=1e-4)
    assert out["converged_after_s"] == 3.0 and out["pairs"] == {"seed": 1, "song": 1}
    never = seed_distance({"a": [a0, dance(np.full(T, 46.0))], "b": [b0]})
    assert never["converged_after_s"] is None
    # two dances for each song: the songs are compared seed by seed, (a0, b0) 23 cm apart throughout and
    # (a1, b1) 46 cm for the first 3 s then 0, so the between-song curve is their mean; the first seed's
    # pair alone is kept as song_seed0_cm
    b1 = dance(np.zeros(T))
    both = seed_distance({"a": [a0, a1], "b": [b0, b1]})
    np.testing.assert_allclose(both["song_cm"], [34.5 / J] * 3 + [11.5 / J] * 7, atol=1e-4)
    np.testing.assert_allclose(both["song_seed0_cm"], [23.0 / J] * 10, atol=1e-4)
    assert both["pairs"] == {"seed": 2, "song": 2}
    # seed distance (b0, b1) is 23 cm throughout, (a0, a1) 46 cm then 0: mean 34.5 then 11.5, never below half
    np.testing.assert_allclose(both["seed_cm"], [34.5 / J] * 3 + [11.5 / J] * 7, atol=1e-4)
    assert both["converged_after_s"] is None


def test_song_beats_are_cached(tmp_path):
    from dancekit.audio import save_wav
    from dancekit.audio.synth import click_track
    from dancekit.features.pulse import song_beats_file

    sr = 22050
    song = tmp_path / "clicks.wav"
    save_wav(song, click_track(bpm=120.0, duration=6.0, sr=sr), sr=sr)
    first = song_beats_file(song, start=1.0, cache_dir=tmp_path / "cache")
    assert len(list((tmp_path / "cache").glob("*.beats.npz"))) == 1
    again = song_beats_file(song, start=1.0, cache_dir=tmp_path / "cache")
    np.testing.assert_array_equal(first.times, again.times)
    assert (first.tempo, first.clarity, first.has_beat) == (again.tempo, again.clarity, again.has_beat)
    fresh = song_beats_file(song, start=1.0, use_cache=False)
    np.testing.assert_array_equal(fresh.times, first.times)


def test_between_tolerance_prefers_the_chain_whose_unpaired_beat_lands_on_a_beat():
    # worked by hand (music beats 1, 2, 3 s; 4-s dance; ±15 % between pairs; candidates within 0.3 s):
    # candidates A(1, 1.02) B(2, 1.85) C(2, 2.18) D(3, 3.03). Feasible chains of two pairs: A-D (rates 1.02,
    # 1.005, 0.97) and C-D (rates 1.09, 0.85, 0.97); B pairs with nothing (to A 0.83, to D 1.18). Pairs only:
    # A-D, the gentler. With a landing tolerance of 0.1 s: A-D's step A→D puts the unpaired 1.85 and 2.18 at
    # 1 + 0.83/1.005 = 1.83 s and 1 + 1.16/1.005 = 2.15 s (0.17 and 0.15 s from a beat: misses), C-D's step
    # start→C puts the unpaired 1.02 at 1.02/1.09 = 0.94 s (0.06 s from the beat at 1 s: a hit) and 1.85 at
    # 1.70 s (a miss): C-D scores 2 + BETWEEN_WEIGHT, A-D 2.
    kin, mus = np.array([1.02, 1.85, 2.18, 3.03]), np.array([1.0, 2.0, 3.0])
    kw = {"kinematic": kin, "music": mus, "duration": 4.0, "pair_rate_change": 0.15, "max_shift": 0.3}
    np.testing.assert_allclose(match_beats(**kw), [[1.0, 1.02], [3.0, 3.03]])
    np.testing.assert_allclose(match_beats(**kw, between_tolerance=0.0), [[1.0, 1.02], [3.0, 3.03]])
    np.testing.assert_allclose(match_beats(**kw, between_tolerance=0.1), [[2.0, 2.18], [3.0, 3.03]])
    # a tolerance below the 0.064-s landing finds no hit: the pairs alone decide again
    np.testing.assert_allclose(match_beats(**kw, between_tolerance=0.05), [[1.0, 1.02], [3.0, 3.03]])
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError, match="between_tolerance"):
        match_beats(**kw, between_tolerance=-0.1)


def _beat_checkpoint(tmp_path, entry):
    import json

    folder = tmp_path / "m"
    folder.mkdir(exist_ok=True)
    (folder / "config.json").write_text(json.dumps({"model": "dual", **({"beat_sync": entry} if entry else {})}))
    return str(folder)


def test_the_beat_sync_stage_reads_its_settings_from_the_checkpoint(tmp_path):
    """A checkpoint's ``"beat_sync"`` entry reaches the warp: with candidates at most 1 ms from a beat no
    movement beat is paired and the dance is left as it was, where the defaults warp it. Revolution and
    the style classifier carry no entry; dual and music2dance do (test below)."""
    from pathlib import Path

    from dancekit.audio import save_wav
    from dancekit.audio.synth import click_track
    from dancekit.pipelines import stages
    from dancekit.pipelines.config import BeatSyncConfig, read_stage_config

    sr = 22050
    result = _dance_result(12.0, np.random.default_rng(3))
    clicks = tmp_path / "clicks.wav"
    save_wav(clicks, click_track(bpm=100.0, duration=12.04, sr=sr), sr=sr)
    config = read_stage_config(_beat_checkpoint(tmp_path, None)).switched(cleanup=False)
    plain = stages.finish(result, clicks, config)
    assert plain.summary().startswith("beat-synced (")
    near = read_stage_config(_beat_checkpoint(tmp_path, {"max_shift": 0.001, "max_rate_change": 0.2}))
    assert near.beat_sync.warp_options() == {"max_shift": 0.001, "max_rate_change": 0.2}
    kept = stages.finish(result, clicks, near.switched(cleanup=False))
    assert "not beat-synced: no movement beat" in kept.summary()
    np.testing.assert_array_equal(kept.motion.positions, result.motion.positions)
    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    assert read_stage_config(folder / "revolution").beat_sync == BeatSyncConfig()
    flag = read_stage_config(_beat_checkpoint(tmp_path, {"step_pairing": False, "max_rate_step": 0.03}))
    assert flag.beat_sync.warp_options() == {"step_pairing": False, "max_rate_step": 0.03}


@pytest.mark.parametrize("entry", [{"max_rate_change": 1.2}, {"pair_rate_change": 0.0}, {"pair_rate_change": 0.2},
                                   {"max_rate_change": 0.3, "pair_rate_change": 0.35}, {"max_shift": -1.0},
                                   {"smooth_s": 0.0}, {"between_tolerance": -0.1}, {"max_shift": "far"},
                                   {"max_rate_step": 0.0}, {"max_rate_step": float("inf")}, {"step_pairing": 1},
                                   {"max_rate_change": True}, {"speed": 1.0}, [0.2]])
def test_a_bad_beat_sync_entry_is_a_checkpoint_error(tmp_path, entry):
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.config import read_stage_config

    with pytest.raises(CheckpointError, match="config.json.*beat_sync"):
        read_stage_config(_beat_checkpoint(tmp_path, entry))


@pytest.mark.parametrize("name", ["dual", "music2dance"])
def test_the_embedded_dual_and_music2dance_beat_sync_entries_are_read(name):
    """The embedded dual and music2dance carry a ``"beat_sync"`` entry (chosen on validation, docs/STAGES.md):
    it is in the stage configuration the loaded pipeline gives ``stages.finish``, its
    rates are in (0, 1) with the pair bound at most the speed bound, and it widens the default ±15 % bound."""
    from dancekit.motion import timewarp
    from dancekit.pipelines import load_pipeline

    spec = load_pipeline(name).stage_options().beat_sync.warp_options()
    assert {"max_rate_change", "pair_rate_change"} <= set(spec)
    assert 0 < spec["pair_rate_change"] <= spec["max_rate_change"] < 1
    assert spec["max_rate_change"] > timewarp.DEFAULT_MAX_RATE_CHANGE
    assert spec.get("between_tolerance", 0.0) >= 0


def test_plausible_jitter_cap_is_the_scale_times_the_smallest_real_jitter_of_the_plausible_genres():
    """Worked by hand: p = (0.5, 0.4, 0.1) over (chacha, rumba, waltz), ρ = 0.7 → plausible {chacha (0.5 ≥ 0.35),
    rumba (0.4 ≥ 0.35)} → 1.5 × min(0.14, 0.05); ρ = 0.1 adds waltz → 1.5 × 0.026; a genre not in the table is
    skipped; no posterior, no plausible genre in the table: None."""
    from dancekit.errors import ParameterError
    from dancekit.pipelines.config import GenreStats, JitterCapConfig, StageConfig
    from dancekit.pipelines.stages import plausible_jitter_cap

    table = {"waltz": 0.026, "rumba": 0.05, "chacha": 0.14}
    probs = {"chacha": 0.5, "rumba": 0.4, "waltz": 0.1}
    assert plausible_jitter_cap(probs, genre_jitter=table, scale=1.5, min_ratio=0.7) == pytest.approx(0.075)
    assert plausible_jitter_cap(probs, genre_jitter=table, scale=1.5, min_ratio=0.1) == pytest.approx(0.039)
    assert plausible_jitter_cap({"tango": 0.9, "chacha": 0.1}, genre_jitter=table, scale=1.0,
                                min_ratio=0.5) is None
    assert plausible_jitter_cap({}, genre_jitter=table, scale=1.0, min_ratio=0.5) is None
    entry = JitterCapConfig(scale=2)
    assert (entry.scale, entry.min_ratio, entry.after_lock, entry.to_end) == (2.0, 0.5, False, False)
    for bad in ({"scale": True}, {"scale": 0}, {"min_ratio": -0.1}, {"after_lock": "true"}, {"scale": "1.5"}):
        with pytest.raises(ParameterError, match=r"stages\.jitter_cap\." + next(iter(bad))):
            JitterCapConfig(**bad)
    with pytest.raises(ParameterError, match="genre_stats.jitter"):  # a cap needs the real jitters
        StageConfig(jitter_cap=JitterCapConfig(), genre_stats=GenreStats())
    with pytest.raises(ParameterError, match="genre_stats.jitter"):
        GenreStats(jitter={"waltz": 0.0})
