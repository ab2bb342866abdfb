"""Input that does not look like music (no beat: silence, noise, speech, a bird, a whale) is danced calmly and
said so; the beat strength that decides it, on known signals and on ../shared/music."""

from __future__ import annotations

import numpy as np
import pytest
from _signals import speech_like, white_noise
from conftest import NON_MUSIC, SONGS

from dancekit.audio.io import load, save_wav
from dancekit.audio.synth import click_track
from dancekit.features import MUSIC_BEAT_STRENGTH, beat_strength, extract, rhythm

RATE = 100.0  # envelope frames per second in the known-answer tests


def _pulses(seconds: float, period_s: float) -> np.ndarray:
    env = np.zeros(int(seconds * RATE))
    env[:: int(period_s * RATE)] = 1.0
    return env


def test_beat_strength_known_answers():
    # a pulse every 0.5 s (120 BPM): the autocorrelation at one period is (k-1)/k of its lag-0 value, k pulses
    # in a window, less the mean's share; close to 1
    assert beat_strength(onset_envelope=_pulses(30, 0.5), rate=RATE) > 0.9
    assert beat_strength(onset_envelope=np.zeros(3000), rate=RATE) == 0.0  # silence
    assert beat_strength(onset_envelope=np.full(3000, 2.5), rate=RATE) == 0.0  # constant
    # a pulse every 2 s (30 BPM) has no peak between 60 and 200 BPM: at those lags the envelope meets zeros
    assert beat_strength(onset_envelope=_pulses(30, 2.0), rate=RATE) < 0.05
    # a 2-s clip scores sqrt(2/8) = 0.5 of what its window would
    short = beat_strength(onset_envelope=_pulses(2, 0.5), rate=RATE)
    whole = beat_strength(onset_envelope=_pulses(2, 0.5), rate=RATE, window_s=2.0)
    assert short == pytest.approx(0.5 * whole)
    noise = [beat_strength(onset_envelope=np.random.default_rng(s).random(3000), rate=RATE) for s in range(5)]
    assert max(noise) < 0.15  # white noise: peaks of about 3 / sqrt(800) within a window


def _strength(y: np.ndarray, sr: int) -> float:
    env = rhythm.fine_onset(rhythm.fine_log_mel(rhythm.to_beat_sr(y, sr)))
    return beat_strength(onset_envelope=env, rate=rhythm.BEAT_SR / rhythm.BEAT_HOP)


@pytest.mark.shared
def test_threshold_separates_real_songs_from_non_music(music_dir):
    songs = [_strength(*load(p)) for p in SONGS]
    others = [_strength(*load(p)) for p in NON_MUSIC]
    others += [_strength(speech_like(seconds=30, seed=s), 22050) for s in range(3)]
    others += [_strength(white_noise(seconds=30, seed=s), 22050) for s in range(2)]
    assert min(songs) >= MUSIC_BEAT_STRENGTH > max(others), (songs, others)


def test_extract_carries_the_beat_strength():
    y = click_track(bpm=120, duration=6.0, sr=22050)
    fs = extract(y, sr=22050, fps=25, preset="music2dance")
    assert fs.beat_strength == pytest.approx(_strength(y, 22050)) and fs.beat_strength > MUSIC_BEAT_STRENGTH


def _speed(motion) -> float:
    p = np.asarray(motion.to_positions(), np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=-1).mean())


def test_speech_is_danced_calmly_and_said_so(tmp_path):
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline()
    save_wav(tmp_path / "talk.wav", speech_like(seconds=8.0, seed=1), sr=22050)
    save_wav(tmp_path / "song.wav", click_track(bpm=120, duration=8.0, sr=22050), sr=22050)
    talk = pipe(str(tmp_path / "talk.wav"), seed=0)
    assert not talk.looks_like_music and talk.beat_strength < MUSIC_BEAT_STRENGTH
    assert talk.genre is None and talk.genre_probs == {}  # no genre read from speech
    assert "calmly (it does not look like music: beat strength" in talk.summary()
    lively = pipe.generate(str(tmp_path / "talk.wav"), seed=0)  # the same model's dance, not calmed
    assert _speed(talk.motion) < 0.6 * _speed(lively)
    song = pipe(str(tmp_path / "song.wav"), seed=0)
    assert song.looks_like_music
    assert "does not look like music" not in song.summary()


@pytest.mark.parametrize("model", ["music2dance", "dual"])
def test_other_models_dance_speech_calmly_too(tmp_path, model, monkeypatch):
    """The embedded music2dance and dual models: speech is danced calmly (positions, rest bone lengths) and
    the summary says so; a click track keeps the model's own dance (with its rotations)."""
    import dancekit.features
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline(model)
    save_wav(tmp_path / "talk.wav", speech_like(seconds=8.0, seed=1), sr=22050)
    save_wav(tmp_path / "song.wav", click_track(bpm=120, duration=8.0, sr=22050), sr=22050)
    opts = {"seed": 0, "beat_sync": False, "cleanup": False}
    talk = pipe(str(tmp_path / "talk.wav"), **opts)
    assert not talk.looks_like_music and talk.beat_strength < MUSIC_BEAT_STRENGTH
    assert "calmly (it does not look like music: beat strength" in talk.summary()
    song = pipe(str(tmp_path / "song.wav"), **opts)
    assert song.looks_like_music and "does not look like music" not in song.summary()
    assert song.motion.rotations is not None  # the model's own rotations are kept for music
    monkeypatch.setattr(dancekit.features, "MUSIC_BEAT_STRENGTH", -1.0)  # nothing is calmed
    lively = pipe(str(tmp_path / "talk.wav"), **opts)
    assert lively.looks_like_music
    assert _speed(talk.motion) < 0.6 * _speed(lively.motion)
