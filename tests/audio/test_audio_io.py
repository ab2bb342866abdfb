"""dancekit.audio: decoding, validation, resampling, writing, synthesisers."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
import soundfile as sf
from conftest import NON_MUSIC, SONGS

from dancekit.audio import MIN_DURATION, load, save_wav, synth, validate_audio
from dancekit.errors import AudioError, ParameterError

SR = 22050


def _sine(freq: float, seconds: float, sr: int = SR, amp: float = 0.5) -> np.ndarray:
    t = np.arange(int(seconds * sr)) / sr
    return (amp * np.sin(2 * np.pi * freq * t)).astype(np.float32)


def _peak_hz(y: np.ndarray, sr: int) -> float:
    spec = np.abs(np.fft.rfft(y * np.hanning(len(y))))
    return float(np.fft.rfftfreq(len(y), 1 / sr)[np.argmax(spec)])


# --------------------------------------------------------------------------------------------- load


def test_wav_round_trip(tmp_path):
    y = _sine(440.0, 2.0)
    path = save_wav(tmp_path / "a.wav", y, sr=SR)
    z, sr = load(path)
    assert sr == SR and z.dtype == np.float32 and z.shape == y.shape
    np.testing.assert_allclose(z, y, atol=1.0 / 32768 + 1e-6)  # PCM_16 quantisation


def test_long_file_is_read_in_blocks(tmp_path):
    # longer than the 2**18-frame block: the blocks must join without a seam
    y = np.linspace(-0.9, 0.9, (1 << 18) * 2 + 1234).astype(np.float32)
    save_wav(tmp_path / "ramp.wav", y, sr=SR, subtype="FLOAT")
    z, _ = load(tmp_path / "ramp.wav")
    np.testing.assert_array_equal(z, y)


def test_resample_keeps_pitch_and_duration(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 2.0, sr=44100), sr=44100)
    z, sr = load(tmp_path / "a.wav", sr=SR)
    assert sr == SR and len(z) == 2 * SR
    assert abs(_peak_hz(z, sr) - 440.0) < 2.0


def test_stereo_mixdown_and_mono_false(tmp_path):
    n = SR * 2
    stereo = np.stack([np.full(n, 0.4), np.full(n, 0.2)], axis=1).astype(np.float32)
    sf.write(tmp_path / "st.wav", stereo, SR, subtype="FLOAT")
    mono, _ = load(tmp_path / "st.wav")
    np.testing.assert_allclose(mono, 0.3, atol=1e-6)
    both, _ = load(tmp_path / "st.wav", mono=False)
    assert both.shape == (2, n)
    np.testing.assert_allclose(both[1], 0.2, atol=1e-6)


def test_start_end_excerpt(tmp_path):
    y = (np.arange(4 * SR) / (4 * SR)).astype(np.float32)  # value = time / 4 s
    save_wav(tmp_path / "ramp.wav", y, sr=SR, subtype="FLOAT")
    z, _ = load(tmp_path / "ramp.wav", start=1.0, end=2.5)
    assert len(z) == int(1.5 * SR)
    assert z[0] == pytest.approx(0.25, abs=1e-6)
    z, _ = load(tmp_path / "ramp.wav", start=2.0, end=99.0)  # end past the file: clipped
    assert len(z) == 2 * SR


@pytest.mark.parametrize(
    "start, end",
    [(2.0, 1.0), (1.0, 1.0), (-1.0, None), (float("nan"), None)],
)
def test_bad_excerpt_bounds(tmp_path, start, end):
    save_wav(tmp_path / "a.wav", _sine(440.0, 3.0), sr=SR)
    with pytest.raises(ParameterError, match="start"):
        load(tmp_path / "a.wav", start=start, end=end)


def test_start_beyond_the_file(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 3.0), sr=SR)
    with pytest.raises(ParameterError, match=r"start=5 s is beyond the end of .*a\.wav"):
        load(tmp_path / "a.wav", start=5.0)


def test_bad_sr_argument(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 2.0), sr=SR)
    with pytest.raises(ParameterError, match="sr must be"):
        load(tmp_path / "a.wav", sr=0)


# --------------------------------------------------------------------------------------------- bad files


def _assert_audio_error(path, match: str) -> None:
    with pytest.raises(AudioError, match=match) as info:
        load(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    _assert_audio_error(tmp_path / "nope.wav", "not found")


def test_folder_instead_of_file(tmp_path):
    (tmp_path / "song.wav").mkdir()
    _assert_audio_error(tmp_path / "song.wav", "folder")


@pytest.mark.parametrize("name", ["noise.wav", "noise.mp3", "noise.ogg", "noise.m4a"])
def test_corrupt_file(tmp_path, rng, name):
    path = tmp_path / name
    path.write_bytes(rng.bytes(50_000))
    _assert_audio_error(path, "cannot decode")


def test_truncated_wav_half(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 4.0), sr=SR)
    data = (tmp_path / "a.wav").read_bytes()
    cut = tmp_path / "cut.wav"
    cut.write_bytes(data[: len(data) // 2])
    _assert_audio_error(cut, "truncated")


def test_truncated_wav_after_header(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 4.0), sr=SR)
    cut = tmp_path / "hdr.wav"
    cut.write_bytes((tmp_path / "a.wav").read_bytes()[:44])
    _assert_audio_error(cut, "truncated")


def test_truncated_wav_inside_header(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 4.0), sr=SR)
    cut = tmp_path / "hdr.wav"
    cut.write_bytes((tmp_path / "a.wav").read_bytes()[:30])
    _assert_audio_error(cut, "cannot decode")


def test_truncated_ogg(tmp_path):
    y = _sine(440.0, 6.0) + 0.05 * np.random.default_rng(0).standard_normal(6 * SR).astype(np.float32)
    sf.write(tmp_path / "a.ogg", y, SR, format="OGG", subtype="VORBIS")
    assert load(tmp_path / "a.ogg")[0].shape == (6 * SR,)  # the intact file is fine
    data = (tmp_path / "a.ogg").read_bytes()
    cut = tmp_path / "cut.ogg"
    cut.write_bytes(data[: len(data) // 2])
    _assert_audio_error(cut, "truncated")


def test_ogg_cut_at_a_page_boundary_is_truncated(tmp_path):
    """Cut just before the last Ogg page: every page left is complete, only the end-of-stream flag is missing."""
    y = _sine(330.0, 6.0) + 0.05 * np.random.default_rng(1).standard_normal(6 * SR).astype(np.float32)
    sf.write(tmp_path / "a.ogg", y, SR, format="OGG", subtype="VORBIS")
    data = (tmp_path / "a.ogg").read_bytes()
    last = data.rfind(b"OggS")
    assert last > 0 and data[last + 5] & 0x04  # the last page carries the end-of-stream flag ...
    prev = data.rfind(b"OggS", 0, last)
    assert not data[prev + 5] & 0x04  # ... the one before it does not
    cut = tmp_path / "cut.ogg"
    cut.write_bytes(data[:last])
    assert sf.info(cut).frames < 6 * SR  # libsndfile alone would silently decode the shorter stream
    _assert_audio_error(cut, "truncated")


@pytest.mark.parametrize("missing", [2, 4, 8])
def test_wav_missing_its_last_bytes_is_truncated(tmp_path, missing):
    """The RIFF size counts the file minus its 8-byte RIFF header: a file a few bytes short (under 8) is caught."""
    save_wav(tmp_path / "a.wav", _sine(440.0, 2.0), sr=SR)
    data = (tmp_path / "a.wav").read_bytes()
    assert data[:4] == b"RIFF" and int.from_bytes(data[4:8], "little") == len(data) - 8
    cut = tmp_path / "cut.wav"
    cut.write_bytes(data[:-missing])
    _assert_audio_error(cut, "truncated")


def test_wav_without_the_pad_byte_of_an_odd_data_chunk_loads(tmp_path):
    """An odd-sized data chunk is followed by a pad byte the RIFF size counts; some writers omit it."""
    n = 2 * SR + 1  # 8-bit mono: an odd number of data bytes
    sf.write(tmp_path / "odd.wav", _sine(440.0, 3.0)[:n], SR, subtype="PCM_U8")
    data = (tmp_path / "odd.wav").read_bytes()
    assert int.from_bytes(data[4:8], "little") == len(data) - 8 and len(data) % 2 == 0
    nopad = tmp_path / "nopad.wav"
    nopad.write_bytes(data[:-1])
    y, sr = load(nopad)
    assert sr == SR and y.shape == (n,)


def test_streamed_wav_with_unknown_riff_size_loads(tmp_path):
    """RIFF size 0 or 0xFFFFFFFF (written by a stream that could not seek back) is not a truncation."""
    save_wav(tmp_path / "a.wav", _sine(440.0, 2.0), sr=SR)
    data = (tmp_path / "a.wav").read_bytes()
    for size in (0, 0xFFFFFFFF):
        streamed = tmp_path / f"streamed_{size}.wav"
        streamed.write_bytes(data[:4] + size.to_bytes(4, "little") + data[8:])
        assert load(streamed)[0].shape == (2 * SR,)


def test_zero_byte_file(tmp_path):
    (tmp_path / "empty.wav").write_bytes(b"")
    _assert_audio_error(tmp_path / "empty.wav", "empty")


def test_zero_length_audio(tmp_path):
    sf.write(tmp_path / "zero.wav", np.zeros(0, dtype=np.float32), SR)
    _assert_audio_error(tmp_path / "zero.wav", "zero-length")


def test_shorter_than_one_second(tmp_path):
    save_wav(tmp_path / "short.wav", _sine(440.0, 0.5), sr=SR)
    _assert_audio_error(tmp_path / "short.wav", "too short")


def test_excerpt_shorter_than_one_second(tmp_path):
    save_wav(tmp_path / "a.wav", _sine(440.0, 3.0), sr=SR)
    with pytest.raises(AudioError, match="too short"):
        load(tmp_path / "a.wav", start=1.0, end=1.5)


def test_nan_samples(tmp_path):
    y = _sine(440.0, 2.0)
    y[SR // 2] = np.nan
    sf.write(tmp_path / "nan.wav", y, SR, subtype="FLOAT")
    _assert_audio_error(tmp_path / "nan.wav", r"non-finite .* first at 0\.500 s")


# --------------------------------------------------------------------------------------------- validate_audio


def test_validate_audio_accepts_silence():
    validate_audio(np.zeros(SR, dtype=np.float32), sr=SR)  # raises nothing
    validate_audio(np.zeros((2, SR), dtype=np.float64), sr=SR)


@pytest.mark.parametrize(
    "y, match",
    [
        (np.zeros(0, dtype=np.float32), "zero-length"),
        (np.zeros(SR - 1, dtype=np.float32), "too short"),
        (np.full(SR, np.inf, dtype=np.float32), "non-finite"),
        (np.zeros(SR, dtype=np.int16), "floating point"),
        (np.zeros((1, 1, SR), dtype=np.float32), "shape"),
    ],
)
def test_validate_audio_rejects(y, match):
    with pytest.raises(AudioError, match=match) as info:
        validate_audio(y, sr=SR, path="song.wav")
    assert "song.wav" in str(info.value)


@pytest.mark.parametrize("sr", [0, -1, 22050.5, True])
def test_validate_audio_bad_sr(sr):
    with pytest.raises(ParameterError, match="sr must be"):
        validate_audio(np.zeros(SR, dtype=np.float32), sr=sr)


def test_min_duration_is_one_second():
    assert MIN_DURATION == 1.0
    validate_audio(np.zeros(SR, dtype=np.float32), sr=SR)  # exactly 1 s is fine


# --------------------------------------------------------------------------------------------- ffmpeg path


def test_m4a_through_ffmpeg(tmp_path):
    import imageio_ffmpeg

    save_wav(tmp_path / "a.wav", _sine(440.0, 3.0, sr=44100), sr=44100)
    m4a = tmp_path / "a.m4a"
    try:
        subprocess.run(
            [
                imageio_ffmpeg.get_ffmpeg_exe(),
                "-nostdin",
                "-v",
                "error",
                "-y",
                "-i",
                str(tmp_path / "a.wav"),
                "-c:a",
                "aac",
                "-b:a",
                "128k",
                str(m4a),
            ],
            check=True,
            capture_output=True, timeout=120,
        )
    except (subprocess.CalledProcessError, OSError, RuntimeError) as exc:
        pytest.skip(f"cannot encode m4a with the bundled ffmpeg: {exc}")
    with pytest.raises(sf.LibsndfileError):
        sf.info(m4a)  # libsndfile cannot read it: the ffmpeg fallback is what is tested
    y, sr = load(m4a)
    assert sr == 44100 and y.dtype == np.float32 and y.ndim == 1
    assert abs(len(y) / sr - 3.0) < 0.1  # AAC adds a little priming / padding
    assert abs(_peak_hz(y, sr) - 440.0) < 2.0
    z, sr2 = load(m4a, sr=SR, start=1.0, end=2.0)
    assert sr2 == SR and len(z) == SR


# --------------------------------------------------------------------------------------------- save_wav


def test_save_wav_is_atomic_and_clips(tmp_path):
    y = np.array([2.0, -2.0, 0.5] * SR, dtype=np.float32)
    save_wav(tmp_path / "c.wav", y, sr=SR)
    z, _ = load(tmp_path / "c.wav")
    assert z.max() == pytest.approx(1.0, abs=1e-4) and z.min() == pytest.approx(-1.0, abs=1e-4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.wav"]  # no temporary left behind


def test_save_wav_missing_folder_leaves_nothing(tmp_path):
    from dancekit.errors import DancekitError

    with pytest.raises(DancekitError, match="does not exist"):
        save_wav(tmp_path / "no" / "c.wav", np.zeros(SR, dtype=np.float32), sr=SR)


# --------------------------------------------------------------------------------------------- synth


def test_click_track_clicks_at_beat_times():
    y = synth.click_track(bpm=120, duration=4.0, sr=SR, offset=0.1)
    times = synth.beat_times(bpm=120, duration=4.0, offset=0.1)
    np.testing.assert_allclose(times, [0.1, 0.6, 1.1, 1.6, 2.1, 2.6, 3.1, 3.6])
    assert len(y) == 4 * SR
    onsets = np.flatnonzero(np.abs(y) > 1e-3)
    first = onsets[np.concatenate([[True], np.diff(onsets) > SR // 10])] / SR
    np.testing.assert_allclose(first, times, atol=2e-4)


def test_click_track_accents_every_meter():
    y = synth.click_track(bpm=120, duration=4.0, sr=SR, meter=4)
    win = int(0.1 * SR)
    energy = [
        float(np.sum(y[int(t * SR) : int(t * SR) + win] ** 2))
        for t in synth.beat_times(bpm=120, duration=4.0)
    ]
    assert energy[0] > 2 * energy[1] and energy[4] > 2 * energy[3]
    assert energy[1] == pytest.approx(energy[2], rel=1e-3)


def test_render_melody_pitch_and_length():
    y = synth.render_melody([(69, 2.0), (None, 1.0)], sr=SR, bpm=120)
    assert len(y) == int(1.5 * SR)
    assert abs(_peak_hz(y[:SR], SR) - 440.0) < 2.0
    assert np.max(np.abs(y[int(1.05 * SR) :])) == 0.0  # the rest is silent


def test_ode_to_joy_is_32_seconds():
    y = synth.ode_to_joy(sr=8000)
    assert len(y) == 32 * 8000 and y.dtype == np.float32
    assert 0.5 < np.max(np.abs(y)) <= 0.9 + 1e-6
    assert sum(b for _, b in synth.ODE_TO_JOY_MELODY) == 64 == sum(b for _, b in synth.ODE_TO_JOY_BASS)


def test_make_demo_tune_script(tmp_path):
    import importlib.util
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "scripts" / "make_demo_tune.py"
    spec = importlib.util.spec_from_file_location("make_demo_tune", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main([str(tmp_path / "demo.wav"), "--sr", "8000"]) == 0
    y, sr = load(tmp_path / "demo.wav")
    assert sr == 8000 and len(y) == 32 * 8000


@pytest.mark.parametrize("bad", [dict(bpm=0), dict(bpm=-5), dict(duration=0)])
def test_click_track_bad_args(bad):
    kw = dict(bpm=120, duration=2.0, sr=SR) | bad
    with pytest.raises(ParameterError):
        synth.click_track(**kw)


# --------------------------------------------------------------------------------------------- real recordings


@pytest.mark.shared
@pytest.mark.parametrize("song", SONGS + NON_MUSIC, ids=lambda p: p.stem[:24])
def test_real_recordings_load(music_dir, song):
    info = sf.info(song)
    end = min(info.duration, 25.0)
    y, sr = load(song, start=0.0, end=end)
    assert sr == info.samplerate and y.dtype == np.float32 and y.ndim == 1
    assert abs(len(y) - round(end * sr)) <= 1
    assert np.isfinite(y).all() and np.abs(y).max() > 0.01


@pytest.mark.shared
def test_real_ogg_cut_in_half_is_truncated(music_dir, tmp_path):
    data = SONGS[2].read_bytes()
    cut = tmp_path / "brahms_cut.ogg"
    cut.write_bytes(data[: len(data) // 2])
    _assert_audio_error(cut, "truncated")
