"""Memory bounded by the chunk (issue 18): the streamed and chunked paths equal the whole-song ones."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf

from dancekit.audio import load
from dancekit.audio.io import stream
from dancekit.audio.synth import ode_to_joy
from dancekit.errors import AudioError
from dancekit.features import spectral
from dancekit.features.presets import extract, extract_path
from dancekit.features.pulse import _song_beats_streamed, song_beats
from dancekit.features.rhythm import BEAT_SR


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    """14 s of a tune at 44.1 kHz, stereo (the channels differ), as flac: decoded and resampled like a real file."""
    sr = 44100
    y = ode_to_joy(sr=sr, bpm=126)[: 14 * sr].astype(np.float32)
    rng = np.random.default_rng(0)
    stereo = np.stack([y, 0.6 * y + 0.01 * rng.standard_normal(len(y)).astype(np.float32)], axis=1)
    path = tmp_path_factory.mktemp("stream") / "tune.flac"
    sf.write(path, stereo, sr)
    return path


@pytest.mark.parametrize("rate", [12800, 22050, 44100])
@pytest.mark.parametrize("span", [(None, None), (2.5, 11.0)])
def test_stream_equals_load(song, monkeypatch, rate, span):
    import dancekit.audio.io as io

    monkeypatch.setattr(io, "_BLOCK", 10007)  # many odd-sized blocks
    start, end = span
    ref, _ = load(song, sr=rate, start=start, end=end)
    got = np.concatenate([b[0] for b in stream(song, rates=[rate], start=start, end=end)])
    assert got.dtype == np.float32 and got.shape == ref.shape
    assert np.array_equal(got, ref)


def test_stream_refuses_what_load_refuses(tmp_path):
    short = tmp_path / "short.wav"
    sf.write(short, np.zeros(8000, np.float32), 16000)
    with pytest.raises(AudioError, match="too short"):
        list(stream(short, rates=[22050]))
    bad = tmp_path / "nan.wav"
    y = np.zeros(32000, np.float32)
    y[8000] = np.nan
    sf.write(bad, y, 16000, subtype="FLOAT")
    with pytest.raises(AudioError, match=r"non-finite .* first at 0\.500 s"):
        list(stream(bad, rates=[22050]))


def test_mel_power_stream_is_mel_power_bit_for_bit(monkeypatch):
    monkeypatch.setattr(spectral, "_MEL_CHUNK", 64)
    y = np.random.default_rng(1).standard_normal(50_000).astype(np.float32)
    ref = spectral.mel_power(y=y, sr=22050, n_fft=2048, hop_length=256)
    s = spectral.MelPowerStream(sr=22050, n_fft=2048, hop_length=256, expected_samples=1000)  # grows
    for a, b in [(0, 5), (5, 3000), (3000, 3001), (3001, 41_000), (41_000, 50_000)]:
        s.feed(y[a:b])
    got = s.finish()
    assert got.shape == ref.shape == (128, 1 + 50_000 // 256)
    assert np.array_equal(got, ref)


def test_power_to_db_inplace_is_librosas():
    import librosa

    M = np.abs(np.random.default_rng(2).standard_normal((16, 300))).astype(np.float32) ** 4
    M[3, :10] = 0.0
    ref = librosa.power_to_db(M)
    assert np.array_equal(spectral.power_to_db_inplace(M.copy()), ref)


def test_tempogram_chunked_equals_tempogram():
    env = np.abs(np.random.default_rng(3).standard_normal(1000)).astype(np.float32)
    env[400:520] = 0.0  # a silent stretch: all-zero frames stay zero
    ref = spectral.tempogram(onset_envelope=env, sr=12800, hop_length=512).T
    got = spectral.tempogram_chunked(onset_envelope=env, chunk=37)
    assert np.array_equal(got, ref)


def test_extract_path_equals_extract_on_the_loaded_song(song):
    """Chunks of 60 frames (2.4 s) with 4 s of context: the chromagram to float rounding, the rest exactly."""
    y, sr = load(song, start=1.0, end=13.0)
    for preset in ("revolution", "music2dance"):
        ref = extract(y, sr=sr, fps=25, preset=preset)
        got = extract_path(song, fps=25, preset=preset, start=1.0, end=13.0, chunk=60)
        assert got.names == ref.names and got.features.shape == ref.features.shape
        off = 0
        for name in ref.names:
            block, d = name.split(":")
            a, b = got.features[:, off:off + int(d)], ref.features[:, off:off + int(d)]
            if block == "chroma_cqt":
                assert np.abs(a - b).max() < 1e-4, (preset, block, np.abs(a - b).max())
            else:
                assert np.array_equal(a, b), (preset, block, np.abs(a - b).max())
            off += int(d)
        assert np.array_equal(got.beat_times, ref.beat_times) and got.tempo == ref.tempo
        assert got.beat_strength == ref.beat_strength
        if preset == "music2dance":
            assert np.array_equal(got.downbeat_times, ref.downbeat_times)


def test_chroma_chunks_follow_the_song(song):
    """The chunked chromagram is not trivially the whole one: with no context it differs at the chunk edges."""
    y, _ = load(song, sr=12800, end=10.0)
    ref = spectral.chroma_cqt(y=y, sr=12800).T
    assert np.abs(spectral.chroma_cqt_chunked(y=y, sr=12800, chunk=50) - ref).max() < 1e-4
    old = spectral.CQT_MARGIN_S
    try:
        spectral.CQT_MARGIN_S = 0.0
        assert np.abs(spectral.chroma_cqt_chunked(y=y, sr=12800, chunk=50) - ref).max() > 1e-2
    finally:
        spectral.CQT_MARGIN_S = old


def test_streamed_song_beats_equal_the_loaded_songs(song):
    y, sr = load(song, sr=BEAT_SR, start=0.5)
    ref = song_beats(y=y, sr=sr)
    got = _song_beats_streamed(song, start=0.5, end=None)
    assert got.tempo == ref.tempo and got.clarity == ref.clarity and got.has_beat == ref.has_beat
    assert np.array_equal(got.times, ref.times) and len(got.times) > 10


def test_html_written_in_pieces_is_the_one_string_page(monkeypatch, tmp_path):
    import base64
    import json
    import re

    from dancekit.motion import Motion, get_skeleton
    from dancekit.render import html
    from dancekit.render._scene import prepare_scene

    sk = get_skeleton("tang2018")
    p = np.random.default_rng(4).normal(size=(300, sk.num_joints, 3)).astype(np.float32) * 20 + 90
    scene = prepare_scene(p, parents=sk.parents, fps=25.0)
    audio = (bytes(range(256)) * 41, "audio/mpeg")
    whole = html.page_html(scene, audio=audio, title="t")
    monkeypatch.setattr(html, "_B64_PIECE", 3 * 7)  # many tiny pieces
    pieces = []
    html.write_page(pieces.append, scene, audio=audio, title="t")
    assert len(pieces) > 100 and "".join(pieces) == whole
    # and the page holds what was given (decoded independently)
    src = re.search(r'src="data:audio/mpeg;base64,([^"]*)"', whole).group(1)
    assert base64.b64decode(src) == audio[0]
    blob = json.loads(re.search(r'<script id="dk-data" type="application/json">(.*?)</script>', whole, re.S).group(1))
    q = np.frombuffer(base64.b64decode(blob["positions"]), "<u2").reshape(300, sk.num_joints, 3)
    assert q.max() == 65535 and blob["frames"] == 300
    del Motion


def test_tempogram_mean_is_librosas_mean():
    import librosa

    env = np.abs(np.random.default_rng(5).standard_normal(900)).astype(np.float32)
    ref = np.mean(librosa.feature.tempogram(onset_envelope=env, sr=22050, hop_length=512, win_length=344), axis=-1,
                  keepdims=True)
    assert np.array_equal(spectral.tempogram_mean(onset_envelope=env, win_length=344, chunk=10_000), ref)
    chunked = spectral.tempogram_mean(onset_envelope=env, win_length=344, chunk=100)
    assert np.allclose(chunked, ref, rtol=1e-12, atol=1e-15)
    bpm = librosa.feature.tempo(onset_envelope=env, sr=22050, hop_length=512)
    assert np.array_equal(librosa.feature.tempo(tg=chunked, sr=22050, hop_length=512), bpm)


@pytest.mark.parametrize("hop", [256, 512])
def test_onset_envelope_in_chunks_is_librosas(hop):
    import librosa

    from dancekit.features.rhythm import BEAT_NFFT, _onset_chunked

    S = (np.random.default_rng(6).standard_normal((128, 700)) * 10).astype(np.float32)
    for aggregate in (np.median, np.mean):
        ref = librosa.onset.onset_strength(S=S, sr=BEAT_SR, hop_length=hop, n_fft=BEAT_NFFT, aggregate=aggregate)
        got = _onset_chunked(S, hop_length=hop, aggregate=aggregate, chunk=33)
        assert got.shape == ref.shape and np.array_equal(got, ref.astype(np.float32))
    strided = np.ascontiguousarray(S[:, ::2])
    ref = librosa.onset.onset_strength(S=strided, sr=BEAT_SR, hop_length=hop, n_fft=BEAT_NFFT, aggregate=np.mean)
    assert np.array_equal(_onset_chunked(S[:, ::2], hop_length=hop, aggregate=np.mean, chunk=50), ref)
