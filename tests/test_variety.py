"""Seed variety of the Dance Revolution decoder (issue 15): the seed keeps changing the dance after its
opening when :class:`SeedVariety` perturbs the decoding per phrase; the same seed still gives the same dance."""

from __future__ import annotations

import pytest
import torch

from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel, SeedVariety, _phrases
from dancekit.pipelines.revolution import variety_from_meta

D, P = 8, 6
N = 120  # frames
PHRASE = 20


def forgetful_model() -> RevolutionModel:
    """A tiny decoder that forgets its state within a few frames (like the trained default, whose dances
    for one song converge): forget gates shut, small recurrent and feedback weights."""
    torch.manual_seed(0)
    model = RevolutionModel(RevolutionConfig(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32, window=6,
                                             decoder_hidden=24, decoder_layers=2, dropout=0.0)).eval()
    H = model.config.decoder_hidden
    with torch.no_grad():
        for layer in range(2):
            getattr(model.decoder, f"weight_hh_l{layer}").mul_(0.3)
            getattr(model.decoder, f"bias_ih_l{layer}")[H : 2 * H] = -8.0  # forget gate ≈ 0
        model.decoder.weight_ih_l0[:, :P].mul_(0.3)  # the fed-back pose
    return model


def music() -> torch.Tensor:
    return torch.randn(1, N, D, generator=torch.Generator().manual_seed(7))


def gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def seed_gap(model, variety, *, frames=slice(-5, None)) -> float:
    """Mean absolute difference of seeds 0 and 3's dances over ``frames``."""
    a = model.generate(music(), generator=gen(0), variety=variety)
    b = model.generate(music(), generator=gen(3), variety=variety)
    return float((a - b)[:, frames].abs().mean())


def test_without_variety_the_seeds_converge_on_a_forgetful_decoder():
    model = forgetful_model()
    assert seed_gap(model, None, frames=slice(0, 2)) > 1e-3  # different openings
    assert seed_gap(model, None) < 1e-5  # the same dance at the end: what issue 15 reports


@pytest.mark.parametrize("variety", [SeedVariety(phrase=PHRASE, state_noise=1.0),
                                     SeedVariety(phrase=PHRASE, latent_noise=0.5)], ids=["state", "latent"])
def test_with_variety_the_seeds_differ_after_every_phrase_boundary(variety):
    model = forgetful_model()
    for boundary in range(PHRASE, N, PHRASE):  # the first frames of every phrase, the last one included
        assert seed_gap(model, variety, frames=slice(boundary, boundary + 3)) > 1e-3, boundary


def test_a_dance_latent_keeps_the_seeds_apart_to_the_end():
    """The embedded default's setting: one latent offset per dance (no phrases needed)."""
    model = forgetful_model()
    variety = SeedVariety(dance_latent=1.0)
    assert variety.active and not SeedVariety(latent_noise=1.0).active  # a phrase path needs phrases
    assert seed_gap(model, variety) > 1e-2  # the last frames
    assert seed_gap(model, variety, frames=slice(N // 2, None)) > 1e-2


@pytest.mark.parametrize("variety", [SeedVariety(phrase=PHRASE, state_noise=0.7, latent_noise=0.3),
                                     SeedVariety(dance_latent=0.8),
                                     SeedVariety(phrase=PHRASE, latent_noise=0.5)])
def test_the_same_seed_gives_the_same_dance_whatever_the_chunking(variety):
    model = forgetful_model()
    a = model.generate(music(), generator=gen(4), variety=variety)
    torch.testing.assert_close(model.generate(music(), generator=gen(4), variety=variety), a, rtol=0, atol=0)
    torch.testing.assert_close(model.generate(music(), generator=gen(4), variety=variety, chunk=33), a,
                               rtol=1e-5, atol=1e-5)


def test_variety_off_is_the_papers_decoding():
    """No variety draws at all: SeedVariety() and None give the dance of the original decoder."""
    model = forgetful_model()
    a = model.generate(music(), generator=gen(2))
    torch.testing.assert_close(model.generate(music(), generator=gen(2), variety=SeedVariety()), a, rtol=0, atol=0)
    torch.testing.assert_close(model.generate(music(), generator=gen(2), variety=SeedVariety(phrase=PHRASE)), a,
                               rtol=0, atol=0)


def test_a_batch_with_one_generator_per_row_equals_one_call_per_seed():
    model = forgetful_model()
    variety = SeedVariety(phrase=PHRASE, state_noise=0.5, latent_noise=0.3)
    batch = model.generate(music().expand(3, -1, -1), generator=[gen(s) for s in (5, 6, 7)], variety=variety)
    for k, s in enumerate((5, 6, 7)):
        torch.testing.assert_close(batch[k : k + 1], model.generate(music(), generator=gen(s), variety=variety),
                                   rtol=1e-4, atol=1e-5)
    with pytest.raises(ParameterError, match="2 generators for a batch of 3"):
        model.generate(music().expand(3, -1, -1), generator=[gen(0), gen(1)])


def test_state_noise_one_redraws_the_state_like_the_start():
    """a = 1 replaces the state by a fresh N(0, 1) draw: h after the mix has unit variance."""
    model = RevolutionModel(RevolutionConfig(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32,
                                             decoder_hidden=256, decoder_layers=2))
    variety = SeedVariety(phrase=10, state_noise=1.0)
    noise = model._variety_noise(5000, 2, variety, gen(0), torch.device("cpu"))
    assert noise["state"].shape == (499, 2, 2, 2, 256)
    assert abs(float(noise["state"].std()) - 1.0) < 0.01


def test_phrases_split_at_the_multiples():
    assert _phrases(0, 45, 20) == [(0, 20), (20, 40), (40, 45)]
    assert _phrases(33, 66, 20) == [(33, 40), (40, 60), (60, 66)]
    assert _phrases(40, 41, 20) == [(40, 41)]


def test_checkpoint_setting_is_read_and_checked():
    assert variety_from_meta({}, 25.0) == SeedVariety()
    v = variety_from_meta({"sampling": {"phrase_s": 3.0, "state_noise": 0.5, "latent_noise": 0.2}}, 25.0)
    assert v == SeedVariety(phrase=75, state_noise=0.5, latent_noise=0.2) and v.active
    with pytest.raises(CheckpointError, match="ckpt: bad 'sampling'.*state_noise"):
        variety_from_meta({"sampling": {"phrase_s": 3.0, "state_noise": 2.0}}, 25.0, folder="ckpt")
    with pytest.raises(CheckpointError, match="must be an object"):
        variety_from_meta({"sampling": 3}, 25.0, folder="ckpt")
