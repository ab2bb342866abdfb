"""The beat warp's bound on the rate's change per frame (``max_rate_step``, issue 15: no visible speed jumps).

Known answers built independently of the solver: a rate profile drawn by hand (1, a ramp up at exactly
``δ`` per frame to 1.3, a hold, a ramp down at ``δ`` to 0.7, a hold, a ramp back to 1), its source frames
by a cumulative sum, and beat pairs read off it every 15 frames (0.6 s). A warp through those pairs with
steps ≤ ``δ`` exists by construction (the profile), so with the bound every pair must land; without it the
smoothest warp changes its rate faster than ``δ`` (the bound has work to do). And pairs that ask for ±30 %
every half second, which no warp with 2 %/frame steps can land (half a second is 12.5 frames: at most 0.25
of rate change, not 0.6).
"""

from __future__ import annotations

import numpy as np
import pytest

from dancekit.errors import ParameterError
from dancekit.motion.timewarp import DEFAULT_MAX_RATE_STEP, beat_warp, warp_rates

FPS = 25.0
T = 501


def _profile_pairs(delta: float) -> np.ndarray:
    """(P, 2) pairs (music s, kinematic s) read every 15 frames off a hand-drawn rate with steps of ``delta``."""
    up, down = np.arange(1, round(0.3 / delta) + 1), np.arange(1, round(0.6 / delta) + 1)
    profile = np.concatenate([np.ones(100), 1 + delta * up, np.full(20, 1.3), 1.3 - delta * down, np.full(20, 0.7),
                              0.7 + delta * up])
    rate = np.ones(T - 1)
    rate[: len(profile)] = profile
    assert rate.sum() == pytest.approx(T - 1) and np.abs(np.diff(rate)).max() <= delta + 1e-12
    source = np.concatenate([[0.0], np.cumsum(rate)])
    frames = np.arange(100, len(profile) + 1, 15)
    return np.stack([frames / FPS, source[frames] / FPS], axis=1)


def _check_warp(s: np.ndarray, bound: float) -> np.ndarray:
    """The warp's frame-to-frame rate changes, after checking its ends and rate box."""
    rate = np.diff(s)
    assert len(s) == T and s[0] == 0 and s[-1] == pytest.approx(T - 1, abs=1e-6)
    assert rate.min() >= 1 - bound - 1e-9 and rate.max() <= 1 + bound + 1e-9
    return np.abs(np.diff(rate))


@pytest.mark.parametrize("delta", [0.02, 0.01])
def test_the_step_bound_caps_a_jumping_rate_and_the_pairs_still_land(delta):
    pairs = _profile_pairs(delta)
    # without the bound and with a short smoothing the rate changes faster than delta (the bound has work to do)
    free = warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_change=0.35, smooth_s=0.1, max_rate_step=None)
    assert _check_warp(free, 0.35).max() > delta * 1.1
    s = warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_change=0.35, smooth_s=0.1, max_rate_step=delta)
    assert _check_warp(s, 0.35).max() <= delta + 1e-9
    at = np.interp(pairs[:, 0] * FPS, np.arange(T), s)
    np.testing.assert_allclose(at, pairs[:, 1] * FPS, atol=0.05)  # feasible: every pair lands


def test_the_default_step_bound_is_two_percent_per_frame_and_applies():
    pairs = _profile_pairs(0.02)
    assert DEFAULT_MAX_RATE_STEP == 0.02
    s = warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_change=0.35, smooth_s=0.1)
    assert _check_warp(s, 0.35).max() <= 0.02 + 1e-9


def test_pairs_the_step_bound_cannot_land_are_dropped_and_the_bounds_hold():
    m = np.arange(0.5, 19.6, 0.5)
    k = np.cumsum(np.where(np.arange(len(m)) % 2 == 0, 0.5 * 1.3, 0.5 * 0.7))  # ±30 % every half second
    pairs = np.stack([m, k], axis=1)
    s = warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_change=0.35, max_rate_step=0.02)
    assert _check_warp(s, 0.35).max() <= 0.02 + 1e-9
    # unbounded, the same pairs land (within half a frame: the box is tight) and the rate swings by more than 0.1 a frame
    free = warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_change=0.35, max_rate_step=None)
    np.testing.assert_allclose(np.interp(m * FPS, np.arange(T), free), k * FPS, atol=0.5)
    assert _check_warp(free, 0.35).max() > 0.1


def test_beat_warp_reports_only_the_pairs_it_lands():
    # a dance whose speed minima ask for ±30 % every half second against beats every half second
    m = np.arange(0.5, 19.6, 0.5)
    kin = np.cumsum(np.where(np.arange(len(m)) % 2 == 0, 0.5 * 1.3, 0.5 * 0.7))
    t = np.arange(T) / FPS
    knots_t = np.concatenate([[0.0], kin, [(T - 1) / FPS]])
    phase = np.interp(t, knots_t, np.arange(len(knots_t)))
    x = phase - np.sin(2 * np.pi * phase) / (2 * np.pi)  # speed 1 - cos 2πφ: zero at every kinematic beat
    p = np.zeros((T, 2, 3))
    p[:, :, 0] = 20.0 * x[:, None]
    p[:, 1, 1] = 10.0
    for step in (None, 0.02):
        source, pairs = beat_warp(p, music_beats=m, fps=FPS, max_rate_change=0.35, pair_rate_change=0.33,
                                  smooth=0, max_rate_step=step)
        if len(pairs):
            at = np.interp(pairs[:, 0] * FPS, np.arange(T), source)
            assert np.abs(at - pairs[:, 1] * FPS).max() <= 0.5
        if step is not None:
            assert np.abs(np.diff(source, 2)).max() <= step + 1e-9


@pytest.mark.parametrize("step", [0.0, -0.01, float("nan"), float("inf")])
def test_a_bad_step_bound_is_a_parameter_error(step):
    pairs = _profile_pairs(0.02)
    with pytest.raises(ParameterError, match="max_rate_step"):
        warp_rates(pairs=pairs, n_frames=T, fps=FPS, max_rate_step=step)


def test_the_pairing_skips_a_chain_the_step_bound_cannot_follow():
    # music beats at 0.5 and 1.0 s; kinematic beats at 0.65 and 1.0 s: the chain of both needs a mean rate of
    # 1.3 over the first half second, then 0.7 over the next (a change of 0.6). At 2 %/frame and 25 fps the
    # rate moves at most 0.5 per second: 0.25 between two half-second steps (a ramp across both). Without the
    # check both pairs are taken; with it only one, the one on the identity (rate 1, the gentlest)
    from dancekit.motion.timewarp import match_beats

    kw = dict(kinematic=np.array([0.65, 1.0]), music=np.array([0.5, 1.0]), duration=3.0, pair_rate_change=0.33,
              max_shift=0.6)
    np.testing.assert_allclose(match_beats(**kw), [[0.5, 0.65], [1.0, 1.0]])
    np.testing.assert_allclose(match_beats(**kw, max_rate_step=0.02, fps=FPS), [[1.0, 1.0]])
    # a slower step bound of 0.05/frame (1.25 per second: 0.625 between the steps) lets both through
    np.testing.assert_allclose(match_beats(**kw, max_rate_step=0.05, fps=FPS), [[0.5, 0.65], [1.0, 1.0]])
    with pytest.raises(ParameterError, match="fps"):
        match_beats(**kw, max_rate_step=0.02)



def _stepping_dance(period: int, n_frames: int) -> np.ndarray:
    """(T, 2, 3) a dance that stops dead every ``period`` frames from frame ``period`` on, and nowhere else: the
    joints travel ``x = φ - sin(2πφ) / 2π`` with the phase φ = frame / period (speed ∝ 1 - cos 2πφ)."""
    phase = np.arange(n_frames) / period
    x = phase - np.sin(2 * np.pi * phase) / (2 * np.pi)
    p = np.zeros((n_frames, 2, 3))
    p[:, :, 0] = 20.0 * x[:, None]
    p[:, 1, 1] = 10.0
    return p


def test_the_warp_puts_each_stop_of_the_dance_on_its_music_beat_frame():
    """Known answer: a dance that stops every 13 frames (frames 13, 26, ..., 195) against music beats every 12
    frames (frames 12, 24, ..., 192): the beats are 8 % faster than the steps, inside every rate bound, and stop
    j is within 0.6 s of beat j, so the warp pairs most of them. The reported pairs must be given beat times and
    built stops, and the warped dance must stop on the paired beats' frames themselves (its speed minima,
    no smoothing). A beat moved by one frame anywhere in the warp lands the stops a frame off."""
    from dancekit.motion.analysis import kinematic_beats
    from dancekit.motion.timewarp import warp_frames

    n = 201
    stops = np.arange(13, n - 1, 13) / FPS  # 15 stops
    beats = np.arange(12, n - 1, 12) / FPS  # 16 beats
    p = _stepping_dance(13, n)
    np.testing.assert_allclose(kinematic_beats(p, fps=FPS, smooth=0), stops, atol=1e-9)  # the stops, as built
    source, pairs = beat_warp(p, music_beats=beats, fps=FPS, smooth=0)
    # the pairs: given beat times with built stops (exactly), increasing in both, most of the 15 stops
    assert len(pairs) >= 10 and np.all(np.diff(pairs, axis=0) > 0)
    assert np.abs(pairs[:, :1] - beats[None, :]).min(axis=1).max() < 1e-9
    assert np.abs(pairs[:, 1:] - stops[None, :]).min(axis=1).max() < 1e-9
    # the warped dance stops on the paired beats' frames
    landed = np.rint(kinematic_beats(warp_frames(p, source_frames=source), fps=FPS, smooth=0) * FPS).astype(int)
    want = np.rint(pairs[:, 0] * FPS).astype(int)
    assert set(want) <= set(landed), (sorted(set(want) - set(landed)), landed)
