"""Seed variety of the Dance Revolution decoder (issue 15): the seed keeps changing the dance after its
opening when :class:`SeedVariety` perturbs the decoding per phrase; the same seed still gives the same dance."""

from __future__ import annotations

import pytest
import torch

from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel, SeedVariety, _phrases
from dancekit.pipelines.config import RevolutionSampling, checkpoint_settings
from dancekit.pipelines.revolution import variety_from_sampling


def variety_from_meta(meta: dict, fps: float, folder: str = "?") -> SeedVariety:
    """The seed variety a checkpoint's config.json gives (parsed as the pipeline parses it)."""
    settings = checkpoint_settings({"model": "revolution", **meta}, folder=folder, sampling=RevolutionSampling)
    return variety_from_sampling(settings.sampling, fps, folder=folder)

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
    with pytest.raises(CheckpointError, match="ckpt: config.json: sampling: .*state_noise"):
        variety_from_meta({"sampling": {"phrase_s": 3.0, "state_noise": 2.0}}, 25.0, folder="ckpt")
    with pytest.raises(CheckpointError, match="must be an object"):
        variety_from_meta({"sampling": 3}, 25.0, folder="ckpt")


# ---- the learned style latent (style_dim > 0, a CVAE per segment) -------------------------------------------


def style_model(*, zero_proj: bool = False) -> RevolutionModel:
    torch.manual_seed(0)
    model = RevolutionModel(RevolutionConfig(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32, window=6,
                                             decoder_hidden=24, dropout=0.0, style_dim=4, style_segment=10))
    if not zero_proj:
        torch.nn.init.normal_(model.style_proj.weight)
    return model.eval()


def test_a_style_latent_model_starts_out_as_the_model_without():
    """The projection is zero-initialised: fine-tuning from a model without the latent starts from its dances."""
    model = style_model(zero_proj=True)
    plain = RevolutionModel(RevolutionConfig(**{**model.config.__dict__, "style_dim": 0})).eval()
    plain.load_state_dict({k: v for k, v in model.state_dict().items() if not k.startswith("style_")})
    v = SeedVariety(style=1.0, style_share=0.5)
    torch.testing.assert_close(model.generate(music(), generator=gen(1), variety=v),
                               plain.generate(music(), generator=gen(1)), rtol=0, atol=0)


def test_the_style_latent_is_drawn_per_seed_and_reproducible():
    model = style_model()
    v = SeedVariety(style=1.0, style_share=0.5)
    assert v.active
    assert seed_gap(model, SeedVariety()) < seed_gap(model, v)
    assert seed_gap(model, v, frames=slice(N - 10, None)) > 1e-2  # apart to the end
    a = model.generate(music(), generator=gen(4), variety=v)
    torch.testing.assert_close(model.generate(music(), generator=gen(4), variety=v, chunk=33), a,
                               rtol=1e-5, atol=1e-5)
    batch = model.generate(music(), generator=[gen(4), gen(5)], variety=v)
    torch.testing.assert_close(batch[:1], a, rtol=1e-4, atol=1e-5)


def test_the_style_path_interpolates_between_segment_centres():
    model = style_model()
    knots = torch.tensor([[[0.0], [10.0], [20.0]]])  # centres of 10-frame segments: 4.5, 14.5, 24.5
    w = model.style_path(knots, 30)[0, :, 0]
    assert float(w[0]) == 0.0 and float(w[4]) == 0.0  # constant before the first centre
    assert abs(float(w[9]) - 4.5) < 1e-5 and abs(float(w[14]) - 9.5) < 1e-5
    assert float(w[29]) == 20.0  # constant after the last


def test_the_style_posterior_has_one_knot_per_segment_and_the_loss_a_kl_term():
    model = style_model().train()
    dance = torch.randn(2, 25, P)
    mu, logvar = model.style_knots(dance)
    assert mu.shape == logvar.shape == (2, 3, 4)
    # the last (5-frame) segment's knot depends on its own frames only
    other = dance.clone()
    other[:, :20] += 1.0
    torch.testing.assert_close(model.style_knots(other)[0][:, 2], mu[:, 2])
    x = torch.randn(2, 25, D)
    _, with_kl = model(x, dance, generator=gen(0))
    model.config.style_beta = 0.0
    _, without = model(x, dance, generator=gen(0))
    assert with_kl.item() > without.item()  # the KL term is added (at least the free bits)
    with pytest.raises(ParameterError, match="style_share"):
        SeedVariety(style=1.0, style_share=1.5)
    assert variety_from_meta({"sampling": {"style": 0.8, "style_share": 0.5}}, 25.0) == \
        SeedVariety(style=0.8, style_share=0.5)
