"""dancekit live (issue 43): online features, the causal beat tracker, the steppers, the online stages, the
session, the pose stream and the CLI. Fast: a few seconds of audio each, fed faster than real time where the
clock does not matter; the 10- and 60-minute runs are benchmarks/bench_live.py."""

from __future__ import annotations

import json
import threading

import mir_eval
import numpy as np
import pytest
import torch

from dancekit.audio.synth import ode_to_joy
from dancekit.errors import ParameterError
from dancekit.features import extract
from dancekit.live import BeatTracker, LiveConfig, OnlineFeatures
from dancekit.live.session import Block, LiveSession

SR = 12800  # the feature rate of the embedded models: 25 fps x hop 512


@pytest.fixture(scope="module")
def song():
    """12 s of a synthetic song with known beats (every 0.5 s: 120 BPM)."""
    return ode_to_joy(sr=SR, bpm=120)[: 12 * SR].astype(np.float32)


def _online(y, *, preset, lookahead_s, block=512, tempogram_future="bar"):
    f = OnlineFeatures(preset=preset, fps=25, lookahead_s=lookahead_s, tempogram_future=tempogram_future)
    rows = [f.feed(y[a : a + block]) for a in range(0, len(y), block)] + [f.finish()]
    return f, np.concatenate(rows)


# ---------------------------------------------------------------------- config
@pytest.mark.parametrize("field, value", [("block_s", 0.0), ("lookahead_s", -1.0), ("calm", 1.5),
                                          ("rate_bound", 0.6), ("smooth_hz", 0.0), ("seed", 1.5),
                                          ("context_s", 1.0), ("max_lag_s", float("nan")),
                                          ("beat_nudge", "push")])
def test_config_rejects_bad_values(field, value):
    with pytest.raises(ParameterError, match=f"LiveConfig.{field}"):
        LiveConfig(**{field: value})


def test_config_from_dict_names_an_unknown_key():
    assert LiveConfig.from_dict({"calm": 0.5}).calm == 0.5
    with pytest.raises(ParameterError, match="lookahed"):
        LiveConfig.from_dict({"lookahed": 0.1})


# ---------------------------------------------------------------------- features
def test_online_features_equal_offline_with_full_lookahead(song):
    """With a lookahead over the features' support the rows are the offline extractor's on the same samples:
    every column once the loudest frame has been heard (the dB floor is 80 dB under the loudest frame so far),
    the tempogram delayed by half its window (192 frames), not the beat column (its own tracker)."""
    off = extract(song, sr=SR, fps=25, preset="revolution")
    f, on = _online(song, preset="revolution", lookahead_s=1.0, tempogram_future="none")
    assert on.shape == off.features.shape == (1 + len(song) // 512, 438)
    from dancekit.features import spectral

    S = spectral.log_melspectrogram(y=song, sr=SR, hop_length=512)
    loudest = int(np.argmax(S.max(axis=0)))
    assert loudest < 150  # the loudest frame (4.1 s) comes in the first half: half the song is compared
    after = slice(loudest + 1, None)
    for name in ("mfcc", "mfcc_delta", "chroma_cqt", "onset_strength"):
        a, b = on[after, f.cols[name]], off.features[after, f.cols[name]]
        np.testing.assert_allclose(a, b, atol=2e-3, rtol=1e-4, err_msg=name)
    # the tempogram: row f is the offline tempogram (librosa's, centred) of the envelope at frame f - 192
    tg = f.cols["tempogram"]
    env = on[:, f.cols["onset_strength"]][:, 0]
    offline_tg = spectral.tempogram(onset_envelope=env, sr=SR, hop_length=512).T  # (T, 384)
    np.testing.assert_allclose(on[192:, tg], offline_tg[:-192], atol=1e-4)
    # the first 192 rows: the window ending at f reaches before the offline padding (a linear ramp to env[0] over
    # 192 frames): zeros there; each row the autocorrelation of the Hann-windowed envelope, scaled to a peak of 1
    padded = np.concatenate([np.zeros(192), np.linspace(0.0, env[0], 193)[:-1], env])
    for fr in (0, 1, 50, 120, 191):
        w = padded[fr : fr + 384] * np.hanning(385)[:-1]  # the periodic Hann window
        ac = np.correlate(w, w, mode="full")[383:]
        ref = ac / np.abs(ac).max() if ac.any() else ac  # all zeros before any sound (the song starts silent)
        np.testing.assert_allclose(on[fr, tg], ref, atol=1e-4, err_msg=f"row {fr}")
    assert on[100:192, tg].any(axis=1).all()


def test_the_bar_tempogram_is_the_centred_one_when_the_bars_repeat():
    """``tempogram_future="bar"``: each row's window is centred on its frame, its future half the envelope's last
    bar repeated. Clicks whose pattern repeats every 2 s (50 frames, sample-exact) make an envelope that repeats
    exactly, so once the first bars have passed each row is the offline (centred) tempogram of the whole envelope,
    computed here by np.correlate as in the test above; the delayed rows (``"none"``) are 7.7 s late instead."""
    bar = 2 * SR
    y = np.zeros(15 * bar, np.float32)
    click = (np.hanning(64) * np.sin(2 * np.pi * 1000 * np.arange(64) / SR)).astype(np.float32)
    for start in range(0, len(y) - bar + 1, bar):
        for k, gain in enumerate((1.0, 0.3, 0.5, 0.3)):  # a loud downbeat, three softer beats
            a = start + k * bar // 4
            y[a : a + 64] += gain * click
    f, on = _online(y, preset="revolution", lookahead_s=1.0)
    _, delayed = _online(y, preset="revolution", lookahead_s=1.0, tempogram_future="none")
    tg = f.cols["tempogram"]
    env = on[:, f.cols["onset_strength"]][:, 0].astype(np.float64)
    assert np.allclose(env[100:150], env[150:200], atol=1e-6)  # the envelope repeats every bar
    padded = np.concatenate([np.linspace(0.0, env[0], 193)[:-1], env, np.linspace(env[-1], 0.0, 193)[1:]])
    for fr in (250, 301, 453, len(env) - 193):
        # frames fr - 192 … fr + 191 under the periodic Hann window, autocorrelated, scaled to a peak of 1
        np.testing.assert_allclose(on[fr, tg], _centred_row(padded, fr), atol=1e-4, err_msg=f"row {fr}")
    # the delayed row of frame 250 is the centred one of frame 58, whose window reaches into the song's padding
    np.testing.assert_allclose(delayed[250, tg], _centred_row(padded, 58), atol=1e-4)
    assert not np.allclose(delayed[250, tg], on[250, tg], atol=1e-2)
    with pytest.raises(ParameterError, match="tempogram_future"):
        LiveConfig(tempogram_future="beat")


def _centred_row(padded: np.ndarray, fr: int) -> np.ndarray:
    w = padded[fr : fr + 384] * np.hanning(385)[:-1]
    ac = np.correlate(w, w, mode="full")[383:]
    return ac / np.abs(ac).max()


def test_online_chroma_equals_the_offline_chromagram_of_its_segment(song, rng):
    """The online chromagram of a few frames of a segment — at its start, in its middle, at its end (the
    centred frames' zero padding), odd and even lengths — is the offline chromagram of that segment at those
    frames, its octave decimation (one resampler, cleared between calls) the offline ``halve``'s samples."""
    from dancekit.features import dsp, spectral
    from dancekit.features.online import OnlineChroma

    ch = OnlineChroma(sr=SR, hop_length=512)
    for n in (1001, 4096, 17000):
        y = rng.standard_normal(n).astype(np.float32)
        for _ in range(2):  # the resampler used again: cleared
            np.testing.assert_array_equal(ch._halve(y), dsp.halve(y))
    for a, n in ((0, 9 * 512), (3 * SR, 40 * 512 + 77), (5 * SR, 25 * 512)):
        seg = song[a : a + n]
        off = spectral.chroma_cqt(y=seg, sr=SR, hop_length=512).T  # (1 + n // 512, 12)
        for frames in ([0], [1, 2], [len(off) // 2], [len(off) - 3, len(off) - 1]):
            np.testing.assert_allclose(ch.frames(seg, np.array(frames)), off[frames], rtol=0, atol=1e-5)


def test_online_features_short_lookahead_stays_close(song):
    """At the default lookahead (0.08 s) the frames' right edge is zero-padded (the song "ends" there): the
    MFCCs, the onset envelope and the tempogram are still exact; the MFCC delta of a row is the offline delta of
    the audio received when the row was made (the song's end: its last 9 frames fit), fed one frame at a time;
    the chromagram moves by a bounded amount (measured here: median 0.02; the chroma is in [0, 1])."""
    from dancekit.features import spectral

    off = extract(song, sr=SR, fps=25, preset="revolution").features
    f = OnlineFeatures(preset="revolution", fps=25, lookahead_s=0.08)
    rows, received = [], []
    for a in range(0, len(song), 512):
        new = f.feed(song[a : a + 512])
        rows.append(new)
        received += [min(len(song), a + 512)] * len(new)
    on = np.concatenate(rows + [f.finish()])
    S = spectral.log_melspectrogram(y=song, sr=SR, hop_length=512)
    k = int(np.argmax(S.max(axis=0))) + 1
    np.testing.assert_allclose(on[k:, f.cols["mfcc"]], off[k:, f.cols["mfcc"]], atol=2e-3, rtol=1e-4)
    np.testing.assert_allclose(on[k:, f.cols["onset_strength"]], off[k:, f.cols["onset_strength"]], atol=2e-3)
    for fr in range(k, len(received), 41):
        m = spectral.mfcc(S=spectral.log_melspectrogram(y=song[: received[fr]], sr=SR, hop_length=512), sr=SR)
        np.testing.assert_allclose(on[fr, f.cols["mfcc_delta"]], spectral.mfcc_delta(mfcc=m)[:, fr], atol=2e-3,
                                   rtol=1e-3, err_msg=f"frame {fr}")
    chroma = np.abs(on[k:, f.cols["chroma_cqt"]] - off[k:, f.cols["chroma_cqt"]])
    assert np.median(chroma) < 0.05 and chroma.max() < 0.6


def test_online_features_reject_dual():
    with pytest.raises(ParameterError, match="dual"):
        OnlineFeatures(preset="dual", fps=25)


# ---------------------------------------------------------------------- beats
def test_beat_tracker_finds_the_beats_of_a_known_song(song):
    """The synthetic song's beats are at k · 0.5 s: once settled (after 4 s) every tracked beat is within
    ±70 ms of one, and the tempo is 120 BPM."""
    f, _ = _online(song, preset="music2dance", lookahead_s=0.08)
    times = np.array([b.time for b in f.tracker.beats])
    truth = np.arange(0, 12, 0.5)
    score = mir_eval.beat.f_measure(truth[truth > 4], times[times > 4], f_measure_threshold=0.07)
    assert score >= 0.95
    assert abs(f.tracker.bpm - 120) < 1.0


def test_beat_tracker_click_track_at_another_tempo():
    """A click track at 97 BPM from 1.3 s: the tempo and the phase follow it (each beat ±70 ms)."""
    from dancekit.audio.synth import click_track

    y = click_track(bpm=97, duration=14.0, sr=SR, offset=1.3).astype(np.float32)
    f, _ = _online(y, preset="music2dance", lookahead_s=0.08)
    times = np.array([b.time for b in f.tracker.beats])
    truth = 1.3 + np.arange(0, 20) * 60 / 97
    truth = truth[truth < 13.5]
    assert mir_eval.beat.f_measure(truth[truth > 5], times[times > 5], f_measure_threshold=0.07) >= 0.95
    assert abs(f.tracker.bpm - 97) < 1.5


def test_beat_tracker_places_no_beat_in_silence():
    t = BeatTracker(rate=100.0)
    assert t.feed(np.zeros(1000)) == [] and t.bpm is None


def test_beat_tracker_against_the_offline_beats_of_the_same_song():
    """The live beats against the offline tracker's (:func:`dancekit.features.pulse.song_beats`) on the same
    song (a synthetic song at 132 BPM: the offline beats are right there), F1 at ±70 ms once settled (after 6 s).
    Real recordings: docs/results/live_beats.json (measured, not asserted)."""
    from dancekit.features.pulse import song_beats

    y = ode_to_joy(sr=SR, bpm=132)[: 18 * SR].astype(np.float32)
    offline = song_beats(y=y, sr=SR).times
    truth = np.arange(0, 18, 60 / 132)
    assert mir_eval.beat.f_measure(truth[truth > 6], offline[offline > 6], f_measure_threshold=0.07) > 0.95
    f, _ = _online(y, preset="music2dance", lookahead_s=0.08)
    times = np.array([b.time for b in f.tracker.beats])
    assert mir_eval.beat.f_measure(offline[offline > 6], times[times > 6], f_measure_threshold=0.07) >= 0.9


# ---------------------------------------------------------------------- steppers
@pytest.fixture(scope="module")
def revolution():
    from dancekit.pipelines import load_pipeline

    return load_pipeline("revolution")


def test_revolution_stepper_equals_one_offline_pass(revolution, rng):
    """Lookahead and context at the encoder's receptive field (100 frames each side): the latents are the
    offline ones, and the decoder stepped block by block with its state carried gives the offline dance."""
    from dancekit.live.steppers import RevolutionStepper
    from dancekit.motion.kinematics import normalize_bone_lengths
    from dancekit.motion.representations import decode_positions

    pipe = revolution
    T = 240
    raw = rng.standard_normal((T, 438)).astype(np.float32) * pipe.stats.music_std + pipe.stats.music_mean
    st = RevolutionStepper(pipe, lookahead=100, context=100, seed=5, variety=False)
    out = [st.push(raw[a : a + 7]) for a in range(0, T, 7)] + [st.finish()]
    on = np.concatenate(out)
    x = torch.from_numpy(pipe.stats.normalize_music(raw).astype(np.float32))[None]
    y = pipe.model.generate(x, generator=torch.Generator().manual_seed(5), variety=None)[0].numpy()
    off = normalize_bone_lengths(decode_positions(pipe.stats.denormalize_dance(y), pipe.skeleton).astype(np.float64),
                                 pipe.skeleton)
    assert on.shape == (T, pipe.skeleton.num_joints, 3)
    # cm: the two encoder chunkings round the latents differently (~1e-6), and the autoregressive decoder carries
    # that forward: measured 0.07 cm (torch's decoder) and 0.09 cm (NumPy's) by frame 240 on another random song,
    # 1e-4 cm over the first 60 frames; a state lost between blocks moves joints by centimetres
    np.testing.assert_allclose(on[:60], off[:60], atol=1e-3)
    np.testing.assert_allclose(on, off, atol=0.5)


def _tiny_revolution(lookahead):
    """A small Dance Revolution pipeline (random weights) whose encoder looks ``lookahead`` frames ahead per layer."""
    from dancekit.models.revolution import RevolutionConfig, RevolutionModel
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.revolution import RevolutionPipeline

    ref = load_pipeline("revolution")
    torch.manual_seed(0)
    model = RevolutionModel(RevolutionConfig(music_dim=438, pose_dim=72, d_model=16, n_heads=2, d_ff=32, window=20,
                                             lookahead=lookahead, decoder_hidden=16)).eval()
    meta = {"fps": 25.0, "skeleton": ref.skeleton.to_dict(), "representation": "positions3d", "preset": "revolution"}
    return RevolutionPipeline(model, meta=meta, stats=ref.stats, folder="tiny")


def test_revolution_stepper_of_a_lookahead_encoder_is_the_same_for_any_block(rng):
    """An encoder that looks 1 frame ahead per layer (2 in all): stepped with a lookahead of 2 frames, the dance is
    one offline pass, whatever the blocks (1, 2, 5 or uneven rows at a time) — its latents never see the stream's
    end. The symmetric encoder stepped the same way is not (its latents near the end see less than offline)."""
    from dancekit.live.steppers import RevolutionStepper

    T = 120
    for lookahead, same in ((1, True), (None, False)):
        pipe = _tiny_revolution(lookahead)
        raw = rng.standard_normal((T, 438)).astype(np.float32) * pipe.stats.music_std + pipe.stats.music_mean
        dances = []
        for sizes in ((1,), (2,), (5,), (3, 1, 7, 2)):
            st = RevolutionStepper(pipe, lookahead=2, context=20, seed=3, variety=False)
            out, a, i = [], 0, 0
            while a < T:
                n = sizes[i % len(sizes)]
                out.append(st.push(raw[a : a + n]))
                a, i = a + n, i + 1
            out.append(st.finish())
            dances.append(np.concatenate(out))
        whole = RevolutionStepper(pipe, lookahead=T, context=20, seed=3, variety=False)
        off = np.concatenate([whole.push(raw), whole.finish()])
        for d in dances:
            assert d.shape == off.shape
            assert np.allclose(d, off, atol=1e-3) == same


def test_session_steps_the_live_component_and_waits_no_longer_than_its_encoder(tmp_path):
    """A checkpoint declaring a ``live`` component: the session steps that model (its encoder's 2 frames are the
    lookahead, even when the config allows more); without one, the model itself with the config's lookahead."""
    import shutil

    from dancekit.checkpoints import write_pretrained
    from dancekit.checkpoints.hub import resolve_model
    src = resolve_model("revolution")
    folder = tmp_path / "rev"
    shutil.copytree(src, folder)
    live = _tiny_revolution(1)
    (folder / "live").mkdir()
    meta = json.loads((folder / "config.json").read_text())
    write_pretrained(folder / "live", live.model, live.model.config, stats=live.stats,
                     extra={k: meta[k] for k in ("representation", "preset", "fps", "hop_length", "skeleton")})
    meta["components"]["live"] = "live"
    (folder / "config.json").write_text(json.dumps(meta))
    s = LiveSession(str(folder), config=LiveConfig(model_lookahead_s=0.4))
    assert s.live_pipe is not s.pipe and s.live_pipe.model.config.lookahead == 1
    assert s.stepper.model is s.live_pipe.model and s.stepper.lookahead == 2 == live.model.encoder.bounded_lookahead
    assert s.live_pipe.variety == s.pipe.variety  # the parent's seed variety
    plain = LiveSession("revolution", config=LiveConfig(model_lookahead_s=0.4))
    assert plain.live_pipe is plain.pipe and plain.stepper.lookahead == 10


def _tiny_music2dance(sampling=None):
    """A small Music2Dance model whose music condition is the features themselves (no F_map): causal
    end to end, so a stepped dance must equal one offline pass whatever the blocks; ``sampling``: its
    checkpoint's sampling entry (default: temperature 0.7, noise correlation 0.5, no smoothing)."""
    from dancekit.checkpoints import NormStats
    from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel
    from dancekit.motion import Skeleton
    from dancekit.motion.root_delta import rootdelta_layout
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.music2dance import Music2DancePipeline

    ref = load_pipeline("music2dance")
    sk = ref.skeleton
    P = rootdelta_layout(sk).dim
    torch.manual_seed(0)
    model = Music2DanceModel(Music2DanceConfig(music_dim=15, pose_dim=P, n_layers=6, channels=8, skip_channels=8,
                                               music_condition="raw", n_genres=2)).eval()
    stats = NormStats(music_mean=np.zeros(15, np.float32), music_std=np.ones(15, np.float32),
                      dance_mean=np.zeros(P, np.float32), dance_std=np.full(P, 0.1, np.float32))
    meta = {"fps": 25.0, "skeleton": sk.to_dict(), "genres": ["a", "b"],
            "sampling": sampling or {"temperature": 0.7, "noise_correlation": 0.5}}
    assert isinstance(Skeleton.from_dict(meta["skeleton"]), Skeleton)
    return Music2DancePipeline(model, meta=meta, stats=stats, folder="tiny")


def test_music2dance_stepper_carries_its_state_across_blocks(rng):
    from dancekit.live.steppers import Music2DanceStepper
    from dancekit.motion.root_delta import decode_rootdelta

    pipe = _tiny_music2dance()
    T = 90
    raw = rng.standard_normal((T, 15)).astype(np.float32)
    st = Music2DanceStepper(pipe, lookahead=0, context=8, seed=2, genre="b")
    on = np.concatenate([st.push(raw[a : a + 4]) for a in range(0, T, 4)] + [st.finish()])
    y = pipe.model.generate(torch.from_numpy(raw)[None], torch.tensor([1]), temperature=0.7,
                            generator=[torch.Generator().manual_seed(2)], noise_correlation=0.5, reference=True)[0]
    off = decode_rootdelta(pipe.stats.denormalize_dance(y.numpy().astype(np.float64)), pipe.skeleton, 25.0).positions
    assert on.shape == off.shape
    np.testing.assert_allclose(on, off, atol=1e-3)


def _gaussian_reference(x, sigma, *, ahead):
    """Row t: the Gaussian-weighted mean of rows t - r ... t + a (r = round(3 sigma), a = r or 0 for True / False,
    else min(ahead, r)), the first and last rows repeated beyond the ends: written out sum by sum, apart from the
    code under test."""
    r = int(round(3 * sigma))
    a = (r if ahead else 0) if isinstance(ahead, bool) else min(ahead, r)
    T = len(x)
    out = np.empty((T, x.shape[1]))
    for t in range(T):
        acc, total = 0.0, 0.0
        for k in range(-r, a + 1):
            w = np.exp(-(k * k) / (2.0 * sigma * sigma))
            acc = acc + w * x[min(max(t + k, 0), T - 1)].astype(np.float64)
            total += w
        out[t] = acc / total
    return out


@pytest.mark.parametrize("ahead", [True, False, 2, 0, 9])
def test_sample_smoother_equals_the_gaussian_of_the_whole_stream(ahead, rng):
    """Rows pushed in uneven blocks: the delayed smoother gives the centred Gaussian of the whole stream (the offline
    smoothing, edges repeated), the causal one the Gaussian's past half, a hold-back of a frames the lags up to a;
    the columns after ``columns`` (the contacts) pass unchanged; the delay holds back exactly the radius (6 rows for
    sigma 2) or the hold-back (at most the radius)."""
    from dancekit.live.steppers import SampleSmoother
    from dancekit.models.foot_constraint import gaussian_smooth

    x = rng.standard_normal((70, 5)).astype(np.float32)
    sm = SampleSmoother(2.0, ahead=ahead, columns=3)
    out, held = [], []
    a = 0
    for n in (1, 2, 9, 3, 20, 1, 1, 30, 3):
        got = sm.push(x[a : a + n])
        a += n
        out.append(got)
        held.append(a - sum(len(o) for o in out))
    out.append(sm.push(x[:0], final=True))
    on = np.concatenate(out)
    assert on.shape == x.shape
    assert set(held[2:]) == {(6 if ahead else 0) if isinstance(ahead, bool) else min(ahead, 6)}
    np.testing.assert_allclose(on[:, :3], _gaussian_reference(x[:, :3], 2.0, ahead=ahead), atol=1e-5)
    np.testing.assert_array_equal(on[:, 3:], x[:, 3:])
    if ahead is True or ahead == 9:
        off = gaussian_smooth(torch.from_numpy(x[None, :, :3]), 2.0)[0].numpy()
        np.testing.assert_allclose(on[:, :3], off, atol=1e-5)


@pytest.mark.parametrize("genre, sigma", [("a", 1.0), ("b", 0.5)])
def test_music2dance_stepper_smooths_its_samples_as_the_checkpoint_says(genre, sigma, rng):
    """The checkpoint's smooth_sigma (genre b has its own): the stepped dance is the offline samples smoothed with
    the centred Gaussian (delayed by its radius), decoded; the causal form with the Gaussian's past half."""
    from dancekit.live.steppers import Music2DanceStepper
    from dancekit.motion.root_delta import decode_rootdelta

    pipe = _tiny_music2dance(sampling={"temperature": 0.7, "noise_correlation": 0.5, "smooth_sigma": 1.0,
                                       "genres": {"b": {"smooth_sigma": 0.5}}})
    T, D = 90, pipe.model.config.gmm_dim
    raw = rng.standard_normal((T, 15)).astype(np.float32)
    y = pipe.model.generate(torch.from_numpy(raw)[None], torch.tensor([pipe.genres.index(genre)]), temperature=0.7,
                            generator=[torch.Generator().manual_seed(2)], noise_correlation=0.5,
                            reference=True)[0].numpy()
    for smoothing in ("delay", "causal"):
        st = Music2DanceStepper(pipe, lookahead=0, context=8, seed=2, genre=genre, smoothing=smoothing)
        assert st.delay == (int(round(3 * sigma)) if smoothing == "delay" else 0)
        on = np.concatenate([st.push(raw[a : a + 4]) for a in range(0, T, 4)] + [st.finish()])
        ys = y.astype(np.float64).copy()
        ys[:, :D] = _gaussian_reference(y[:, :D], sigma, ahead=smoothing == "delay")
        off = decode_rootdelta(pipe.stats.denormalize_dance(ys), pipe.skeleton, 25.0).positions
        assert on.shape == off.shape
        np.testing.assert_allclose(on, off, atol=1e-3)


@pytest.mark.slow
def test_live_music2dance_trembles_no_more_than_offline(tmp_path):
    """The embedded music2dance on 16 s of a synthetic song, live (fed block by block) and offline (the model
    alone, every stage): the live dance's jitter per unit of smoothed energy stays within 1.3x the offline one's
    (measured: 0.9x; the samples unsmoothed, as before the fix: 3.2x; the causal half-kernel: 1.4x)."""
    import soundfile as sf

    from dancekit.metrics.stability import jitter, smoothed_energy
    from dancekit.pipelines import load_pipeline

    y = ode_to_joy(sr=SR, bpm=120)[: 16 * SR].astype(np.float32)
    sf.write(tmp_path / "song.wav", y, SR)
    pipe = load_pipeline("music2dance")

    def tremble(p, sk):
        return jitter(p, fps=25, skeleton=sk)["speed_residual"] / smoothed_energy(p, fps=25, skeleton=sk)

    off = pipe(tmp_path / "song.wav", seed=0, genre="none").motion
    s = LiveSession("music2dance", pipe=pipe)
    frames = [f for a in range(0, len(y), 512) for f in s.feed([Block(y[a : a + 512], 0.0)], now=lambda: 0.0)]
    frames += s.finish()
    live = np.stack([f.joints for f in frames])
    assert live.shape == off.positions.shape
    assert tremble(live, s.skeleton) < 1.3 * tremble(off.to_positions(), off.skeleton)


def test_stepper_rejects_an_unknown_genre():
    from dancekit.live.steppers import Music2DanceStepper

    with pytest.raises(ParameterError, match="unknown genre 'salsa'"):
        Music2DanceStepper(_tiny_music2dance(), lookahead=0, context=8, genre="salsa")


# ---------------------------------------------------------------------- session
def _blocks(y, n=512, gaps=()):
    """The song as blocks (arrival: now); the block indices in ``gaps`` are dropped (None)."""
    import time

    return [Block(None if i in gaps else y[a : a + n], time.monotonic(), n=len(y[a : a + n]))
            for i, a in enumerate(range(0, len(y), n))]


def _speed(p, fps=25.0):
    return np.linalg.norm(np.diff(p, axis=0), axis=-1).mean(axis=1) * fps  # (T - 1,) cm/s, mean over joints


@pytest.mark.slow
@pytest.mark.parametrize("model", ["revolution", "music2dance"])
def test_session_dances_silence_and_the_music_coming_back(model, song):
    """4 s of music, 3 s of silence, 3 s of music again (one block dropped in the middle of the music): every
    frame comes out, finite, on the floor; in the silence the dancer calms (slower) without freezing, and the
    music coming back brings the speed back."""
    y = song[: 10 * SR].copy()
    y[4 * SR : 7 * SR] = 0.0
    s = LiveSession(model)
    frames = []
    for b in _blocks(y, n=2048, gaps={10}):
        # each block handled as it arrives: never behind, so the dance does not depend on the machine's load
        # (behind the clock the session would take its lighter path)
        frames.extend(s.feed([b], now=lambda b=b: b.arrival))
    frames.extend(s.finish())
    assert s.stats.light_blocks == 0
    assert [f.index for f in frames] == list(range(1 + len(y) // 512))
    p = np.stack([f.joints for f in frames]).astype(np.float64)
    assert np.isfinite(p).all()
    up = s.skeleton.up_index
    # the lowest joint near the floor (cm): the causal floor (5th percentile of the last 2 s) leaves a bouncing
    # dance a few cm up (measured: music2dance 5.3 cm, revolution under 1 cm; offline's centred curve: 0.2)
    assert abs(np.median(p[:, :, up].min(axis=1))) < 6.0
    v = _speed(p)
    music, silence, back = v[75:100].mean(), v[140:175].mean(), v[215:245].mean()
    assert 0.02 * music < silence < 0.8 * music  # calmer, not frozen
    assert back > 1.25 * silence
    # frames whose centre lies in a block of silence (blocks of 0.16 s: frames 100-171)
    assert not any(f.music for f in frames[101:171]) and all(f.music for f in frames[75:99])
    assert s.stats.dropped_blocks == 1


def test_session_dances_from_the_start_while_the_tracker_warms_up(song):
    """The beat tracker needs 3 s of sound before it can tell a pulse: meanwhile the dancer dances (the frames
    say music, and the poses are those of a session that never calms), it does not calm as if the song were
    speech."""
    y = song[: 4 * SR]
    got = {}
    for calm in (0.4, 1.0):
        s = LiveSession("revolution", config=LiveConfig(calm=calm))
        # on a clock that never falls behind (the lighter path would change the features)
        got[calm] = [f for a in range(0, len(y), 512) for f in s.feed([Block(y[a : a + 512], 0.0)], now=lambda: 0.0)]
    warm = [f for f in got[0.4] if f.time < 2.8]
    assert len(warm) == 70 and all(f.music for f in warm)
    np.testing.assert_array_equal(np.stack([f.joints for f in warm]),
                                  np.stack([f.joints for f in got[1.0][: len(warm)]]))


def test_session_nudges_within_the_offline_warp_bound_of_its_model():
    """The beat nudge's rate bound is the model's offline warp bound (its checkpoint's
    stages.beat_sync.max_rate_change, else ±15 %) unless the config names one; 0: no nudge."""
    from pathlib import Path

    import dancekit

    folder = Path(dancekit.__file__).parent / "assets" / "models" / "music2dance"
    bound = json.loads((folder / "config.json").read_text())["stages"]["beat_sync"]["max_rate_change"]
    assert LiveSession("music2dance").nudge.bound == bound != 0.15
    assert LiveSession("revolution").nudge.bound == 0.15
    assert LiveSession("music2dance", config=LiveConfig(rate_bound=0.1)).nudge.bound == 0.1
    assert LiveSession("music2dance", config=LiveConfig(rate_bound=0.0)).nudge is None


@pytest.mark.parametrize("model, smoothing, hold, floor", [("revolution", "delay", 0.08, 0.12),
                                                           ("music2dance", "delay", None, 0.36),
                                                           ("music2dance", "delay", 0.08, 0.20),
                                                           ("music2dance", "causal", 0.08, 0.12)])
def test_session_latency_is_logged_apart_from_the_lookahead(model, smoothing, hold, floor, song):
    """Blocks of 0.04 s arriving on a clock (block k at (k + 1) · 0.04 s) and handled 10 ms after arrival: each
    frame's latency is its lookahead plus those 10 ms. The lookahead, from the arrival of the block holding the
    frame's centre (block f for frame f, at (f + 1) · 0.04 s) to the arrival of the block that completes its
    0.08 s feature and 2-frame model lookahead (block f + 3: its rows up to f + 2 need samples up to
    (f + 2) · 512 + 1024), is 3 blocks: 0.12 s for every frame but the last ones (danced at the end); music2dance's
    delayed smoothing holds each frame back 6 frames more (its Gaussian's radius, sigma 2): 0.36 s; with a hold of
    0.08 s (the default), 2 frames more: 0.20 s."""
    s = LiveSession(model, config=LiveConfig(sample_smoothing=smoothing, smoothing_hold_s=hold))
    y = song[: 4 * SR]
    n = 512
    for k, a in enumerate(range(0, len(y), n)):
        arrival = (k + 1) * n / SR
        s.feed([Block(y[a : a + n], arrival)], now=lambda t=arrival: t + 0.01)
    lat, look = np.array(s.stats.latency), np.array(s.stats.lookahead)
    assert len(lat) > 80
    np.testing.assert_allclose(lat - look, 0.01, atol=1e-9)
    np.testing.assert_allclose(look, floor, atol=1e-9)


# ---------------------------------------------------------------------- pose stream
def test_pose_stream_client_reads_frames_with_increasing_timestamps(song):
    """A client of the documented pose stream: the hello (skeleton), then pose frames in order."""
    from websockets.sync.client import connect

    from dancekit.live.server import PoseServer, hello_message

    s = LiveSession("revolution")
    server = PoseServer(hello_message(s.skeleton, fps=s.fps, model="revolution"), port=0).start()
    s.sinks.append(server.send)
    got: list[dict] = []
    try:
        with connect(f"ws://127.0.0.1:{server.port}/poses", open_timeout=10) as ws:
            hello = json.loads(ws.recv(timeout=10))
            feeder = threading.Thread(target=lambda: [s.feed([b]) for b in _blocks(song[: 3 * SR])])
            feeder.start()
            while len(got) < 40:
                got.append(json.loads(ws.recv(timeout=20)))
            feeder.join(timeout=60)
    finally:
        server.stop()
    assert hello["type"] == "hello" and len(hello["parents"]) == len(hello["joint_names"]) == s.skeleton.num_joints
    assert all(m["type"] == "pose" for m in got)
    assert [m["frame"] for m in got] == list(range(40))
    t = np.array([m["t"] for m in got])
    sent = np.array([m["sent"] for m in got])
    assert (np.diff(t) > 0).all() and (np.diff(sent) >= 0).all()
    assert np.array(got[-1]["joints"]).shape == (s.skeleton.num_joints, 3)


def test_live_page_is_served():
    import urllib.request

    from dancekit.live.server import PoseServer

    server = PoseServer({"type": "hello"}, port=0).start()
    try:
        html = urllib.request.urlopen(server.url, timeout=10).read().decode()
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(server.url + "nothing", timeout=10)
    finally:
        server.stop()
    assert "/poses" in html and "<canvas" in html


@pytest.mark.parametrize("model", ["revolution", "music2dance"])
def test_rest_bones_equal_the_offline_bone_lengths(model, rng):
    """The live stages' bone lengths (NumPy, a tree level at a time) equal the offline normalize_bone_lengths: a
    block of one frame, a batch of blocks, a bone of zero length (its rest offset) and a model's own dance."""
    from dancekit.live.stages import RestBones
    from dancekit.motion.kinematics import normalize_bone_lengths
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline(model).skeleton
    rest = RestBones(sk)
    J = sk.num_joints
    x = rng.standard_normal((40, J, 3)) * 30.0
    child = next(j for j in range(J) if sk.parents[j] >= 0)
    x[3, child] = x[3, sk.parents[child]]  # a bone of zero length
    for poses in (x[:1], x, x.reshape(4, 10, J, 3), x.astype(np.float32)):
        got = rest(poses)
        assert got.dtype == np.float64 and got.shape == poses.shape
        np.testing.assert_allclose(got, normalize_bone_lengths(poses, sk), rtol=0, atol=1e-9)
    lengths = np.linalg.norm(got[..., [j for j in range(J) if sk.parents[j] >= 0], :]
                             - got[..., [p for p in sk.parents if p >= 0], :], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(sk.offsets, axis=-1)[np.asarray(sk.parents) >= 0],
                                                        lengths.shape), atol=1e-9)
    s = LiveSession(model)
    s.stepper.raw = True
    raw = s.stepper.push(rng.standard_normal((60, s.pipe.model.config.music_dim)).astype(np.float32))
    raw = np.concatenate([raw, s.stepper.finish()]).astype(np.float64) if len(raw) else s.stepper.finish()
    np.testing.assert_allclose(rest(raw), normalize_bone_lengths(raw, sk), rtol=0, atol=1e-6)


def test_online_floor_bounds_turn_the_path_as_offline():
    """A figure drifting in a straight line at 0.8 m/s for 30 s, its arms swinging, fed to the online stages in
    pieces (music playing, no smoothing): its horizontal positions are the offline clean-up's turned path
    (:func:`dancekit.motion.cleanup.contain_root_path`) — beyond 4 m it loops back, it does not stop at the
    edge."""
    from dancekit.live.stages import OnlineStages
    from dancekit.motion.analysis import horizontal_axes, rest_pose
    from dancekit.motion.cleanup import contain_root_path
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline("revolution").skeleton
    fps, T = 25.0, 750
    a, b = horizontal_axes(sk)
    t = np.arange(T) / fps
    p = np.repeat(rest_pose(sk)[None], T, axis=0)
    p[..., sk.up_index] -= p[0, :, sk.up_index].min()
    p[:, :, a] += 80.0 * t[:, None]  # cm: 0.8 m/s
    p[:, :, b] += 10.0 * np.sin(0.5 * t)[:, None]
    hands = [sk.index(n) for n in ("left_wrist", "right_wrist")]
    p[:, hands, b] += 15.0 * np.sin(2 * np.pi * t)[:, None]  # bone lengths change: set back by the stages
    stages = OnlineStages(sk, fps=fps, config=LiveConfig(smooth_hz=float("inf")))
    on = np.concatenate([stages.process(p[k : k + 9], np.ones(len(p[k : k + 9]), bool)) for k in range(0, T, 9)])
    from dancekit.motion.kinematics import normalize_bone_lengths

    off = contain_root_path(np.asarray(normalize_bone_lengths(p, sk), np.float64), skeleton=sk, fps=fps)
    np.testing.assert_allclose(on[..., [a, b]], off[..., [a, b]], atol=0.05)  # cm (float32 out)
    travel = np.hypot(*(on[:, sk.root, [a, b]] - on[0, sk.root, [a, b]]).T)
    assert travel.max() < 12 * 100 and travel[-1] < 0.5 * 80.0 * t[-1]  # turned back, within the hard bound
    assert np.linalg.norm(np.diff(on[:, sk.root, [a, b]], axis=0), axis=1).min() > 0.5 * 80.0 / fps  # never stuck


def test_online_ground_contact_takes_the_float_away():
    """A figure floating 2-14 cm over the floor (0.7 Hz) through the online stages (music playing, no smoothing):
    the ground contact takes the float away and never puts the lowest joint under the floor (measured: median
    0.3 cm, at most 4.9 cm while it rises; without the stage, after the 2-s floor alone: median 5.6 cm, up to
    11.8 cm, 1 cm under the floor)."""
    from dancekit.live.stages import OnlineStages
    from dancekit.motion.analysis import rest_pose
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline("revolution").skeleton
    fps, T, up = 25.0, 500, sk.up_index
    t = np.arange(T) / fps
    p = np.repeat(rest_pose(sk)[None], T, axis=0)
    p[..., up] += (8.0 - p[0, :, up].min() + 6.0 * np.sin(2 * np.pi * 0.7 * t))[:, None]
    stages = OnlineStages(sk, fps=fps, config=LiveConfig(smooth_hz=float("inf")))
    on = np.concatenate([stages.process(p[k : k + 7], np.ones(len(p[k : k + 7]), bool)) for k in range(0, T, 7)])
    low = on[:, :, up].min(axis=1)[50:]  # cm, after the first 2 s
    assert low.min() > -1e-3 and np.median(low) < 1.0 and low.max() < 6.0


# ---------------------------------------------------------------------- beat alignment
def test_beat_nudge_moves_the_kinematic_beats_towards_the_music_beats():
    """A dance whose speed minima come every 0.5 s but 0.17 s after the music's beats (wandering ±0.1 s): the
    nudged clock (rate within ±15 %, at most 0.24 s behind the model) brings them closer to the beats (median
    distance 0.22 s → 0.10 s, measured), never runs ahead of the model nor falls further behind than allowed."""
    from dancekit.live.stages import BeatNudge

    fps, T = 25.0, 1000
    rng = np.random.default_rng(0)
    t = np.arange(T) / fps
    kinematic = 0.17 + np.arange(0, 45, 0.5) + np.cumsum(rng.normal(0, 0.02, 90)).clip(-0.1, 0.1)
    pos = np.zeros((T, 2, 3))
    pos[:, 1, 0] = 30 * np.cos(np.pi * np.interp(t, kinematic, np.arange(len(kinematic))))
    beats = np.arange(0.0, 45, 0.5)

    def distances(p):
        v = np.linalg.norm(np.diff(p, axis=0), axis=-1).mean(axis=1)
        minima = (np.array([i for i in range(1, len(v) - 1) if v[i] < v[i - 1] and v[i] <= v[i + 1]]) + 0.5) / fps
        return np.array([np.abs(beats - m).min() for m in minima[minima > 8]])

    nudge = BeatNudge(fps=fps, rate_bound=0.15, max_lag_s=0.24)
    out = np.stack([nudge.process(pos[i : i + 1], beats[beats > t[i]][0])[0] for i in range(T)])
    before, after = np.median(distances(pos)), np.median(distances(out))
    assert after < 0.6 * before
    assert all(0.85 - 1e-9 <= r <= 1.15 + 1e-9 for r in nudge.rates)
    # each shown pose lies between the model's poses at most 6 frames (0.24 s) back and the newest one
    for i in range(T):  # an interpolation of two of the last 7 frames: within their range
        recent = pos[max(0, i - 6) : i + 1, 1, 0]
        assert recent.min() - 1e-9 <= out[i, 1, 0] <= recent.max() + 1e-9
    # no beat predicted: rate 1 once the clock has settled half the allowed lag (3 frames) behind the model
    plain = BeatNudge(fps=fps).process(pos[:200], None)
    np.testing.assert_allclose(plain[100:], pos[97:197], atol=1e-3)


def test_beat_nudge_pulse_puts_the_speed_dips_on_the_beats():
    """A dance at a constant speed (a joint on a circle, 0.6 m/s: no kinematic beat of its own) played with the
    pulse (beats every 0.5 s, rate within ±15 %): its speed dips to 0.85× on each beat and rises to 1.15× between
    two (measured from the rate law, the clock kept 3 frames behind the model), so every speed minimum after the
    first 2 s is within one frame of a beat and there is one per beat."""
    from dancekit.live.stages import BeatNudge

    fps, T = 25.0, 500
    t = np.arange(T) / fps
    pos = np.zeros((T, 2, 3))
    pos[:, 1, 0], pos[:, 1, 2] = 30 * np.cos(2 * t), 30 * np.sin(2 * t)  # cm: 60 cm/s along the circle
    beats = np.arange(0.0, 25, 0.5)

    def run(mode):
        nudge = BeatNudge(fps=fps, rate_bound=0.15, max_lag_s=0.24, mode=mode)
        out = np.stack([nudge.process(pos[i : i + 1], beats[beats > t[i]][0], 0.5)[0] for i in range(T)])
        return out, nudge

    out, nudge = run("pulse")
    v = np.linalg.norm(np.diff(out, axis=0), axis=-1)[:, 1] * fps  # cm/s between frames i and i + 1
    minima = np.array([i for i in range(1, len(v) - 1) if v[i] < v[i - 1] and v[i] <= v[i + 1]])
    minima = (minima[minima > 2 * fps] + 0.5) / fps  # s: the middle of the slowest step
    assert len(minima) == np.sum((beats > 2 + 0.5 / fps) & (beats < (T - 2) / fps))
    assert np.abs(minima[:, None] - beats[None]).min(axis=1).max() <= 1 / fps + 1e-9
    assert 0.8 * 60 < v[50:].min() < 0.9 * 60 and 1.1 * 60 < v[50:].max() < 1.2 * 60
    assert all(0.85 - 1e-9 <= r <= 1.15 + 1e-9 for r in nudge.rates)
    with pytest.raises(ParameterError, match="mode"):
        BeatNudge(fps=fps, mode="push")


def test_beat_nudge_pulse_moving_spares_a_dancer_near_stillness():
    """``"pulse_moving"``: a joint circling at 60 cm/s (body-relative, 6× the still second's 10 cm/s) gets the
    whole pulse, the same poses as ``"pulse"`` once a second of speeds is known; at 8 cm/s (under the still
    second) none: the rate is the clock's drift alone, as with no beat predicted."""
    from dancekit.live.stages import BeatNudge

    fps, T = 25.0, 300
    t = np.arange(T) / fps
    beats = np.arange(0.0, 15, 0.5)

    def run(mode, speed, beat=True):
        pos = np.zeros((T, 2, 3))
        w = speed / 30.0  # rad/s on a 30-cm circle
        pos[:, 1, 0], pos[:, 1, 2] = 30 * np.cos(w * t), 30 * np.sin(w * t)
        nudge = BeatNudge(fps=fps, rate_bound=0.15, mode=mode, root=0, unit_scale=0.01)
        out = [nudge.process(pos[i : i + 1], beats[beats > t[i]][0] if beat else None, 0.5)[0] for i in range(T)]
        return np.stack(out), nudge

    fast, _ = run("pulse_moving", 60.0)
    whole, _ = run("pulse", 60.0)
    np.testing.assert_allclose(fast[40:], whole[40:], atol=1e-6)
    _, slow = run("pulse_moving", 8.0)
    _, drift = run("pulse_moving", 8.0, beat=False)  # no beat: the clock's drift alone
    np.testing.assert_allclose(slow.rates[30:], drift.rates[30:], atol=1e-9)
    _, pulsed = run("pulse", 8.0)
    assert np.ptp(pulsed.rates[30:]) > 0.25


def test_a_session_stopped_before_any_audio_ends_with_no_frames():
    """A client that starts and stops without sending audio (``dancekit serve``'s socket, an empty stdin): the
    session's end makes no frame and does not fail."""
    s = LiveSession("revolution")
    assert s.finish() == []
    assert s.stats.latency == []


def test_the_stream_resampler_gives_the_whole_resampling_whatever_the_pieces():
    """Pieces of 1, 441 and 4000 samples at 44.1 kHz resampled to 12.8 kHz, the flush included, are one stream's
    resampling of the whole (soxr keeps its state), of the length the rates give; without the flush the last
    milliseconds are missing."""
    from dancekit.live.session import StreamResampler

    x = np.sin(np.arange(44100) * 2 * np.pi * 440 / 44100).astype(np.float32)
    whole = StreamResampler(44100, 12800)
    ref = np.concatenate([whole(x), whole.flush()])
    assert abs(len(ref) - 12800) <= 1
    for piece in (1, 441, 4000):
        r = StreamResampler(44100, 12800)
        parts = [r(x[a : a + piece]) for a in range(0, len(x), piece)]
        body = np.concatenate(parts)
        assert len(body) < len(ref)  # soxr holds the last few samples until the flush
        assert np.array_equal(np.concatenate([body, r.flush()]), ref)
    same = StreamResampler(12800, 12800)
    assert np.array_equal(same(x[:100]), x[:100]) and len(same.flush()) == 0


@pytest.mark.parametrize("path", ["numpy", "torch"])
def test_the_revolution_stepper_projects_each_frame_once(revolution, rng, monkeypatch, path):
    """The first encoder layer's queries, keys and values of a frame do not change as more music comes: the stepper
    computes them once per frame as the rows arrive and every block's latents use them (not a projection of the
    frames it looks at again); in NumPy (the encoder's frames of a float32 model on the CPU) and in torch."""
    from dancekit.live.steppers import RevolutionStepper
    from dancekit.models.revolution import NumpyLocalEncoder, SelfAttention

    projected, given = [], []
    if path == "numpy":
        real_proj, real_range = NumpyLocalEncoder.projections, NumpyLocalEncoder.forward_range

        def projections(self, x):
            projected.append(x.shape[0])
            return real_proj(self, x)

        def forward_range(self, x, start, stop, *, qkv0=None):
            given.append(qkv0 is not None)
            return real_range(self, x, start, stop, qkv0=qkv0)

        monkeypatch.setattr(NumpyLocalEncoder, "projections", projections)
        monkeypatch.setattr(NumpyLocalEncoder, "forward_range", forward_range)
    else:
        monkeypatch.setattr(NumpyLocalEncoder, "usable", staticmethod(lambda encoder: False))
        layer = revolution.model.encoder.layers[0]
        real_proj, real_range = type(layer).projections, SelfAttention.forward_range

        def projections(self, x):
            projected.append(x.shape[1])
            return real_proj(self, x)

        def forward_range(self, x, start, stop, *, qkv=None):
            if self is layer.attn:
                given.append(qkv is not None)
            return real_range(self, x, start, stop, qkv=qkv)

        monkeypatch.setattr(type(layer), "projections", projections)
        monkeypatch.setattr(SelfAttention, "forward_range", forward_range)
    T = 120
    raw = rng.standard_normal((T, 438)).astype(np.float32) * revolution.stats.music_std + revolution.stats.music_mean
    st = RevolutionStepper(revolution, lookahead=4, context=50, seed=0)
    assert (st.np_encoder is not None) == (path == "numpy")
    for a in range(0, T, 3):
        st.push(raw[a : a + 3])
    assert sum(projected) == T  # each frame once
    assert given and all(given)
