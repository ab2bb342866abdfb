"""audio/arrange.py and pipelines/compose.py: music that follows a dance (its tempo, beats, metre; chords of one
key changing on bars; bass and drums on the pulse). Known answers from synthetic pulses and dances."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pretty_midi")

from dancekit.audio.arrange import (  # noqa: E402
    beat_curve,
    comb_period,
    dance_pulse,
    follow_dance,
    key_scale,
    key_triads,
    lock_beats,
    pulse_metre,
    pulse_tempo,
    track_beats,
)
from dancekit.errors import ParameterError  # noqa: E402

FPS = 25.0


def _pulse(bpm, seconds=40.0, *, accent_every=None, phase=0.37, noise=0.05, seed=0, width=0.03):
    """A pulse curve with a Gaussian bump (σ ``width`` s) every 60 / bpm s from ``phase`` (not whole frames), the
    first of every ``accent_every`` beats twice as high, plus noise; returns (pulse, beat times)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    beats = np.arange(phase, seconds, 60.0 / bpm)
    height = np.ones(len(beats))
    if accent_every:
        height[::accent_every] = 2.0
    p = (height[None] * np.exp(-0.5 * ((t[:, None] - beats[None]) / width) ** 2)).sum(1)
    return np.maximum(p + rng.normal(0, noise, len(t)), 0.0), beats


@pytest.mark.parametrize("bpm", [84.0, 101.0, 126.0])
def test_tempo_and_beats_of_a_known_pulse(bpm):
    from dancekit.metrics.music_beats import beat_f1

    p, truth = _pulse(bpm)
    assert pulse_tempo(p, fps=FPS, fold_from=None) == pytest.approx(bpm, rel=0.02)
    frames = track_beats(p, fps=FPS, bpm=bpm)
    times = lock_beats(frames, fps=FPS, period=60.0 / bpm)
    assert beat_f1(times, truth, tolerance=0.05) > 0.95
    # locked to the tempo: the tracked frames are whole frames, their phase wanders within a frame; it is held
    assert np.median(np.diff(times)) == pytest.approx(60.0 / bpm, abs=1e-9)
    assert np.mean(np.abs(np.diff(times) - 60.0 / bpm) < 1e-9) > 0.8


def test_the_prior_picks_the_metrical_level():
    """A pulse with a bump on every beat at 60 BPM and a weaker one halfway: 120 BPM is there too; a prior
    centred on 60 reads 60, one centred on 120 reads 120."""
    p, _ = _pulse(60.0)
    half, _ = _pulse(60.0, phase=0.87, seed=1)
    both = p + 0.6 * half
    kw = {"fps": FPS, "prior_octaves": 0.5, "fold_from": None}
    assert pulse_tempo(both, prior_bpm=60.0, **kw) == pytest.approx(60.0, rel=0.02)
    assert pulse_tempo(both, prior_bpm=120.0, **kw) == pytest.approx(120.0, rel=0.02)


@pytest.mark.parametrize("bpm, folded", [(60.0, 120.0), (101.0, 101.0), (180.0, 90.0)])
def test_the_octave_rule_folds_into_86_to_172(bpm, folded):
    p, _ = _pulse(bpm, width=0.06)  # (bumps narrower than a frame alias at 180 BPM: 3 beats are 25 frames)
    assert pulse_tempo(p, fps=FPS) == pytest.approx(folded, rel=0.02)  # the default rule: [86, 172) BPM


def _bars(bar, steps, seconds=60.0, *, start=0.23, noise=0.05, seed=0, width=0.05):
    """A pulse with a bump (σ ``width`` s) at each of ``steps`` (s from the bar's start) in every bar of ``bar`` s,
    plus noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FPS)) / FPS
    b = np.concatenate([k * bar + np.asarray(steps) for k in range(int(seconds / bar) + 1)]) + start
    b = b[b < seconds]
    return np.maximum(np.exp(-0.5 * ((t[:, None] - b[None]) / width) ** 2).sum(1) + rng.normal(0, noise, len(t)), 0.0)


@pytest.mark.parametrize("steps", [(0.0, 0.74, 1.36), (0.0, 0.6, 1.3)])
def test_the_comb_reads_the_tempo_of_uneven_steps_from_their_bars(steps):
    """Three uneven steps to a 2-s bar (a waltz's long first step): the beat is 2 / 3 s, 90 BPM. The single
    autocorrelation peak sits between the step intervals (off by more than 1 %); the comb over the multiples of the
    period, whose every third one is a whole bar, reads 90 BPM."""
    p = _bars(2.0, steps)
    assert abs(pulse_tempo(p, fps=FPS, fold_from=None, comb_seconds=0) / 90.0 - 1) > 0.01
    assert pulse_tempo(p, fps=FPS, fold_from=None) == pytest.approx(90.0, rel=0.005)


def test_lock_beats_keeps_the_period_and_follows_the_phase():
    """Tracked frames of a 0.6-s pulse (15 frames at 25 fps) whose phase moves by 2 frames at beat 10, with one
    beat tracked a frame early, one missing and one doubled: the locked beats are every 0.6 s, phased on the
    median of ±1 beat (the lone early beat is outvoted), the missing beat filled and the double dropped."""
    period = 0.6
    frames = [5 + 15 * k for k in range(10)] + [7 + 15 * k for k in range(10, 20)]
    frames[4] -= 1  # one beat a frame early
    del frames[15]  # one beat not tracked
    frames.insert(7, frames[6] + 1)  # a second beat one frame after beat 6
    times = lock_beats(np.array(frames), fps=FPS, period=period)
    # (at the step, beats 8-10 have two beats of the old phase, beats 9-11 two of the new one)
    want = np.array([0.2 + period * k for k in range(10)] + [0.28 + period * k for k in range(10, 20)])
    np.testing.assert_allclose(times, want, atol=1e-9)
    np.testing.assert_allclose(np.diff(times)[:9], period, atol=1e-9)
    # with max_shift the phase moves at most 0.1 period (0.06 s) a beat: after the 0.08-s step it is 0.02 s behind,
    # within a frame of the dance's phase, where it holds
    slow = lock_beats(np.array(frames), fps=FPS, period=period, max_shift=0.1)
    assert np.abs(np.diff(slow) - period).max() <= 0.1 * period + 1e-9
    np.testing.assert_allclose(slow[:10], want[:10], atol=1e-9)
    np.testing.assert_allclose(slow[10:] - want[10:], -0.02, atol=1e-9)
    with pytest.raises(ParameterError, match="period"):
        lock_beats(np.array(frames), fps=FPS, period=0.0)
    with pytest.raises(ParameterError, match="max_shift"):
        lock_beats(np.array(frames), fps=FPS, period=period, max_shift=0.5)


def test_comb_period_of_a_known_autocorrelation():
    """An autocorrelation with peaks at every multiple of 17.3 frames (and nothing else): from a start 5 % off,
    the comb finds 17.3 within its step; with no multiple inside the curve it returns the start."""
    lags = np.arange(300.0)
    acf = np.exp(-0.5 * ((lags[:, None] - 17.3 * np.arange(1, 18)[None]) / 1.0) ** 2).sum(1)
    assert comb_period(acf, 18.2, span=0.08, max_lag=200.0) == pytest.approx(17.3, abs=0.02)
    assert comb_period(acf[:10], 18.2, span=0.08, max_lag=200.0) == 18.2


def test_beat_curve_has_a_unit_bump_at_each_beat():
    c = beat_curve(np.array([1.0, 2.0, 2.04]), num_frames=100, fps=FPS, width=0.04)
    assert c[25] == pytest.approx(1.0 + 2 * np.exp(-0.5 * (1.0 / 0.04) ** 2))  # on the frame of the first beat
    assert c[50] == pytest.approx(1.0 + np.exp(-0.5))  # 2.00 s, and 2.04 s one σ away
    assert c[:15].max() == 0.0 and c[75:].max() == 0.0  # nothing beyond 5 σ of a beat
    assert beat_curve(np.zeros(0), num_frames=10, fps=FPS).max() == 0.0
    with pytest.raises(ParameterError, match="width"):
        beat_curve(np.ones(1), num_frames=10, fps=FPS, width=0.0)


@pytest.mark.parametrize("metre", [3, 4])
def test_metre_of_an_accented_pulse(metre):
    p, _ = _pulse(96.0, accent_every=metre)
    assert pulse_metre(p, fps=FPS, bpm=96.0) == metre


def test_dance_pulse_peaks_at_the_speed_minima():
    t = np.arange(400) / FPS
    speed = 50.0 + 30.0 * np.cos(2 * np.pi * t / 0.6)  # minima at 0.3 + 0.6 k s
    p = dance_pulse(speed, fps=FPS, window=1.2)
    peaks = np.flatnonzero((p[1:-1] > p[:-2]) & (p[1:-1] >= p[2:])) + 1
    inner = peaks[(peaks > 30) & (peaks < 370)] / FPS
    np.testing.assert_allclose((inner - 0.3) / 0.6, np.round((inner - 0.3) / 0.6), atol=0.05)
    assert p.min() >= 0.0


@pytest.mark.parametrize("key", [(0, False), (9, True), (8, True), (6, False)])
def test_every_chord_is_in_the_printed_key_and_changes_only_on_bars(key):
    """Whatever the composed chroma says, every note of the piano and the bass is in the key's scale; the
    chord changes only on a bar's first beat; drums and bass play on every beat."""
    p, truth = _pulse(110.0, accent_every=4)
    rng = np.random.default_rng(key[0])
    chroma = rng.random((len(p), 12)) ** 4  # a random composed chroma
    act = rng.random(len(p))
    arr = follow_dance(p, fps=FPS, key=key, chroma=chroma, activation=act)
    scale = key_scale(*key)
    piano, bass, drums = arr.midi.instruments
    assert {n.pitch % 12 for n in piano.notes} <= scale and {n.pitch % 12 for n in bass.notes} <= scale
    assert all(c in key_triads(*key) for c in arr.bar_chords)
    assert arr.key_name().split()[1] == ("minor" if key[1] else "major")
    assert arr.beats_per_bar == 4
    downbeats = {round(n.start, 6) for n in drums.notes if n.pitch == 36}
    for i in range(1, len(arr.chords)):
        if arr.chords[i] != arr.chords[i - 1]:
            assert round(arr.beat_times[i], 6) in downbeats  # a change happens on a kick (a bar's first beat)
    assert len(set(arr.bar_chords)) > 1  # the random chroma does move the chords
    assert arr.bar_chords[0] == arr.bar_chords[-1] == key_triads(*key)[0]  # tonic first and last
    onsets = sorted({round(n.start, 6) for n in bass.notes})
    np.testing.assert_allclose(onsets, arr.beat_times, atol=1e-6)
    assert len([n for n in drums.notes if n.pitch == 42]) == len(arr.beat_times)
    assert arr.tempo == pytest.approx(110.0, rel=0.02)


def test_the_composed_chroma_chooses_the_bar_chord():
    """Chroma of F major over bars 2-3 and of A minor over bars 4-5 in C major: those bars get IV and vi."""
    p, _ = _pulse(120.0, seconds=20.0, accent_every=4, phase=0.0)
    arr = follow_dance(p, fps=FPS, key=(0, False), bpm=120.0, beats_per_bar=4, chroma=None)
    starts = [arr.beat_times[i] for i in range(len(arr.chords)) if i == 0 or i % 4 == 0]
    chroma = np.full((len(p), 12), 0.1)
    for b, pcs in ((2, [5, 9, 0]), (3, [5, 9, 0]), (4, [9, 0, 4]), (5, [9, 0, 4])):
        a, z = int(round(starts[b] * FPS)), int(round(starts[b + 1] * FPS))
        chroma[a:z, pcs] = 1.0
    arr = follow_dance(p, fps=FPS, key=(0, False), bpm=120.0, beats_per_bar=4, chroma=chroma)
    assert arr.bar_chords[2:6] == [(5, False), (5, False), (9, True), (9, True)]


def test_accents_follow_the_activation():
    p, _ = _pulse(100.0, seconds=20.0, accent_every=4)
    act = np.zeros(len(p))
    act[: len(p) // 2] = 1.0  # G_D→M's beats strong in the first half only
    arr = follow_dance(p, fps=FPS, key=(0, False), activation=act, beats_per_bar=4)
    hats = sorted((n.start, n.velocity) for n in arr.midi.instruments[2].notes if n.pitch == 42)
    first = [v for t, v in hats if t < 0.45 * len(p) / FPS]
    second = [v for t, v in hats if t > 0.55 * len(p) / FPS]
    assert min(first) > max(second)
    piano_first = [n for n in arr.midi.instruments[0].notes if n.start < 0.45 * len(p) / FPS]
    piano_second = [n for n in arr.midi.instruments[0].notes if n.start > 0.55 * len(p) / FPS]
    assert len(piano_first) > 2 * len(piano_second)  # the weak half: the piano on the downbeats only


def test_rendered_music_is_tracked_at_the_dance_tempo():
    """Listen-free check: librosa's beat tracker on the rendered WAV finds the arranged beats (F1 ≥ 0.9) and
    the tempo (±5 %)."""
    import librosa

    from dancekit.audio.midi import render
    from dancekit.metrics.music_beats import beat_f1

    p, _ = _pulse(92.0, seconds=20.0, accent_every=3)
    arr = follow_dance(p, fps=FPS, key=(7, False), chroma=np.random.default_rng(0).random((len(p), 12)))
    assert arr.beats_per_bar == 3
    y, _ = render(arr.midi, sr=22050, backend="builtin")
    tempo, frames = librosa.beat.beat_track(y=y.astype(np.float64), sr=22050, units="frames")
    tracked = librosa.frames_to_time(frames, sr=22050)
    assert beat_f1(tracked, arr.beat_times, min_beat_time=2.0) >= 0.9
    assert float(np.atleast_1d(tempo)[0]) == pytest.approx(92.0, rel=0.05)


def test_flat_pulse_and_bad_input():
    arr = follow_dance(np.zeros(100), fps=FPS, key=(0, False))
    assert arr.tempo == pytest.approx(120.0)
    assert np.isnan(pulse_tempo(np.zeros(400), fps=FPS))
    with pytest.raises(ParameterError, match="chroma"):
        follow_dance(np.ones(10), fps=FPS, key=(0, False), chroma=np.zeros((10, 11)))
    with pytest.raises(ParameterError, match="beats_per_bar"):
        follow_dance(np.ones(10), fps=FPS, key=(0, False), beats_per_bar=5)
    with pytest.raises(ParameterError, match="tempo"):
        follow_dance(np.ones(10), fps=FPS, key=(0, False), bpm=5.0)


def test_compose_pipeline_follows_a_stepping_dance(tmp_path):
    """A dance whose ankles plant every 0.6 s (100 BPM) in bars of 4 (a deeper plant on every 4th step):
    ``compose`` at its default reads 100 BPM, 4 beats to a bar, and its beats fall on the plants."""
    from dancekit.metrics.music_beats import beat_f1
    from dancekit.motion import Motion, get_skeleton
    from dancekit.pipelines.compose import follow

    sk = get_skeleton("tang2018")
    T = int(30 * FPS)
    t = np.arange(T) / FPS
    plants = np.arange(0.45, 30.0, 0.6)
    depth = np.where(np.arange(len(plants)) % 4 == 0, 1.0, 0.6)
    speed = 1.0 - (depth[None] * np.exp(-0.5 * ((t[:, None] - plants[None]) / 0.06) ** 2)).sum(1)  # dips at plants
    x = np.cumsum(speed) / FPS * 20.0  # the ankles travel forward at that speed
    pos = np.zeros((T, sk.num_joints, 3), np.float32)
    pos[:, :, 1] = 50.0 + np.arange(sk.num_joints)
    for j in (sk.index("left_ankle"), sk.index("right_ankle")):
        pos[:, j, 0] = x
    arr = follow(Motion(skeleton=sk, fps=FPS, positions=pos), key=(2, True))
    assert arr.tempo == pytest.approx(100.0, rel=0.03) and arr.beats_per_bar == 4
    assert beat_f1(arr.beat_times, plants, tolerance=0.08) > 0.9


def test_compose_pipeline_reads_the_tempo_and_metre_of_an_uneven_waltz_step():
    """A synthetic waltz: the ankles plant three times a bar of 2 s at uneven times (0, 0.74, 1.36 s: a long first
    step), the first plant deepest. The known answer is 90 BPM (three beats to 2 s) in bars of 3, and the beats
    follow the plants (the kinematic beats) within the tolerance of the music scores."""
    from dancekit.metrics.music_beats import beat_f1
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.analysis import kinematic_beats
    from dancekit.pipelines.compose import follow

    sk = get_skeleton("tang2018")
    T = int(40 * FPS)
    t = np.arange(T) / FPS
    plants = np.concatenate([k * 2.0 + np.array([0.0, 0.74, 1.36]) for k in range(20)]) + 0.3
    plants = plants[plants < 39.5]
    depth = np.where(np.arange(len(plants)) % 3 == 0, 1.0, 0.6)
    speed = 1.0 - (depth[None] * np.exp(-0.5 * ((t[:, None] - plants[None]) / 0.06) ** 2)).sum(1)
    x = np.cumsum(speed) / FPS * 20.0
    pos = np.zeros((T, sk.num_joints, 3), np.float32)
    pos[:, :, 1] = 50.0 + np.arange(sk.num_joints)
    for j in (sk.index("left_ankle"), sk.index("right_ankle")):
        pos[:, j, 0] = x
    motion = Motion(skeleton=sk, fps=FPS, positions=pos)
    arr = follow(motion, key=(7, False))
    assert arr.tempo == pytest.approx(90.0, rel=0.01) and arr.beats_per_bar == 3
    kb = kinematic_beats(motion.to_positions(), fps=FPS)
    assert beat_f1(arr.beat_times, kb, tolerance=0.1) > 0.75
    # the beats are tracked on the kinematic beats, every one a bump of the same height (not on how deep the dip is)
    from dancekit.pipelines.compose import phase_pulse_of

    curve = phase_pulse_of(motion)
    frames = np.round(kb * FPS).astype(int)
    np.testing.assert_allclose(curve[frames], 1.0, atol=1e-3)
    assert len(kb) >= len(plants) - 2 and curve.max() == pytest.approx(1.0, abs=1e-3)


def test_a_given_tempo_is_kept_exactly_and_phased_on_the_pulse():
    p, truth = _pulse(100.0, seconds=20.0, phase=0.21)
    arr = follow_dance(p, fps=FPS, key=(0, False), bpm=100.0)
    assert arr.tempo == pytest.approx(100.0, rel=1e-9)
    np.testing.assert_allclose(np.diff(arr.beat_times), 0.6, atol=1e-9)
    assert abs(arr.beat_times[0] - 0.21) <= 0.5 / FPS  # phased on the pulse's bumps
