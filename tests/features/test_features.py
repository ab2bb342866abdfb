"""dancekit.features: known answers on synthetic signals, real songs, cache, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import NON_MUSIC, SONGS

from dancekit.audio import save_wav, synth
from dancekit.errors import AudioError, DancekitError, ParameterError
from dancekit.features import (
    PRESET_DIMS,
    FeatureSet,
    beat_onehot,
    beat_track,
    chroma_cqt,
    default_cache_dir,
    downbeats,
    extract,
    extract_file,
    feature_sr,
    fold_meter,
    mfcc_delta,
    onset_strength,
    tempogram,
)

SR = 22050
BEAT_COLUMN = {"revolution": "beat", "music2dance": "beat", "dual": "beat_percussive"}


@pytest.fixture(scope="module")
def clicks_120():
    """20 s click track at 120 BPM, first click at 0.13 s, and its true beat times."""
    y = synth.click_track(bpm=120, duration=20.0, sr=SR, offset=0.13)
    return y, synth.beat_times(bpm=120, duration=20.0, offset=0.13)


# --------------------------------------------------------------------------------------------- beats


@pytest.mark.parametrize("fps", [15, 25, 30])
def test_click_track_beats_within_one_frame(clicks_120, fps):
    y, truth = clicks_120
    fs = extract(y, sr=SR, fps=fps, preset="music2dance")
    assert fs.tempo == pytest.approx(120.0, abs=2.0)  # not 60
    got = np.flatnonzero(fs.block("beat")[:, 0])
    want = np.round(truth * fps).astype(int)
    assert len(got) >= len(want) - 1  # at most one (edge) beat missed
    assert np.abs(got[:, None] - want[None, :]).min(axis=1).max() <= 1
    # beat_times themselves, in seconds, are within one frame too
    assert np.abs(fs.beat_times[:, None] - truth[None, :]).min(axis=1).max() < 1.0 / fps


def test_naive_low_rate_tracking_would_fail(clicks_120):
    """The reason for the fine grid: librosa on the 15 fps grid misreads 120 BPM."""
    import librosa

    y, _ = clicks_120
    low = librosa.resample(y, orig_sr=SR, target_sr=15 * 512)
    naive, _ = librosa.beat.beat_track(y=low, sr=15 * 512, hop_length=512)
    assert abs(float(np.atleast_1d(naive)[0]) - 120.0) > 2.0
    tempo, _ = beat_track(y=y, sr=SR)
    assert tempo == pytest.approx(120.0, abs=2.0)


@pytest.mark.parametrize("bpm", [75, 97, 140])
def test_beat_track_other_tempi(bpm):
    y = synth.click_track(bpm=bpm, duration=12.0, sr=SR, offset=0.21)
    truth = synth.beat_times(bpm=bpm, duration=12.0, offset=0.21)
    tempo, times = beat_track(y=y, sr=SR)
    assert tempo == pytest.approx(bpm, rel=0.02)
    assert len(times) >= len(truth) - 1
    assert np.abs(times[:, None] - truth[None, :]).min(axis=1).max() < 0.03


def test_beat_onehot_known_answer():
    out = beat_onehot(beat_times=np.array([0.0, 0.49, 1.02, -0.5, 9.0]), fps=10, n_frames=20)
    assert out.dtype == np.float32 and out.shape == (20,)
    assert np.flatnonzero(out).tolist() == [0, 5, 10]  # round(t*fps); out-of-range beats dropped


# --------------------------------------------------------------------------------------------- downbeats


@pytest.mark.parametrize(
    "accent, want",
    [
        ([1, 0, 0, 0] * 8, (4, 0)),
        ([0, 1, 0] * 8, (3, 1)),
        ([1, 0] * 8, (2, 0)),
        ([0, 0, 1, 0.0] * 8, (4, 2)),
        ([1, 0, 0.65, 0] * 8, (4, 0)),  # strong beat 3: 2/4 scores higher, 4/4 within 10 % wins
        ([1, 0, 0.95, 0] * 8, (2, 0)),  # beat 3 nearly as strong as beat 1: 2/4
        ([1, 0, 0], (1, 0)),  # too few beats for any meter
    ],
)
def test_fold_meter_known_answers(accent, want):
    meter, phase, _ = fold_meter(np.array(accent, dtype=float))
    assert (meter, phase) == want


@pytest.mark.parametrize("meter", [2, 3, 4])
@pytest.mark.parametrize("skip", [0, 1])
def test_downbeats_of_accented_click_track(meter, skip):
    bpm, dur = 110.0, 16.0
    y = synth.click_track(bpm=bpm, duration=dur, sr=SR, meter=meter)
    truth = synth.beat_times(bpm=bpm, duration=dur)[::meter]
    cut = skip * 60.0 / bpm - 0.1 if skip else 0.0  # start just before beat `skip`: phase changes
    y = y[int(round(cut * SR)) :]
    truth = truth[truth >= cut] - cut
    _, beats = beat_track(y=y, sr=SR)
    got = downbeats(y=y, sr=SR, beat_times=beats)
    assert set(got) <= set(beats)
    assert len(got) >= len(truth) - 1
    assert np.abs(got[:, None] - truth[None, :]).min(axis=1).max() < 0.05


def test_music2dance_downbeats_of_ode_to_joy():
    y = synth.ode_to_joy(sr=SR)[: 16 * SR]  # 8 bars of 4/4 at 120 BPM: downbeats every 2 s
    fs = extract(y, sr=SR, fps=25, preset="music2dance")
    d = fs.downbeat_times
    assert len(d) >= 7
    np.testing.assert_allclose(np.diff(d), 2.0, atol=0.03)
    assert np.abs(d - np.round(d / 2.0) * 2.0).max() < 0.05
    beat = fs.block("beat")[:, 0]
    down = fs.block("downbeat")[:, 0]
    assert np.all(beat[down == 1] == 1)  # every downbeat is a beat


def test_downbeats_few_or_no_beats():
    y = np.zeros(2 * SR, dtype=np.float32)
    assert downbeats(y=y, sr=SR, beat_times=np.zeros(0)).size == 0
    np.testing.assert_array_equal(downbeats(y=y, sr=SR, beat_times=np.array([0.5, 1.0])), [0.5])


# --------------------------------------------------------------------------------------------- shapes


@pytest.mark.parametrize("preset", sorted(PRESET_DIMS))
@pytest.mark.parametrize("fps", [15, 25, 30])
def test_frame_count_and_dimension(preset, fps):
    fsr = fps * 512
    n = 3 * fsr + 777  # not a multiple of the hop
    y = synth.click_track(bpm=100, duration=n / fsr, sr=fsr)[:n]
    assert len(y) == n
    fs = extract(y, sr=fsr, fps=fps, preset=preset)
    assert fs.features.shape == (1 + n // 512, PRESET_DIMS[preset])
    assert fs.features.dtype == np.float32
    assert sum(int(x.split(":")[1]) for x in fs.names) == PRESET_DIMS[preset]
    assert np.isfinite(fs.features).all()


def test_preset_dims():
    assert PRESET_DIMS == {"revolution": 438, "music2dance": 15, "dual": 53}


def test_frame_count_from_another_sample_rate():
    y = synth.click_track(bpm=100, duration=5.3, sr=44100)
    fs = extract(y, sr=44100, fps=25, preset="music2dance")
    m = int(np.ceil(len(y) * 25 * 512 / 44100))  # length after resampling to 12800 Hz
    assert fs.num_frames == 1 + m // 512


def test_names_and_blocks():
    fs = extract(synth.click_track(bpm=120, duration=3.0, sr=SR), sr=SR, fps=25, preset="revolution")
    assert fs.names == (
        "mfcc:20",
        "mfcc_delta:20",
        "chroma_cqt:12",
        "tempogram:384",
        "onset_strength:1",
        "beat:1",
    )
    assert fs.columns("tempogram") == slice(52, 436)
    assert fs.block("beat").shape == (fs.num_frames, 1)
    with pytest.raises(ParameterError, match="downbeat"):
        fs.block("downbeat")


# --------------------------------------------------------------------------------------------- known answers


@pytest.mark.parametrize("fps", [15, 25])
def test_chroma_of_a4_is_a(fps):
    fsr = fps * 512
    t = np.arange(3 * fsr) / fsr
    y = (0.5 * np.sin(2 * np.pi * 440.0 * t)).astype(np.float32)
    c = chroma_cqt(y=y, sr=fsr)
    assert c.shape == (12, 1 + len(y) // 512)
    mid = c[:, 5:-5]
    assert np.all(np.argmax(mid, axis=0) == 9)  # C=0 ... A=9
    np.testing.assert_allclose(mid.max(axis=0), 1.0)


def test_dual_harmonic_chroma_and_percussive_beats():
    t = np.arange(12 * SR) / SR
    tone = (0.3 * np.sin(2 * np.pi * 440.0 * t)).astype(np.float32)
    truth = synth.beat_times(bpm=120, duration=12.0, offset=0.13)
    y = tone + synth.click_track(bpm=120, duration=12.0, sr=SR, offset=0.13)
    fs = extract(y, sr=SR, fps=25, preset="dual")
    chroma = fs.block("chroma_harmonic")[10:-10]
    assert np.mean(np.argmax(chroma, axis=1) == 9) > 0.95
    got = np.flatnonzero(fs.block("beat_percussive")[:, 0])
    want = np.round(truth * 25).astype(int)
    assert len(got) >= len(want) - 1
    assert np.abs(got[:, None] - want[None, :]).min(axis=1).max() <= 1


def test_onset_strength_peaks_at_clicks():
    fps = 25
    fsr = fps * 512
    y = synth.click_track(bpm=60, duration=6.0, sr=fsr, offset=0.5)
    env = onset_strength(y=y, sr=fsr)
    assert env.shape == (1 + len(y) // 512,) and env.min() >= 0
    peaks = [int(np.argmax(env[k * fps : (k + 1) * fps])) + k * fps for k in range(6)]
    want = [round((0.5 + k) * fps) for k in range(6)]
    assert max(abs(p - w) for p, w in zip(peaks, want)) <= 1


def test_tempogram_peaks_at_the_beat_period():
    fps = 30
    fsr = fps * 512
    y = synth.click_track(bpm=120, duration=20.0, sr=fsr)
    env = onset_strength(y=y, sr=fsr)
    tg = tempogram(onset_envelope=env, sr=fsr)
    assert tg.shape == (384, len(env))
    lag = 5 + int(np.argmax(tg[5:100].mean(axis=1)))
    assert abs(lag - 15) <= 1  # 0.5 s period = 15 frames at 30 fps


def test_mfcc_delta_short_and_linear():
    ramp = np.tile(np.arange(20, dtype=np.float32), (3, 1))  # slope 1 per frame
    d = mfcc_delta(mfcc=ramp)
    np.testing.assert_allclose(d[:, 5:-5], 1.0, atol=1e-5)
    assert mfcc_delta(mfcc=np.ones((20, 2), dtype=np.float32)).tolist() == np.zeros((20, 2)).tolist()
    assert mfcc_delta(mfcc=ramp[:, :4]).shape == (3, 4)


# --------------------------------------------------------------------------------------------- robustness


@pytest.mark.parametrize("preset", sorted(PRESET_DIMS))
def test_silence(preset):
    fs = extract(np.zeros(3 * SR, dtype=np.float32), sr=SR, fps=25, preset=preset)
    assert np.isfinite(fs.features).all()
    assert fs.block(BEAT_COLUMN[preset]).sum() == 0
    assert fs.beat_times.size == 0 and fs.tempo == 0.0
    if preset == "music2dance":
        assert fs.block("downbeat").sum() == 0 and fs.downbeat_times.size == 0


def test_extract_rejects_bad_audio():
    with pytest.raises(AudioError, match="too short"):
        extract(np.zeros(SR // 2, dtype=np.float32), sr=SR, fps=25, preset="dual")
    y = np.zeros(2 * SR, dtype=np.float32)
    y[100] = np.nan
    with pytest.raises(AudioError, match="non-finite"):
        extract(y, sr=SR, fps=25, preset="dual")
    with pytest.raises(ParameterError, match="mono"):
        extract(np.zeros((2, 2 * SR), dtype=np.float32), sr=SR, fps=25, preset="dual")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(preset="salsa"), "'salsa'"),
        (dict(backend="essentia"), "'essentia'"),
        (dict(fps=0), "fps=0|got 0"),
        (dict(fps=-25), "-25"),
        (dict(fps=float("nan")), "nan"),
        (dict(fps="25"), "'25'"),
        (dict(fps=29.97), "29.97"),  # 29.97 * 512 is not a whole number of Hz
        (dict(fps=1000), "fps=1000"),
        (dict(hop_length=0), "hop_length"),
        (dict(hop_length=256.0), "256.0"),
    ],
)
def test_bad_parameters_name_the_value(kwargs, match):
    args = dict(sr=SR, fps=25, preset="music2dance") | kwargs
    with pytest.raises(ParameterError, match=match):
        extract(np.zeros(2 * SR, dtype=np.float32), **args)


def test_feature_sr():
    assert feature_sr(fps=15) == 7680
    assert feature_sr(fps=25, hop_length=512) == 12800
    assert feature_sr(fps=30.0) == 15360
    assert feature_sr(fps=29.97, hop_length=100) == 2997


# --------------------------------------------------------------------------------------------- real audio


@pytest.mark.shared
@pytest.mark.parametrize("song", SONGS, ids=lambda p: p.stem[:24])
@pytest.mark.parametrize("preset", sorted(PRESET_DIMS))
def test_real_songs(music_dir, song, preset, tmp_path):
    fs = extract_file(song, fps=25, preset=preset, start=5.0, end=25.0, use_cache=False)
    assert fs.features.shape == (1 + (20 * 12800) // 512, PRESET_DIMS[preset])
    assert np.isfinite(fs.features).all()
    assert 60 <= fs.tempo <= 200 and len(fs.beat_times) >= 20  # music with a beat
    assert fs.block(BEAT_COLUMN[preset]).sum() == len(np.unique(np.round(fs.beat_times * 25)))
    assert np.std(fs.features, axis=0).max() > 0


@pytest.mark.shared
@pytest.mark.parametrize("recording", NON_MUSIC, ids=lambda p: p.stem[:24])
@pytest.mark.parametrize("preset", sorted(PRESET_DIMS))
def test_non_music_recordings(music_dir, recording, preset):
    fs = extract_file(recording, fps=25, preset=preset, start=0.0, end=20.0, use_cache=False)
    assert fs.features.shape[1] == PRESET_DIMS[preset] and fs.num_frames > 25
    assert np.isfinite(fs.features).all()


# --------------------------------------------------------------------------------------------- cache


@pytest.fixture
def demo_wav(tmp_path):
    return save_wav(tmp_path / "demo.wav", synth.ode_to_joy(sr=SR)[: 8 * SR], sr=SR)


def test_cache_hit_returns_identical_arrays(demo_wav, tmp_path):
    cache = tmp_path / "cache"
    first = extract_file(demo_wav, fps=25, preset="revolution", cache_dir=cache)
    assert not first.from_cache
    assert len(list(cache.glob("*[0-9a-f].npz"))) == 1  # the features (and the song's beats, *.beats.npz)
    second = extract_file(demo_wav, fps=25, preset="revolution", cache_dir=cache)
    assert second.from_cache
    np.testing.assert_array_equal(second.features, first.features)
    np.testing.assert_array_equal(second.beat_times, first.beat_times)
    assert second.names == first.names and second.tempo == first.tempo and second.fps == 25.0
    # any parameter change misses the cache
    third = extract_file(demo_wav, fps=25, preset="revolution", start=1.0, cache_dir=cache)
    assert not third.from_cache and third.num_frames < first.num_frames
    assert len(list(cache.glob("*[0-9a-f].npz"))) == 2


def test_extract_file_caches_the_song_beats_it_tracked(demo_wav, tmp_path):
    """The features step leaves the song's beats (:func:`song_beats_file`, the beat-sync stage's input) in the
    cache: the same beats as tracking them afresh, and the stage does not track them again."""
    from dancekit.features import pulse

    cache = tmp_path / "cache"
    fs = extract_file(demo_wav, fps=25, preset="music2dance", start=1.0, cache_dir=cache)
    entries = list(cache.glob("*.beats.npz"))
    assert len(entries) == 1
    fresh = pulse.song_beats_file(demo_wav, start=1.0, use_cache=False)
    cached = pulse.song_beats_file(demo_wav, start=1.0, cache_dir=cache)
    np.testing.assert_array_equal(cached.times, fresh.times)
    np.testing.assert_array_equal(cached.times, fs.beat_times)
    assert (cached.tempo, cached.clarity, cached.has_beat) == (fresh.tempo, fresh.clarity, fresh.has_beat)
    # the dual preset tracks beats on the percussive part: it leaves no song-beats entry
    extract_file(demo_wav, fps=25, preset="dual", cache_dir=tmp_path / "dual")
    assert not list((tmp_path / "dual").glob("*.beats.npz"))


def test_cache_key_follows_content(demo_wav, tmp_path):
    cache = tmp_path / "cache"
    a = extract_file(demo_wav, fps=25, preset="music2dance", cache_dir=cache)
    save_wav(demo_wav, synth.click_track(bpm=90, duration=8.0, sr=SR), sr=SR)  # same name, new content
    b = extract_file(demo_wav, fps=25, preset="music2dance", cache_dir=cache)
    assert not b.from_cache and not np.array_equal(a.features, b.features)


def test_corrupt_cache_entry_is_recomputed(demo_wav, tmp_path):
    cache = tmp_path / "cache"
    good = extract_file(demo_wav, fps=25, preset="music2dance", cache_dir=cache)
    (entry,) = cache.glob("*[0-9a-f].npz")
    entry.write_bytes(b"not an npz")
    again = extract_file(demo_wav, fps=25, preset="music2dance", cache_dir=cache)
    assert not again.from_cache
    np.testing.assert_array_equal(again.features, good.features)
    assert extract_file(demo_wav, fps=25, preset="music2dance", cache_dir=cache).from_cache  # repaired


def test_no_cache_writes_nothing(demo_wav, tmp_path, monkeypatch):
    monkeypatch.setenv("DANCEKIT_CACHE", str(tmp_path / "root"))
    assert default_cache_dir() == tmp_path / "root" / "features"
    fs = extract_file(demo_wav, fps=25, preset="music2dance", use_cache=False)
    assert not fs.from_cache and not (tmp_path / "root").exists()
    extract_file(demo_wav, fps=25, preset="music2dance")
    assert len(list((tmp_path / "root" / "features").glob("*[0-9a-f].npz"))) == 1


def test_extract_file_errors_name_the_file(tmp_path):
    with pytest.raises(AudioError, match="nope.ogg"):
        extract_file(tmp_path / "nope.ogg", fps=25, preset="dual", cache_dir=tmp_path)
    with pytest.raises(ParameterError, match="'tango'"):
        extract_file(tmp_path / "nope.ogg", fps=25, preset="tango", cache_dir=tmp_path)


def test_featureset_save_load(tmp_path):
    fs = extract(
        synth.click_track(bpm=120, duration=4.0, sr=SR, meter=4), sr=SR, fps=30, preset="music2dance"
    )
    fs.save(tmp_path / "f.npz")
    back = FeatureSet.load(tmp_path / "f.npz")
    np.testing.assert_array_equal(back.features, fs.features)
    np.testing.assert_array_equal(back.downbeat_times, fs.downbeat_times)
    assert (back.names, back.fps, back.preset, back.hop_length) == (fs.names, 30.0, "music2dance", 512)
    (tmp_path / "bad.npz").write_bytes(b"junk")
    with pytest.raises(DancekitError, match="bad.npz"):
        FeatureSet.load(tmp_path / "bad.npz")


# --------------------------------------------------------------------------------------------- CLI


def test_cli_writes_npz(demo_wav, tmp_path, capsys):
    from dancekit.cli.main import main

    out = tmp_path / "out.npz"
    rc = main(["features", str(demo_wav), "-o", str(out), "--preset", "dual", "--fps", "25", "--no-cache"])
    assert rc == 0
    z = np.load(out)
    assert z["features"].shape == (1 + 8 * 12800 // 512, 53) and z["features"].dtype == np.float32
    assert float(z["fps"]) == 25.0 and str(z["preset"]) == "dual"
    assert list(z["names"]) == ["mfcc:20", "mfcc_delta:20", "chroma_harmonic:12", "beat_percussive:1"]
    assert z["beat_times"].dtype == np.float64 and len(z["beat_times"]) >= 14
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "201x53" in lines[0]


def test_cli_missing_file_one_line_on_stderr(tmp_path, capsys):
    from dancekit.cli.main import main

    missing = tmp_path / "missing.mp3"
    rc = main(["features", str(missing), "-o", str(tmp_path / "o.npz"), "--preset", "dual", "--fps", "25"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0]
    assert not (tmp_path / "o.npz").exists()


# --------------------------------------------------------------------------------------------- madmom


def _madmom_or_skip():
    from dancekit.features import import_madmom

    try:
        return import_madmom()
    except ParameterError as exc:
        pytest.skip(str(exc))


def test_madmom_backend():
    _madmom_or_skip()
    y = synth.ode_to_joy(sr=SR)[: 12 * SR]
    fs = extract(y, sr=SR, fps=25, preset="music2dance", backend="madmom")
    assert fs.tempo == pytest.approx(120.0, abs=4.0)
    assert len(fs.beat_times) >= 20
    assert np.abs(fs.beat_times[:, None] - np.arange(0, 12, 0.5)[None]).min(axis=1).max() < 0.06
    assert set(fs.downbeat_times) <= set(fs.beat_times) and len(fs.downbeat_times) >= 4


def test_madmom_missing_gives_parameter_error(monkeypatch):
    import importlib

    from dancekit.features import madmom_backend

    def fail(name, *a, **k):
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    monkeypatch.setattr(importlib, "import_module", fail)
    with pytest.raises(ParameterError, match=r"dancekit\[madmom\]"):
        madmom_backend.import_madmom()
