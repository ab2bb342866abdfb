"""The music attribute classifier of Music2Dance, its training family and its use by `--genre auto`."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from _prepared import write_fake_prepared

from dancekit import registry
from dancekit.checkpoints import declare_components, load_pretrained, save_pretrained
from dancekit.cli.main import main
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.music_attributes import (
    MusicAttributeClassifier,
    MusicAttributeConfig,
    log_lag_autocorrelation,
    rhythm_lags,
)
from dancekit.training import TrainConfig, train


def tiny(**kw) -> MusicAttributeClassifier:
    torch.manual_seed(0)
    return MusicAttributeClassifier(MusicAttributeConfig(**{"music_dim": 5, "n_classes": 3, "window": 40, **kw}))


def test_shapes_and_shortest_input():
    model = tiny()
    assert model(torch.randn(2, 40, 5)).shape == (2, 3)
    assert model.min_frames() == 4  # kernel 2, 2, then 2 with stride 2
    assert model(torch.randn(1, 4, 5)).shape == (1, 3)
    with pytest.raises(ParameterError, match="at least 4 frames"):
        model(torch.randn(1, 3, 5))
    with pytest.raises(ParameterError, match=r"\(B, n, 5\)"):
        model(torch.randn(1, 40, 6))
    fc = tiny(frontend="fc")  # the paper's FC+Bi-LSTM baseline: per-frame layers, any length from 1 frame
    assert fc.min_frames() == 1 and fc(torch.randn(2, 1, 5)).shape == (2, 3)
    with pytest.raises(ParameterError, match="frontend"):
        tiny(frontend="rnn")


def test_config_errors_and_json_round_trip():
    with pytest.raises(ParameterError, match="n_classes"):
        MusicAttributeConfig(n_classes=1)
    with pytest.raises(ParameterError, match="channels"):
        MusicAttributeConfig(channels=())
    with pytest.raises(ParameterError, match="dropout"):
        MusicAttributeConfig(dropout=1.0)
    c = MusicAttributeConfig(channels=[8, 8])
    assert c.channels == (8, 8) and MusicAttributeConfig(**json.loads(json.dumps(c.__dict__))) == c


def test_predict_song_is_the_mean_log_probability_of_half_overlapping_windows():
    model = tiny().eval()
    x = torch.randn(100, 5)
    # windows of 40 frames, hop 20: starts 0, 20, 40, 60 (the last one flush with the end)
    with torch.no_grad():
        logp = torch.stack([F.log_softmax(model(x[s : s + 40][None])[0], -1) for s in (0, 20, 40, 60)]).mean(0)
    want = torch.softmax(logp, 0).numpy()
    got = model.predict_song(x.numpy())
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-7)
    assert got.sum() == pytest.approx(1.0)
    # a song shorter than a window is classified in one piece; a song of 3 frames is refused
    with torch.no_grad():
        short = torch.softmax(model(x[:25][None])[0], -1).numpy()
    np.testing.assert_allclose(model.predict_song(x[:25].numpy()), short, rtol=1e-5, atol=1e-7)
    with pytest.raises(ParameterError, match="at least"):
        model.predict_song(x[:3].numpy())


# ---- the rhythm periodicity: tempo and metre ------------------------------------------------------------


def _impulses(n: int, period: int) -> torch.Tensor:
    x = torch.zeros(n, dtype=torch.float64)
    x[::period] = 1.0
    return x


def test_log_lag_autocorrelation_of_an_impulse_train_has_known_values():
    """Impulses every P frames, centred: r(k)/r(0) is 1 at multiples of P (n - k a multiple of P) and about
    -1/(P - 1) at the other lags (per whole period: two impulse × background pairs and P - 2 background pairs);
    each value is the brute-force sum of the definition, and a fractional lag reads the straight line between
    its two whole lags."""
    n, period = 400, 10
    x = _impulses(n, period)
    xc = (x - x.mean()).numpy()

    def brute(k: int) -> float:
        return float(np.mean(xc[: n - k] * xc[k:]) / np.mean(xc * xc))

    got = log_lag_autocorrelation(x[None], torch.tensor([10.0, 20.0, 7.0, 9.5, 3.25], dtype=torch.float64))[0]
    want = [1.0, 1.0, brute(7), (brute(9) + brute(10)) / 2, 0.75 * brute(3) + 0.25 * brute(4)]
    torch.testing.assert_close(got, torch.tensor(want, dtype=torch.float64))
    assert got[0] == pytest.approx(1.0) and got[2] == pytest.approx(-1 / 9, abs=2e-3)


def test_log_lag_autocorrelation_ignores_scale_and_offset_and_reads_zero_where_it_cannot(rng):
    x = torch.from_numpy(rng.normal(size=(3, 120)))
    lags = torch.tensor([1.0, 4.5, 30.0, 118.5, 119.0, 500.0], dtype=torch.float64)
    a = log_lag_autocorrelation(x, lags)
    torch.testing.assert_close(log_lag_autocorrelation(3.0 * x - 7.0, lags), a)
    assert (a[:, -2:] == 0).all() and (a[:, :-2].abs() <= 1.5).all()  # lags >= n - 1 read 0
    flat = log_lag_autocorrelation(torch.full((2, 50), 4.0, dtype=torch.float64), lags)
    assert (flat == 0).all()
    with pytest.raises(ParameterError, match=r"x \(B, n\)"):
        log_lag_autocorrelation(x[0], lags)


def test_rhythm_lags_are_log_spaced_between_the_configured_ends():
    lags = rhythm_lags(MusicAttributeConfig(rhythm_bins=5, rhythm_min_lag=4.0, rhythm_max_lag=64.0))
    torch.testing.assert_close(lags, torch.tensor([4.0, 8.0, 16.0, 32.0, 64.0]))


def test_rhythm_only_classifier_reads_the_onset_column_alone():
    model = tiny(frontend="none", rhythm_bins=8, rhythm_max_lag=30.0).eval()
    assert model.lstm is None and len(model.convs) == 0 and model.min_frames() == 2
    assert sum(p.numel() for p in model.parameters()) == 8 * 3 + 3  # one linear layer on the 8 lags
    x = torch.randn(2, 40, 5)
    y = x.clone()
    y[:, :, 1:] = torch.randn(2, 40, 4)  # every column but the onset strength (column 0) changes
    with torch.no_grad():
        torch.testing.assert_close(model(y), model(x))
        assert not torch.allclose(model(x), model(torch.randn(2, 40, 5)))
    both = tiny(rhythm_bins=8)  # the paper's trunk and the rhythm periodicity side by side
    assert both.head.in_features == 2 * 32 + 8 and both(x).shape == (2, 3)
    with pytest.raises(ParameterError, match="rhythm_bins > 0"):
        MusicAttributeConfig(frontend="none")
    with pytest.raises(ParameterError, match="rhythm_min_lag"):
        MusicAttributeConfig(rhythm_bins=4, rhythm_min_lag=10.0, rhythm_max_lag=10.0)
    with pytest.raises(ParameterError, match="rhythm_column"):
        MusicAttributeConfig(music_dim=5, rhythm_column=5)


class _Metre(torch.utils.data.Dataset):
    """Onset tracks of bars of 3 (class 0) or 4 (class 1) beats: a strong onset on each downbeat, weaker ones on the
    other beats (each a bump of 2 frames' standard deviation, as an onset-strength envelope), noise; a beat period
    of 14-16 frames and a phase drawn per track (the same tempi for both classes, so only the metre tells them
    apart); 5 columns, the onset strength first, the rest noise."""

    def __init__(self, n: int, seed: int, frames: int = 200):
        g = torch.Generator().manual_seed(seed)
        self.y = torch.arange(n) % 2
        self.x = torch.randn(n, frames, 5, generator=g) * 0.3
        for i in range(n):
            period = int(torch.randint(14, 17, (1,), generator=g))
            bar = 3 + int(self.y[i])
            beats = torch.arange(int(torch.randint(0, period, (1,), generator=g)), frames, period)
            down = (torch.arange(len(beats)) % bar) == int(torch.randint(0, bar, (1,), generator=g))
            t = torch.arange(frames, dtype=torch.float32)[:, None]
            bumps = torch.exp(-0.5 * ((t - beats[None].float()) / 2.0) ** 2)  # (frames, beats)
            self.x[i, :, 0] += bumps @ torch.where(down, 3.0, 1.0)

    def __len__(self) -> int:
        return len(self.y)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"music": self.x[i], "genre": self.y[i]}


def test_the_rhythm_periodicity_tells_three_beat_from_four_beat_bars(tmp_path):
    """A known answer the chords cannot give: trained on synthetic onset tracks, the rhythm-only classifier
    separates bars of 3 from bars of 4 beats on held-out tracks at tempi drawn anew."""
    torch.manual_seed(0)
    model = MusicAttributeClassifier(MusicAttributeConfig(music_dim=5, n_classes=2, window=200, frontend="none",
                                                          rhythm_bins=32, rhythm_min_lag=6.0, rhythm_max_lag=100.0))
    config = TrainConfig(steps=150, batch_size=16, lr=1e-2, warmup_steps=5, val_every=150, ckpt_every=150,
                         log_every=50, threads=1)
    train(model, _Metre(64, seed=0), None, config, step_fn=registry.get("music_attributes").load("objective"),
          out_dir=tmp_path / "run", progress=False)
    held_out = _Metre(60, seed=1)
    with torch.no_grad():
        acc = (model.eval()(held_out.x).argmax(-1) == held_out.y).float().mean().item()
    assert acc >= 0.9


def test_music2dance_fmap_starts_from_a_trunk_with_rhythm_but_not_from_a_rhythm_only_classifier(tmp_path):
    from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel
    from dancekit.training.m2d import load_fmap

    stats = {"music_mean": np.zeros(15, np.float32), "music_std": np.ones(15, np.float32)}
    for name, kw in (("both", {"rhythm_bins": 8}), ("none", {"rhythm_bins": 8, "frontend": "none"})):
        clf = MusicAttributeClassifier(MusicAttributeConfig(n_classes=4, window=100, **kw))
        save_pretrained(tmp_path / name, clf, clf.config, stats=stats,
                        extra={"fps": 25.0, "preset": "music2dance", "genres": ["waltz", "rumba", "chacha", "tango"]})
    model = Music2DanceModel(Music2DanceConfig(music_dim=15, pose_dim=20, n_layers=2, channels=8, skip_channels=8))
    load_fmap(model, str(tmp_path / "both"))
    assert int(model.fmap_loaded) == 1
    with pytest.raises(CheckpointError, match="does not fit"):
        load_fmap(Music2DanceModel(model.config), str(tmp_path / "none"))


class _Toy(torch.utils.data.Dataset):
    """Class c raises feature column c by 1.5 (noise std 1): separable from a window's mean."""

    def __init__(self, n: int, seed: int):
        g = torch.Generator().manual_seed(seed)
        self.y = torch.arange(n) % 3
        self.x = torch.randn(n, 40, 5, generator=g)
        self.x[torch.arange(n), :, self.y] += 1.5

    def __len__(self) -> int:
        return len(self.y)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"music": self.x[i], "genre": self.y[i]}


def test_the_generic_loop_trains_it_to_separate_a_toy_problem(tmp_path):
    model = tiny()
    config = TrainConfig(steps=150, batch_size=16, lr=3e-3, warmup_steps=5, val_every=150, ckpt_every=150,
                         log_every=50, threads=1)
    train(model, _Toy(96, seed=0), None, config, step_fn=registry.get("music_attributes").load("objective"), out_dir=tmp_path / "run",
          progress=False)
    held_out = _Toy(60, seed=1)
    with torch.no_grad():
        acc = (model.eval()(held_out.x).argmax(-1) == held_out.y).float().mean().item()
    assert acc >= 0.95
    again, meta, _ = load_pretrained(tmp_path / "run" / "model")
    with torch.no_grad():
        torch.testing.assert_close(again(held_out.x), model(held_out.x))  # save → load: identical outputs
    assert meta["model"] == "music_attributes"


@pytest.fixture
def prepared_music2dance(tmp_path, rng):
    """A tiny prepared dataset with `music2dance` features (15 columns) for two genres."""
    return write_fake_prepared(tmp_path / "prepared", rng, preset="music2dance", dim=15)


def test_train_cli_music_attributes(prepared_music2dance, tmp_path, capsys):
    out = tmp_path / "run"
    base = ["train", "music_attributes", "--data", str(prepared_music2dance), "--out", str(out), "--quiet",
            "--set", "seq_len=40", "--set", "batch_size=2", "--set", "threads=1"]
    assert main(base + ["--set", "steps=3", "--set", "channels=8,8,8"]) == 0
    assert "trained music_attributes to step 3" in capsys.readouterr().out
    model, meta, stats = load_pretrained(out / "model")
    c = model.config
    assert (c.music_dim, c.n_classes, c.window, c.channels) == (15, 4, 40, (8, 8, 8))  # window = seq_len
    assert meta["preset"] == "music2dance" and meta["genres"] == ["waltz", "rumba", "chacha", "tango"]
    assert meta["train"]["balance_genres"] is True and stats["music_mean"].shape == (15,)  # family defaults
    assert main(base + ["--set", "window=50"]) == 2
    assert "window=50" in capsys.readouterr().err


# ---- --genre auto: the genre read from the music -------------------------------------------------------


def test_the_embedded_model_ships_its_music_attribute_classifier():
    """`--genre auto` of the default model needs revolution/music_attributes/: its absence fails, never skips."""
    from dancekit.checkpoints import DEFAULT_MODEL, components, embedded_models
    from dancekit.pipelines.music_attributes import MusicAttributePipeline

    folder = embedded_models()[DEFAULT_MODEL]
    parts = components(folder)  # a declared component whose folder is gone fails here
    reader = parts.get("genre_reader")
    assert reader is not None, f"the embedded model declares no music attribute classifier ({folder / 'config.json'})"
    for name in ("config.json", "model.safetensors", "stats.npz"):
        assert (reader / name).is_file(), reader / name
    pipe = MusicAttributePipeline.from_pretrained(reader)
    assert set(parts["genres"]) == {"waltz", "rumba", "chacha", "tango"} and set(parts["genres"]) <= set(pipe.genres)


def _save_classifier(folder, *, favour: str, genres: list[str], fps: float = 25.0):
    """A classifier whose output is (almost) always ``favour``: zero weights in the head, a large bias."""
    model = MusicAttributeClassifier(MusicAttributeConfig(n_classes=len(genres), window=100))
    with torch.no_grad():
        model.head.weight.zero_()
        model.head.bias.zero_()
        model.head.bias[genres.index(favour)] = 5.0
    stats = {"music_mean": np.zeros(15, np.float32), "music_std": np.ones(15, np.float32)}
    save_pretrained(folder, model, model.config, stats=stats,
                    extra={"fps": fps, "preset": "music2dance", "hop_length": 512, "genres": genres})


@pytest.fixture
def reads_genre(tmp_path, song_wav):
    """A tiny Dance Revolution folder with genre models for rumba and waltz and a classifier that says rumba."""
    from dancekit.models.revolution import RevolutionConfig, RevolutionModel
    from dancekit.motion import get_skeleton

    genres = ["waltz", "rumba", "chacha", "tango"]
    skel = get_skeleton("tang2018")
    stats = {"music_mean": np.zeros(438, np.float32), "music_std": np.ones(438, np.float32),
             "dance_mean": np.zeros(72, np.float32), "dance_std": np.ones(72, np.float32)}
    meta = {"fps": 25.0, "preset": "revolution", "representation": "positions3d", "hop_length": 512,
            "skeleton": skel.to_dict(), "genres": genres}
    root = tmp_path / "parent"
    for k, sub in enumerate(["", "genres/rumba", "genres/waltz"]):
        torch.manual_seed(k)
        model = RevolutionModel(RevolutionConfig(d_model=16, n_heads=2, d_ff=32, decoder_hidden=16))
        save_pretrained(root / sub if sub else root, model, model.config, stats=stats, extra=meta)
    _save_classifier(root / "music_attributes", favour="rumba", genres=genres)
    declare_components(root, {"genre_reader": "music_attributes",
                              "genres": {"rumba": "genres/rumba", "waltz": "genres/waltz"}})
    return root


@pytest.fixture
def song_wav(tmp_path):
    from dancekit.audio import save_wav
    from dancekit.audio.synth import click_track

    path = tmp_path / "click.wav"
    save_wav(path, click_track(bpm=120, duration=3.0, sr=22050), sr=22050)
    return path


def test_auto_dances_the_genre_read_from_the_music(reads_genre, song_wav):
    from dancekit.pipelines import MusicAttributePipeline, RevolutionPipeline

    pipe = RevolutionPipeline.from_pretrained(reads_genre)
    probs = pipe.read_genre(song_wav)
    assert list(probs) == ["waltz", "rumba"] and sum(probs.values()) == pytest.approx(1.0)
    assert max(probs, key=probs.get) == "rumba"
    raw = MusicAttributePipeline.from_pretrained(reads_genre / "music_attributes")(song_wav)
    assert list(raw) == ["waltz", "rumba", "chacha", "tango"] and raw["rumba"] > 0.9
    auto = pipe(song_wav, seed=0).motion.to_positions()
    np.testing.assert_array_equal(auto, pipe(song_wav, seed=0, genre="rumba").motion.to_positions())
    alone = pipe(song_wav, seed=0, genre="none").motion.to_positions()
    plain = RevolutionPipeline.from_pretrained(reads_genre)
    plain.genre_reader = None  # the same folder without its classifier: "auto" is the model alone
    np.testing.assert_array_equal(alone, plain(song_wav, seed=0).motion.to_positions())
    assert np.abs(auto - alone).max() > 1e-3


def test_dance_cli_reports_the_genre_it_read(reads_genre, song_wav, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["dance", str(song_wav), "-o", str(out), "--checkpoint", str(reads_genre), "--format", "npz",
                 "--quiet"]) == 0
    assert "as rumba (read from the music, p = " in capsys.readouterr().out
    assert main(["dance", str(song_wav), "-o", str(out), "--checkpoint", str(reads_genre), "--format", "npz",
                 "--quiet", "--genre", "none"]) == 0
    assert "read from the music" not in capsys.readouterr().out
    assert main(["models"]) == 0  # the embedded default reads the genre from the music
    assert "auto (read from the music), none" in capsys.readouterr().out


def test_a_classifier_that_does_not_fit_is_refused(reads_genre, tmp_path):
    from dancekit.pipelines import MusicAttributePipeline, RevolutionPipeline

    bad = tmp_path / "bad"
    shutil.copytree(reads_genre, bad)
    shutil.rmtree(bad / "music_attributes")
    _save_classifier(bad / "music_attributes", favour="rumba", genres=["waltz", "rumba", "chacha", "tango"], fps=30.0)
    with pytest.raises(CheckpointError, match="30 fps"):
        RevolutionPipeline.from_pretrained(bad)
    with pytest.raises(CheckpointError, match="not a music attribute classifier"):
        MusicAttributePipeline.from_pretrained(reads_genre)
