"""Known-answer tests of the dance-to-music rhythm scores (dancekit.metrics.music_beats).

The expected bin counts are worked out by hand in the comments (1-s bins, bin i = [i, i + 1) s of
its clip), not by the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dancekit.audio.synth import beat_times, click_track
from dancekit.errors import ParameterError
from dancekit.metrics.music_beats import (
    beat_f1,
    clicks_on,
    clip_bin_counts,
    coverage_hit,
    coverage_hit_audio,
    coverage_hit_scores,
    dense_clicks,
    metronome,
    onset_bins,
    onset_times,
    tempo_error,
    tempo_from_beats,
    tempo_hit,
    wrong_tempo_metronome,
)

NAN = float("nan")


def same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, abs=1e-12)


# 120 BPM from 0.1 s over 10 s: clicks 0.1, 0.6, 1.1, 1.6, ..., 9.6 -> two per second, every 1-s bin has one.
CLICKS_120 = 0.1 + 0.5 * np.arange(20)
# 40 BPM from 0.2 s over 10 s: 0.2, 1.7, 3.2, 4.7, 6.2, 7.7, 9.2 -> bins 0, 1, 3, 4, 6, 7, 9 (7 of 10).
CLICKS_40 = 0.2 + 1.5 * np.arange(7)


def test_onset_bins_by_hand():
    # 0.0 -> 0, 0.99 -> 0, 1.0 -> 1, 2.5 -> 2, 3.2 is past the 3.2-s span; 4 bins (the last one partial)
    bins = onset_bins([0.0, 0.99, 1.0, 2.5, 3.2, -0.1], duration=3.2)
    assert bins.tolist() == [True, True, True, False]


def test_click_track_against_itself_dense():
    # whole track: R = G = H = 10; 2-s clips: five clips of R = G = H = 2
    assert clip_bin_counts(CLICKS_120, CLICKS_120, duration=10).tolist() == [[10, 10, 10]]
    counts = clip_bin_counts(CLICKS_120, CLICKS_120, duration=10, clip_length=2)
    assert counts.tolist() == [[2, 2, 2]] * 5
    a = coverage_hit_scores(counts, protocol="A")
    assert a == {"bcs": 1.0, "bhs": 1.0, "n_clips": 5}
    b = coverage_hit_scores(counts, protocol="B")
    assert b == {"bcs": 1.0, "bhs": 1.0, "csd": 0.0, "hsd": 0.0, "f1": 1.0, "n_clips": 5}


def test_click_track_against_itself_sparse():
    # 40 BPM over 10 s: bins 0, 1, 3, 4, 6, 7, 9 of 10 (whole). 2-s clips: [0,2) 0.2, 1.7 -> 2 bins;
    # [2,4) 3.2 -> 1; [4,6) 4.7 -> 1; [6,8) 6.2, 7.7 -> 2; [8,10) 9.2 -> 1. Every ratio is 1 (not 7/10).
    assert onset_bins(CLICKS_40, duration=10).astype(int).tolist() == [1, 1, 0, 1, 1, 0, 1, 1, 0, 1]
    counts = clip_bin_counts(CLICKS_40, CLICKS_40, duration=10, clip_length=2)
    assert counts[:, 0].tolist() == [2, 1, 1, 2, 1]
    assert (counts[:, 0] == counts[:, 1]).all() and (counts[:, 0] == counts[:, 2]).all()
    assert clip_bin_counts(CLICKS_40, CLICKS_40, duration=10).tolist() == [[7, 7, 7]]
    for protocol in ("A", "B"):
        for clip in (None, 2.0, 5.0):
            s = coverage_hit(CLICKS_40, CLICKS_40, duration=10, protocol=protocol, clip_length=clip)
            assert s["bcs"] == 1.0 and s["bhs"] == 1.0


def test_click_track_against_copy_shifted_by_1_5_s():
    # reference: 48 BPM from 0.1 s over 10 s = 0.1, 1.35, 2.6, 3.85, 5.1, 6.35, 7.6, 8.85 -> bins
    # {0,1,2,3,5,6,7,8}, R = 8; shifted by 1.5 s: 1.6, 2.85, 4.1, 5.35, 6.6, 7.85, 9.1 (10.35 falls
    # off) -> bins {1,2,4,5,6,7,9}, G = 7; hits {1,2,5,6,7}, H = 5.
    ref = 0.1 + 1.25 * np.arange(8)
    gen = ref + 1.5
    assert clip_bin_counts(gen, ref, duration=10).tolist() == [[8, 7, 5]]
    a = coverage_hit(gen, ref, duration=10, protocol="A")
    b = coverage_hit(gen, ref, duration=10, protocol="B")
    assert a["bcs"] == pytest.approx(7 / 8) and a["bhs"] == pytest.approx(5 / 8)
    assert b["bcs"] == pytest.approx(5 / 7) and b["bhs"] == pytest.approx(5 / 8)
    assert math.isnan(b["csd"]) and math.isnan(b["hsd"])  # one clip: no sample std
    # 2-s clips (local times): [0,2) R .1 1.35 {0,1}, G 1.6 {1}; [2,4) R .6 1.85 {0,1}, G .85 {0};
    # [4,6) R 1.1 {1}, G .1 1.35 {0,1}; [6,8) R .35 1.6 {0,1}, G .6 1.85 {0,1}; [8,10) R .85 {0}, G 1.1 {1}
    counts = clip_bin_counts(gen, ref, duration=10, clip_length=2)
    assert counts.tolist() == [[2, 1, 1], [2, 1, 1], [1, 2, 1], [2, 2, 2], [1, 1, 0]]
    a = coverage_hit_scores(counts, protocol="A")
    # A: G/R = .5, .5, 2, 1, 1 -> 1.0; H/R = .5, .5, 1, 1, 0 -> 0.6
    assert a["bcs"] == pytest.approx(1.0) and a["bhs"] == pytest.approx(0.6) and a["n_clips"] == 5
    b = coverage_hit_scores(counts, protocol="B")
    # B: H/G = 1, 1, .5, 1, 0 -> 0.7, sample var (3 * .09 + .04 + .49) / 4 = .2; H/R -> 0.6, var .7 / 4
    assert b["bcs"] == pytest.approx(0.7) and b["csd"] == pytest.approx(math.sqrt(0.2))
    assert b["bhs"] == pytest.approx(0.6) and b["hsd"] == pytest.approx(math.sqrt(0.175))
    assert b["f1"] == pytest.approx(2 * 0.7 * 0.6 / 1.3)


def test_dense_click_track_games_coverage():
    # 4 clicks a second over 10 s fill all 10 bins; the 40 BPM reference fills 7 -> R=7, G=10, H=7
    dense = dense_clicks(duration=10)
    assert len(dense) == 40
    assert clip_bin_counts(dense, CLICKS_40, duration=10).tolist() == [[7, 10, 7]]
    a = coverage_hit(dense, CLICKS_40, duration=10, protocol="A")
    b = coverage_hit(dense, CLICKS_40, duration=10, protocol="B")
    assert a["bcs"] == pytest.approx(10 / 7) and a["bcs"] > 1 and a["bhs"] == 1.0
    assert b["bcs"] == pytest.approx(0.7) and b["bcs"] < 1 and b["bhs"] == 1.0
    assert b["f1"] == pytest.approx(2 * 0.7 / 1.7)


def test_metronome_right_tempo_games_bins_but_not_beat_f1():
    # the known weakness: a 120 BPM metronome with a random phase fills every 1-s bin, as the reference
    rng = np.random.default_rng(7)
    phase = float(rng.uniform(0.0, 0.5))
    assert metronome(bpm=120, duration=10, seed=7) == pytest.approx(phase + 0.5 * np.arange(20))
    gen = metronome(bpm=120, duration=10, phase=0.35)  # 0.25 s off the reference's 0.1 + 0.5 k
    for protocol in ("A", "B"):
        s = coverage_hit(gen, CLICKS_120, duration=10, protocol=protocol, clip_length=2)
        assert s["bcs"] == 1.0 and s["bhs"] == 1.0
    assert beat_f1(gen, CLICKS_120) == 0.0


def test_empty_tracks():
    empty = np.zeros(0)
    # generated empty: R = 10, G = H = 0 -> A: 0/10, 0/10; B: H/G = 0/0 undefined, H/R = 0
    a = coverage_hit(empty, CLICKS_120, duration=10, protocol="A")
    assert (a["bcs"], a["bhs"]) == (0.0, 0.0)
    b = coverage_hit(empty, CLICKS_120, duration=10, protocol="B", clip_length=2)
    assert math.isnan(b["bcs"]) and b["bhs"] == 0.0 and math.isnan(b["f1"])
    b0 = coverage_hit(empty, CLICKS_120, duration=10, protocol="B", clip_length=2, zero_division=0.0)
    assert (b0["bcs"], b0["bhs"], b0["f1"], b0["csd"]) == (0.0, 0.0, 0.0, 0.0)  # the LORIS script's 0
    # reference empty: every ratio over R is undefined (NaN), for both protocols
    for protocol in ("A", "B"):
        s = coverage_hit(CLICKS_120, empty, duration=10, protocol=protocol)
        assert math.isnan(s["bcs"]) == (protocol == "A") and math.isnan(s["bhs"])
    # one silent 2-s clip in each: the reference (40 BPM without 3.2) is silent in [2,4), the
    # generated (120 BPM without [4,6)) in [4,6). Per clip [R, G, H]:
    # [0,2) R {0,1} G {0,1}; [2,4) R {} G {0,1}; [4,6) R 4.7 {0} G {}; [6,8) R {0,1} G {0,1};
    # [8,10) R 9.2 {1} G {0,1}
    ref = CLICKS_40[CLICKS_40 != 3.2]
    gen = CLICKS_120[(CLICKS_120 < 4) | (CLICKS_120 >= 6)]
    counts = clip_bin_counts(gen, ref, duration=10, clip_length=2)
    assert counts.tolist() == [[2, 2, 2], [0, 2, 0], [1, 0, 0], [2, 2, 2], [1, 2, 1]]
    # undefined clips are left out: A G/R over clips 0, 2, 3, 4 = 1, 0, 1, 2 -> 1.0; H/R = 1, 0, 1, 1 -> .75
    a = coverage_hit_scores(counts, protocol="A")
    assert a == {"bcs": 1.0, "bhs": 0.75, "n_clips": 5}
    # B H/G over clips 0, 1, 3, 4 = 1, 0, 1, .5 -> .625 (var .6875 / 3); H/R -> .75 (var .75 / 3)
    b = coverage_hit_scores(counts, protocol="B")
    assert b["bcs"] == pytest.approx(0.625) and b["csd"] == pytest.approx(math.sqrt(0.6875 / 3))
    assert b["bhs"] == pytest.approx(0.75) and b["hsd"] == pytest.approx(0.5)
    # ... or scored 0 with zero_division=0: A (1 + 0 + 0 + 1 + 2) / 5, (1 + 0 + 0 + 1 + 1) / 5; B H/G 2.5 / 5
    a0 = coverage_hit_scores(counts, protocol="A", zero_division=0.0)
    b0 = coverage_hit_scores(counts, protocol="B", zero_division=0.0)
    assert (a0["bcs"], a0["bhs"]) == (pytest.approx(0.8), pytest.approx(0.6))
    assert (b0["bcs"], b0["bhs"]) == (pytest.approx(0.5), pytest.approx(0.6))


def test_clips_shorter_than_a_bin():
    # a 0.6-s track is shorter than one 1-s bin: no clip is scored, every score is NaN
    assert clip_bin_counts([0.1], [0.1], duration=0.6).shape == (0, 3)
    for protocol in ("A", "B"):
        s = coverage_hit([0.1], [0.1], duration=0.6, protocol=protocol)
        assert s["n_clips"] == 0 and all(same(v, NAN) for k, v in s.items() if k != "n_clips")
    # a clip length under one bin is refused
    with pytest.raises(ParameterError, match="shorter than one bin"):
        clip_bin_counts([0.1], [0.1], duration=10, clip_length=0.5)
    # 10.5 s in 2-s clips: five clips, the trailing 0.5 s is dropped (10.2 is not counted) ...
    ref = np.array([0.5, 10.2])
    assert clip_bin_counts(ref, ref, duration=10.5, clip_length=2).tolist() == [[1, 1, 1]] + [[0, 0, 0]] * 4
    # ... but the whole 10.5-s track has 11 bins, the partial last one included
    assert clip_bin_counts(ref, ref, duration=10.5).tolist() == [[2, 2, 2]]
    # a 1.5-s track, whole: two bins, 1.2 in the partial second one: R = {0}, G = {0, 1}, H = {0}
    gen, ref = [0.4, 0.7, 1.2], [0.3]
    assert clip_bin_counts(gen, ref, duration=1.5).tolist() == [[1, 2, 1]]
    a = coverage_hit(gen, ref, duration=1.5, protocol="A")
    b = coverage_hit(gen, ref, duration=1.5, protocol="B")
    assert (a["bcs"], a["bhs"], b["bcs"], b["bhs"]) == (2.0, 1.0, 0.5, 1.0)


def test_coverage_hit_rejects_bad_input():
    with pytest.raises(ParameterError, match="protocol"):
        coverage_hit([0.1], [0.1], duration=2, protocol="C")
    with pytest.raises(ParameterError, match="duration"):
        coverage_hit([0.1], [0.1], duration=-1)
    with pytest.raises(ParameterError, match="NaN"):
        clip_bin_counts([np.nan], [0.1], duration=2)
    with pytest.raises(ParameterError, match="hits"):
        coverage_hit_scores([[1, 1, 2]])


def test_audio_click_tracks():
    sr = 22050
    ref = click_track(bpm=40, duration=10, sr=sr, offset=0.2)
    t = onset_times(ref, sr=sr, protocol="A")
    assert len(t) == 7 and np.abs(t - beat_times(bpm=40, duration=10, offset=0.2)).max() < 0.05
    # against itself (A, 2-s clips): BCS = BHS = 1
    a = coverage_hit_audio(ref, ref, sr=sr, protocol="A", clip_length=2)
    assert (a["bcs"], a["bhs"], a["n_clips"]) == (1.0, 1.0, 5)
    # a dense click track (4 a second) against the 40 BPM reference, whole: R = 7, G = 10, H = 7
    dense = click_track(bpm=240, duration=10, sr=sr, offset=0.05)
    a = coverage_hit_audio(dense, ref, sr=sr, protocol="A")
    b = coverage_hit_audio(dense, ref, sr=sr, protocol="B")
    assert a["bcs"] == pytest.approx(10 / 7) and a["bhs"] == 1.0
    assert b["bcs"] == pytest.approx(0.7) and b["bhs"] == 1.0
    # silence has no onsets; resampling to the detector's 22050 Hz keeps the clicks
    assert len(onset_times(np.zeros(sr, np.float32), sr=sr)) == 0
    y16 = click_track(bpm=40, duration=5, sr=16000, offset=0.2)
    assert len(onset_times(y16, sr=16000, protocol="B")) == 4


def test_beat_f1():
    beats = metronome(bpm=120, duration=10, phase=0.0)
    assert beat_f1(beats, beats) == 1.0
    assert beat_f1(beats + 0.25, beats) == 0.0
    # the window is ±0.1 s, not mir_eval's default 0.07 s
    assert beat_f1(beats + 0.08, beats) == 1.0
    assert beat_f1(beats + 0.08, beats, tolerance=0.07) == 0.0
    # half of the beats: precision 1, recall 0.5 -> F1 = 2/3
    assert beat_f1(beats[::2], beats) == pytest.approx(2 / 3)
    # nothing is trimmed by default (mir_eval.beat.evaluate would drop beats before 5 s)
    short = beats[beats < 5]
    assert beat_f1(short, short) == 1.0
    assert math.isnan(beat_f1(short, short, min_beat_time=5.0))
    assert beat_f1(np.zeros(0), beats) == 0.0 and math.isnan(beat_f1(beats, np.zeros(0)))


def test_tempo():
    assert tempo_from_beats(metronome(bpm=96, duration=20, phase=0.3)) == pytest.approx(96)
    assert math.isnan(tempo_from_beats([1.0]))
    assert tempo_error(132, 120) == pytest.approx(0.1)
    assert tempo_hit(123, 120) and not tempo_hit(132, 120)
    # doubled / halved: a miss by default, forgiven with allow_octave
    assert tempo_error(240, 120) == pytest.approx(1.0) and tempo_error(60, 120) == pytest.approx(0.5)
    assert not tempo_hit(240, 120) and not tempo_hit(60, 120)
    assert tempo_error(240, 120, allow_octave=True) == 0.0 and tempo_hit(61, 120, allow_octave=True)
    assert not tempo_hit(NAN, 120)


def test_baselines():
    a, b = metronome(bpm=100, duration=30, seed=3), metronome(bpm=100, duration=30, seed=3)
    assert np.array_equal(a, b) and 0 <= a[0] < 0.6 and np.diff(a) == pytest.approx(0.6)
    assert a[-1] < 30 <= a[-1] + 0.6
    assert metronome(bpm=120, duration=10, phase=0.1) == pytest.approx(
        beat_times(bpm=120, duration=10, offset=0.1)
    )
    fast = wrong_tempo_metronome(bpm=100, duration=30, factor=1.2, seed=0)
    slow = wrong_tempo_metronome(bpm=100, duration=30, factor=0.8, seed=0)
    assert tempo_from_beats(fast) == pytest.approx(120) and tempo_from_beats(slow) == pytest.approx(80)
    with pytest.raises(ParameterError, match="differ from 1"):
        wrong_tempo_metronome(bpm=100, duration=30, factor=1.0)
    assert dense_clicks(duration=2).tolist() == [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75]
    assert clicks_on([3.0, -1.0, 0.5, 3.0, 12.0], duration=10).tolist() == [0.5, 3.0]
