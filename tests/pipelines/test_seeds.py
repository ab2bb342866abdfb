"""Many dances in one pass (issue 18): seeds as one batch equal the seeds danced one at a time."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.audio import save_wav
from dancekit.audio.synth import ode_to_joy
from dancekit.cli.main import main
from dancekit.errors import ParameterError
from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel
from dancekit.models.revolution import RevolutionConfig, RevolutionModel, SeedVariety, decode_seeds
from dancekit.pipelines import load_pipeline, parse_seeds

SR = 22050
# A seed's dance must not depend on the batch it is danced in, bit for bit: batched matrix products round the
# last float bits differently for every batch size (and the autoregressive decoders carry such a difference into
# another dance within ~20 s: 28-37 cm apart after 40 s on the test song W_32 before the fix; docs/research/seed-variety-and-fid.md,
# "A seed's dance whatever the batch"), so every family decodes each seed on its own. Exact equality, no
# tolerance: on the code that batched the seeds these tests fail at the first frame (~1e-5 cm apart).


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    path = tmp_path_factory.mktemp("song") / "ode.wav"
    save_wav(path, ode_to_joy(sr=SR, bpm=120)[: int(5.0 * SR)], sr=SR)
    return path


def test_parse_seeds():
    assert parse_seeds("0-7") == list(range(8))
    assert parse_seeds("0,3,9") == [0, 3, 9]
    assert parse_seeds("0-2, 10,20-21") == [0, 1, 2, 10, 20, 21]
    assert parse_seeds("5") == [5]
    for bad in ("3-1", "a", "0,0", "0-2,1", "-1", "", "0-99"):
        with pytest.raises(ParameterError):
            parse_seeds(bad)


def _tiny_revolution(seed: int = 0, hidden: int = 16) -> RevolutionModel:
    torch.manual_seed(seed)
    return RevolutionModel(RevolutionConfig(music_dim=8, pose_dim=6, d_model=16, n_heads=2, d_ff=32,
                                            decoder_hidden=hidden, window=10, encoder_chunk=32)).eval()


@pytest.mark.parametrize("variety", [None, SeedVariety(phrase=20, state_noise=0.3, latent_noise=0.5)])
def test_model_rows_are_the_seeds_alone(variety):
    model = _tiny_revolution()
    music = torch.randn(1, 70, 8)  # 70 frames: three encoder chunks

    def batch(seeds):
        return model.generate(music, generator=[torch.Generator().manual_seed(s) for s in seeds], variety=variety)

    three, five = batch([4, 0, 11]), batch([0, 1, 2, 3, 4])
    assert three.shape == (3, 70, 6) and five.shape == (5, 70, 6)
    for k, s in enumerate([4, 0, 11]):
        alone = model.generate(music, generator=torch.Generator().manual_seed(s), variety=variety)[0]
        assert torch.equal(three[k], alone), s
        assert torch.equal(batch([s])[0], alone), s
    assert torch.equal(three[0], five[4]) and torch.equal(three[1], five[0])  # any batch size, any position
    assert not torch.allclose(three[0], three[1], atol=1e-2)  # other seeds, other dances


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_decode_seeds_of_several_models_in_lanes_are_each_the_seed_alone(workers):
    """Rows of three models (two of one decoder architecture, which share a frame loop, one of another) decoded
    together, in any number of lanes: each row bit for bit its model's dance of that seed alone."""
    a, b, c = _tiny_revolution(0), _tiny_revolution(1), _tiny_revolution(2, hidden=24)
    variety = SeedVariety(phrase=20, state_noise=0.3, latent_noise=0.5)
    music = torch.randn(1, 70, 8)
    models, seeds = [a, c, b, a, c, a], [4, 0, 11, 0, 7, 2]
    with torch.no_grad():
        rows = decode_seeds(models, [m._latents(music, None) for m in models],
                            [torch.Generator().manual_seed(s) for s in seeds], variety, workers=workers)
    assert rows.shape == (6, 70, 6)
    for k, (m, s) in enumerate(zip(models, seeds)):
        alone = m.generate(music, generator=torch.Generator().manual_seed(s), variety=variety)[0]
        assert torch.equal(rows[k], alone), (k, s)
    assert not torch.allclose(rows[0], rows[3], atol=1e-2)  # one model, two seeds: two dances
    with pytest.raises(ParameterError, match="workers"):
        decode_seeds(models[:1], [a._latents(music, None)], [torch.Generator()], variety, workers=0)


@pytest.mark.parametrize("mixtures", [1, 3])
def test_music2dance_rows_are_the_seeds_alone(mixtures):
    cfg = Music2DanceConfig(music_dim=6, pose_dim=14, n_genres=3, n_layers=4, channels=32, skip_channels=32,
                            genre_dim=4, fmap_channels=(4, 4, 4), fmap_lstm_hidden=4, n_mixtures=mixtures,
                            min_log_var=-2.0)
    torch.manual_seed(0)
    model = Music2DanceModel(cfg).eval()
    music = torch.randn(1, 60, 6)

    def batch(seeds, genre):
        return model.generate(music.expand(len(seeds), -1, -1), torch.tensor([genre] * len(seeds)),
                              temperature=0.8, noise_correlation=0.5,
                              generator=[torch.Generator().manual_seed(s) for s in seeds])

    three, five = batch([4, 0, 11], 1), batch([0, 1, 2, 3, 4], 1)
    for k, s in enumerate([4, 0, 11]):
        alone = batch([s], 1)[0]
        assert torch.equal(three[k], alone), s
    assert torch.equal(three[0], five[4]) and torch.equal(three[1], five[0])
    mixed = model.generate(music.expand(2, -1, -1), torch.tensor([2, 1]), temperature=0.8, noise_correlation=0.5,
                           generator=[torch.Generator().manual_seed(s) for s in (0, 0)])  # a genre per row
    assert torch.equal(mixed[1], three[1]) and torch.equal(mixed[0], batch([0], 2)[0])
    assert not torch.allclose(three[0], three[1], atol=1e-2)


@pytest.mark.parametrize("name", ["revolution", "dual", "music2dance"])
@pytest.mark.slow
def test_dances_equal_each_seed_alone(song, name):
    """Every dance family: pipe.dances(seeds=...)[k] is bit for bit pipe(seed=seeds[k]) (stages on), so a seed is
    the same dance in any batch, at any position."""
    pipe = load_pipeline(name)
    seeds = [2, 0, 3]
    batch = pipe.dances(str(song), seeds=seeds)
    assert [r.seed for r in batch] == seeds
    for r, s in zip(batch, seeds):
        alone = pipe(str(song), seed=s)
        assert r.notes == alone.notes and r.genre == alone.genre
        a, b = r.motion.to_positions(), alone.motion.to_positions()
        assert a.shape == b.shape
        assert np.array_equal(a, b), (name, s, np.abs(a - b).max())
    first, second = batch[0].motion.to_positions(), batch[1].motion.to_positions()
    n = min(len(first), len(second))
    assert np.abs(first[:n] - second[:n]).max() > 1.0  # the seeds dance differently (cm)


@pytest.mark.slow
def test_revolution_seeds_of_several_genre_models_in_lanes_equal_each_seed_alone(song):
    """The default model's seeds danced by three models at once (a genre model of another size, one of the
    parent's size and the parent itself, the last two in one frame loop), decoded in two lanes: each dance bit for
    bit the seed alone."""
    pipe = load_pipeline("revolution")
    seeds, genres = [2, 0, 3, 4], ["rumba", "auto", "waltz", "none"]
    batch = pipe.dances(str(song), seeds=seeds, genre=genres, workers=2)
    assert len({r.danced_by for r in batch}) == 3
    for r, s, g in zip(batch, seeds, genres):
        alone = pipe(str(song), seed=s, genre=g)
        assert r.genre == alone.genre and r.notes == alone.notes
        assert np.array_equal(r.motion.to_positions(), alone.motion.to_positions()), (s, g)


def test_cli_seeds_write_one_output_set_per_seed(tmp_path, capsys, song):
    out = tmp_path / "many"
    assert main(["dance", str(song), "-o", str(out), "--seeds", "0-1,4", "--format", "npz", "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ode_seed0.npz", "ode_seed1.npz", "ode_seed4.npz"]
    assert "(seed 4)" in capsys.readouterr().out
    one = tmp_path / "one"
    assert main(["dance", str(song), "-o", str(one), "--seed", "4", "--format", "npz", "--quiet"]) == 0
    with np.load(out / "ode_seed4.npz") as a, np.load(one / "ode.npz") as b:
        assert a["positions"].shape == b["positions"].shape
        assert np.array_equal(a["positions"], b["positions"])
    with np.load(out / "ode_seed0.npz") as a, np.load(one / "ode.npz") as b:
        assert np.abs(a["positions"][:50] - b["positions"][:50]).max() > 1.0


def test_cli_refuses_bad_seeds(tmp_path, capsys, song):
    """A bad seed list is one error line (not argparse's usage), exit status 2, nothing written."""
    for flags, says in ((["--seeds", "3-1"], "bad seed range"), (["--seeds", "0-100"], "at most 64"),
                        (["--seeds", "1,2", "--seed", "3"], "not both")):
        assert main(["dance", str(song), "-o", str(tmp_path / "x"), *flags]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("dancekit dance: error:") and says in err[0], err
    assert not (tmp_path / "x").exists()
