"""dancekit.features.dsp (librosa's feature algorithms in NumPy, written to spare a fresh process the import of
librosa.beat and librosa.core.constantq) against librosa itself, step by step, on synthetic songs and, where
they are present, the real songs of ../shared/music and tang2018.

Equal means bit-equal where the same operations run in the same order (windows, STFT, mel filters, dB, onset
envelopes, tempogram, tempo, the beat tracker's local score and dynamic program, beat frames, resampling);
the constant-Q magnitude, chroma, MFCC and deltas sum in another order (BLAS, a matrix DCT) and agree to
float32 rounding.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancekit.audio import synth
from dancekit.audio.io import resample
from dancekit.features import dsp as _dsp

librosa = pytest.importorskip("librosa")

SR = 22050
HOP = 256
SHARED = Path(__file__).resolve().parents[3] / "shared"
REAL = [SHARED / "music" / n for n in ("Kevin_MacLeod_-_Vibe_Ace.ogg", "brahms_hungarian_dance_5.ogg",
                                        "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg")]
REAL += [SHARED / "data" / "tang2018" / d / "audio.mp3" for d in ("DANCE_W_7", "DANCE_C_6", "DANCE_R_3", "DANCE_T_5")]


def _synthetic() -> dict[str, np.ndarray]:
    return {"ode_to_joy": synth.ode_to_joy(sr=SR, bpm=112.0)[: 12 * SR].astype(np.float32),
            "clicks_97bpm": synth.click_track(bpm=97.0, duration=12.0, sr=SR).astype(np.float32)}


def _songs() -> list:
    out = [pytest.param(y, id=k) for k, y in _synthetic().items()]
    for p in REAL:
        marks = pytest.mark.skipif(not p.exists(), reason=f"{p} not here")
        out.append(pytest.param(p, id=p.parent.name if p.name == "audio.mp3" else p.stem[:24], marks=marks))
    return out


def _audio(song, seconds: float = 30.0) -> np.ndarray:
    if isinstance(song, Path):
        from dancekit.audio import load

        y, sr = load(song, sr=SR, end=seconds)
        return y
    return song


def _log_mel(y: np.ndarray) -> np.ndarray:
    D = _dsp.stft(y, n_fft=2048, hop_length=HOP)
    return _dsp.power_to_db(_dsp.mel_filters(sr=SR, n_fft=2048) @ (D.real**2 + D.imag**2)).astype(np.float32)


def test_window_and_fast_length_match_scipy():
    import scipy.fft
    import scipy.signal

    for n in (1, 2, 3, 344, 384, 512, 1024, 2048):
        np.testing.assert_array_equal(_dsp.hann(n), scipy.signal.get_window("hann", n))
    assert [_dsp.next_fast_len_real(n) for n in range(1, 4000)] == [scipy.fft.next_fast_len(n, real=True)
                                                                     for n in range(1, 4000)]


def test_resample_is_librosas_soxr_hq():
    y = _synthetic()["ode_to_joy"]
    for target in (12800, 7680, 44100):
        np.testing.assert_array_equal(resample(y, orig_sr=SR, target_sr=target),
                                      librosa.resample(y, orig_sr=SR, target_sr=target, res_type="soxr_hq"))
    stereo = np.stack([y, -0.5 * y])
    np.testing.assert_array_equal(resample(stereo, orig_sr=SR, target_sr=16000),
                                  librosa.resample(stereo, orig_sr=SR, target_sr=16000, res_type="soxr_hq"))


@pytest.mark.parametrize("song", _songs())
def test_spectrogram_steps_equal_librosa(song):
    y = _audio(song)
    for n_fft, hop in ((2048, HOP), (512, 128)):
        np.testing.assert_array_equal(_dsp.stft(y, n_fft=n_fft, hop_length=hop),
                                      librosa.stft(y, n_fft=n_fft, hop_length=hop))
    np.testing.assert_array_equal(_dsp.stft(y, n_fft=512, hop_length=64, window="ones"),
                                  librosa.stft(y, n_fft=512, hop_length=64, window="ones"))
    for sr, n_fft in ((SR, 2048), (12800, 2048), (7680, 2048)):
        np.testing.assert_array_equal(_dsp.mel_filters(sr=sr, n_fft=n_fft), librosa.filters.mel(sr=sr, n_fft=n_fft))
    D = _dsp.stft(y, n_fft=2048, hop_length=HOP)
    M = _dsp.mel_filters(sr=SR, n_fft=2048) @ (D.real**2 + D.imag**2)
    np.testing.assert_array_equal(_dsp.power_to_db(M), librosa.power_to_db(M))
    S = _log_mel(y)
    for agg in (np.mean, np.median):
        np.testing.assert_array_equal(_dsp.onset_strength(S, n_fft=2048, hop_length=HOP, aggregate=agg),
                                      librosa.onset.onset_strength(S=S, sr=SR, n_fft=2048, hop_length=HOP,
                                                                   aggregate=agg))
    np.testing.assert_array_equal(_dsp.mel_frequencies(128, fmax=SR / 2), librosa.mel_frequencies(n_mels=128,
                                                                                                   fmax=SR / 2))


@pytest.mark.parametrize("song", _songs())
def test_tempo_and_beats_equal_librosa(song):
    """The same tempo and the same beat frames as librosa's tracker (Ellis' dynamic programme), on the
    envelope dancekit tracks (hop 256 at 22050 Hz, median-aggregated, padded with 2 s of zeros)."""
    y = _audio(song)
    env = _dsp.onset_strength(_log_mel(y), n_fft=2048, hop_length=HOP, aggregate=np.median).astype(np.float32)
    np.testing.assert_array_equal(_dsp.tempogram(env, win_length=384),
                                  librosa.feature.tempogram(onset_envelope=env, sr=SR, hop_length=HOP, win_length=384))
    np.testing.assert_array_equal(_dsp.autocorrelate(env.astype(np.float64)), librosa.autocorrelate(env.astype(np.float64)))
    for start_bpm in (120.0, 80.0):
        assert _dsp.tempo(env, sr=SR, hop_length=HOP, start_bpm=start_bpm) == librosa.feature.tempo(
            onset_envelope=env, sr=SR, hop_length=HOP, start_bpm=start_bpm)[0]
    padded = np.pad(env, (172, 172))
    frame_rate = SR / HOP
    for bpm, tightness in ((librosa.feature.tempo(onset_envelope=env, sr=SR, hop_length=HOP)[0], 100.0),
                           (97.0, 100.0), (131.3, 400.0)):
        ours = _dsp.beat_track(padded, bpm=bpm, frame_rate=frame_rate, tightness=tightness)
        _, theirs = librosa.beat.beat_track(onset_envelope=padded, sr=SR, hop_length=HOP, bpm=bpm,
                                            tightness=tightness, units="frames")
        assert len(ours) > 5
        np.testing.assert_array_equal(ours, theirs)
    # the two inner steps, on their own
    fpb = float(np.round(frame_rate * 60.0 / 97.0))
    onsets = padded / (padded.std(ddof=1) + np.finfo(np.float32).tiny)
    score = _dsp._local_score(onsets.astype(np.float64), fpb)
    # the last bit may differ: librosa compiles its local score with numba, whose sums fuse differently per CPU
    np.testing.assert_allclose(score, getattr(librosa.beat, "__beat_local_score")(onsets, np.array([fpb])),
                               rtol=1e-12, atol=1e-12)
    link, cum = _dsp._beat_dp(score, fpb, 100.0)
    link0, cum0 = getattr(librosa.beat, "__beat_track_dp")(score, np.array([fpb]), 100.0)
    np.testing.assert_array_equal(link, link0)
    np.testing.assert_array_equal(cum, cum0)


def test_beat_tracker_known_answer_on_a_click_track():
    """An independent answer: a 120 BPM click track has a beat every 0.5 s, on the clicks."""
    y = synth.click_track(bpm=120.0, duration=10.0, sr=SR).astype(np.float32)
    env = _dsp.onset_strength(_log_mel(y), n_fft=2048, hop_length=HOP, aggregate=np.median).astype(np.float32)
    frames = _dsp.beat_track(np.pad(env, (172, 172)), bpm=120.0, frame_rate=SR / HOP) - 172
    times = frames[(frames >= 0) & (frames < len(env))] * HOP / SR
    assert len(times) >= 17
    np.testing.assert_allclose(np.diff(times), 0.5, atol=1.5 * HOP / SR)
    np.testing.assert_allclose(times % 0.5, 0.0, atol=2 * HOP / SR)  # on the clicks (t = 0, 0.5, ...)
    assert _dsp.beat_track(np.zeros(500, np.float32), bpm=120.0, frame_rate=SR / HOP).size == 0


@pytest.mark.parametrize("song", _songs())
def test_constant_q_chroma_agrees_with_librosa(song):
    """librosa.cqt sums a sparse basis (scipy.sparse), this a dense one (BLAS): float32 rounding apart."""
    y = resample(_audio(song, 20.0), orig_sr=SR, target_sr=12800)
    fmin = 32.703195662574764
    for sr, n_oct in ((12800, 7), (7680, 6)):
        yy = y if sr == 12800 else resample(y, orig_sr=12800, target_sr=sr)
        C0 = np.abs(librosa.cqt(y=yy, sr=sr, hop_length=512, fmin=fmin, n_bins=36 * n_oct, bins_per_octave=36))
        C1 = _dsp.cqt_magnitude(yy, sr=sr, hop_length=512, fmin=fmin, n_bins=36 * n_oct, bins_per_octave=36)
        assert C1.shape == C0.shape and C1.dtype == np.float32
        assert np.abs(C1 - C0).max() <= 1e-5 * C0.max()
        ch0 = librosa.feature.chroma_cqt(C=C0, sr=sr, bins_per_octave=36, n_octaves=n_oct)
        ch1 = _dsp.chroma_from_cqt(C1, bins_per_octave=36)
        assert np.abs(ch1 - ch0).max() <= 1e-4
        np.testing.assert_allclose(_dsp.chroma_from_cqt(C0, bins_per_octave=36), ch0, atol=1e-6)


def test_cepstra_and_deltas_agree_with_librosa():
    S = _log_mel(_synthetic()["ode_to_joy"])
    m0 = librosa.feature.mfcc(S=S, n_mfcc=20)
    m1 = _dsp.dct_ortho(S, n=20)
    assert np.abs(m1 - m0).max() <= 2e-7 * np.abs(m0).max()
    for width in (3, 9):
        d0 = librosa.feature.delta(m0, width=width)
        d1 = _dsp.delta(m0, width=width)
        assert d1.dtype == np.float32 and np.abs(d1 - d0).max() <= 1e-6 * np.abs(d0).max()


def test_kinematic_beats_are_scipys_strict_minima():
    import scipy.signal

    from dancekit.motion import analysis

    rng = np.random.default_rng(0)
    for speed in (rng.random(200), np.round(rng.random(300) * 4), np.array([1.0, 0.0]), np.ones(5)):
        ours = np.flatnonzero((speed[1:-1] < speed[:-2]) & (speed[1:-1] < speed[2:])) + 1
        np.testing.assert_array_equal(ours, scipy.signal.argrelextrema(speed, np.less)[0])
    # and the function itself, on positions whose speed has plateaus and several minima
    rng = np.random.default_rng(1)
    x = np.cumsum(np.round(rng.normal(size=(150, 3, 3)), 1), axis=0)
    speed = analysis.mean_joint_speed(x, fps=30.0, smooth=0.0)
    beats = analysis.kinematic_beats(x, fps=30.0, smooth=0.0)
    assert beats.size > 10
    np.testing.assert_array_equal(beats, scipy.signal.argrelextrema(speed, np.less)[0] / 30.0)
