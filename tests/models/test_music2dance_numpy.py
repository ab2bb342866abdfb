"""The NumPy frame loop of the Music2Dance WaveNet (:class:`NumpyWaveNet`, issue 13's ≤ 5 s point) against the
torch reference (:meth:`Music2DanceModel.step`, ``generate(reference=True)``).

Both loops compute the same products in the same float dtype from the same random draws; they differ by float
rounding only (NumPy's BLAS against torch's, the gate's sigmoid as a tanh), so 50 sampled frames of a random
model agree to 1e-5. A wrong tap, dilation, bias, gate half, clamp or noise draw moves them by 1e-2 or more.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel, NumpyWaveNet

T = 50


def _model(dtype=torch.float32, **kw) -> Music2DanceModel:
    cfg = dict(music_dim=6, pose_dim=14, n_genres=3, n_layers=7, channels=8, skip_channels=12, genre_dim=4,
               fmap_channels=(4, 4, 4), fmap_lstm_hidden=4, n_mixtures=1, min_log_var=-2.0)
    torch.manual_seed(0)
    model = Music2DanceModel(Music2DanceConfig(**{**cfg, **kw})).to(dtype).eval()
    with torch.no_grad():  # biases away from zero, so that a bias dropped or added twice shows
        for m in model.modules():
            if isinstance(m, torch.nn.Conv1d | torch.nn.Linear) and m.bias is not None:
                m.bias.normal_(0, 0.3)
    return model


def _gens(seeds):
    return [torch.Generator().manual_seed(s) for s in seeds]


CASES = {
    "sampled": ({}, {"temperature": 1.0}),
    "correlated_noise": ({}, {"temperature": 0.8, "noise_correlation": 0.9}),
    "means": ({}, {"temperature": 0.0}),
    "kernel3": ({"kernel": 3, "max_dilation_exp": 2}, {"temperature": 0.7, "noise_correlation": 0.5}),
    "raw_music": ({"music_condition": "raw"}, {"temperature": 1.0, "genre_scale": 1.5}),
    "mixture_sampled": ({"n_mixtures": 3}, {"temperature": 1.0}),  # the component choice: torch, frame by frame
    "mixture_correlated": ({"n_mixtures": 3}, {"temperature": 0.9, "noise_correlation": 0.8}),
    "mixture_means": ({"n_mixtures": 3}, {"temperature": 0.0}),
    "no_contacts": ({"contact_dim": 0}, {"temperature": 1.0}),
}


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("case", sorted(CASES))
def test_numpy_loop_equals_the_torch_step(case, dtype):
    model_kw, gen_kw = CASES[case]
    model = _model(dtype, **model_kw)
    music = torch.randn(2, T, model.config.music_dim, generator=torch.Generator().manual_seed(1), dtype=dtype)
    genre = torch.tensor([2, -1])
    ref = model.generate(music, genre, generator=_gens([5, 6]), reference=True, **gen_kw)
    out = model.generate(music, genre, generator=_gens([5, 6]), **gen_kw)
    assert out.dtype == ref.dtype == dtype and out.shape == ref.shape == (2, T, model.config.pose_dim)
    torch.testing.assert_close(out, ref, rtol=0, atol=1e-5)
    # the frames are sampled and fed back (not the means, not a constant): the check compares something
    assert ref[:, 1:].std(dim=1).mean() > 0.01
    if model.config.contact_dim:
        assert set(out[..., -model.config.contact_dim :].unique().tolist()) <= {0.0, 1.0}


def test_numpy_loop_with_one_generator_and_none_draws_as_the_torch_loop():
    """One generator for a batch (a (B, D) draw a frame), and the global generator (``generator=None``)."""
    model = _model()
    music = torch.randn(3, T, model.config.music_dim, generator=torch.Generator().manual_seed(2))
    ref = model.generate(music, None, generator=torch.Generator().manual_seed(3), reference=True,
                         noise_correlation=0.7)
    out = model.generate(music, None, generator=torch.Generator().manual_seed(3), noise_correlation=0.7)
    torch.testing.assert_close(out, ref, rtol=0, atol=1e-5)
    torch.manual_seed(9)
    ref = model.generate(music, None, reference=True)
    torch.manual_seed(9)
    out = model.generate(music, None)
    torch.testing.assert_close(out, ref, rtol=0, atol=1e-5)


def test_numpy_loop_rows_are_the_seeds_alone_and_seeds_reproduce():
    model = _model()
    music = torch.randn(1, T, model.config.music_dim, generator=torch.Generator().manual_seed(4))
    kw = {"temperature": 0.8, "noise_correlation": 0.95}
    batch = model.generate(music.expand(3, -1, -1), torch.tensor([0, 1, -1]), generator=_gens([7, 0, 7]), **kw)
    for k, (g, s) in enumerate(zip([0, 1, -1], [7, 0, 7])):
        alone = model.generate(music, torch.tensor([g]), generator=_gens([s]), **kw)[0]
        torch.testing.assert_close(batch[k], alone, rtol=0, atol=1e-5)
    again = model.generate(music, torch.tensor([0]), generator=_gens([7]), **kw)[0]
    assert torch.equal(again, model.generate(music, torch.tensor([0]), generator=_gens([7]), **kw)[0])
    assert (batch[0] - batch[2]).abs().max() > 1e-2  # another genre, another dance
    other = model.generate(music, torch.tensor([0]), generator=_gens([8]), **kw)[0]
    assert (other - again).abs().max() > 1e-2  # another seed, another dance


def test_numpy_loop_chunks_carry_the_state_across():
    """A song longer than a chunk: the rings, the noise correlation and the last frame carry over."""
    model = _model()
    music = torch.randn(1, 70, model.config.music_dim, generator=torch.Generator().manual_seed(5))
    kw = {"temperature": 0.9, "noise_correlation": 0.8}
    whole = model.generate(music, None, generator=_gens([1]), **kw)
    chunked = NumpyWaveNet(model)
    chunked.CHUNK = 16
    cond, _ = model._conditions(music, None)
    out = torch.from_numpy(chunked.generate(cond, music.new_zeros(1, model.config.pose_dim), generator=_gens([1]),
                                            **kw))
    torch.testing.assert_close(out, whole, rtol=0, atol=1e-6)


def test_reduced_precision_and_the_lstm_keep_their_torch_loops():
    from dancekit.models.precision import to_precision

    model = _model()
    music = torch.randn(1, 20, model.config.music_dim)
    quick = to_precision(model, "bf16")
    with torch.no_grad():
        assert quick.fast_step is not None
        a = quick.generate(music, None, temperature=0.0)
        b = quick.generate(music, None, temperature=0.0, reference=True)
    assert torch.equal(a, b)  # the fused bf16 step, not the NumPy loop
    lstm = _model(generator="lstm", lstm_hidden=8, lstm_layers=1)
    assert torch.equal(lstm.generate(music, None, temperature=0.0),
                       lstm.generate(music, None, temperature=0.0, reference=True))
    with pytest.raises(ParameterError, match="WaveNet"):
        NumpyWaveNet(lstm)
    assert np.isfinite(a.numpy()).all()


@pytest.mark.parametrize("case", ["sampled", "mixture_sampled"])
def test_a_given_prefix_is_the_dance_and_its_next_inputs(case):
    """``generate(prefix=...)``: the first N frames are the prefix in both loops; frame N is the model's sample from
    the inputs [first, prefix...] (known answer: the teacher-forced :meth:`forward` over those inputs gives its
    mixture parameters; with temperature 0 the frame is their mean); and the loops agree after it."""
    model_kw, gen_kw = CASES[case]
    model = _model(**model_kw)
    P, N = model.config.pose_dim, 9
    music = torch.randn(2, T, model.config.music_dim, generator=torch.Generator().manual_seed(1))
    genre = torch.tensor([2, -1])
    prefix = torch.randn(1, N, P, generator=torch.Generator().manual_seed(4))
    ref = model.generate(music, genre, generator=_gens([5, 6]), reference=True, prefix=prefix, **gen_kw)
    out = model.generate(music, genre, generator=_gens([5, 6]), prefix=prefix, **gen_kw)
    assert torch.equal(out[:, :N], prefix.expand(2, -1, -1)) and torch.equal(ref[:, :N], prefix.expand(2, -1, -1))
    torch.testing.assert_close(out, ref, rtol=0, atol=1e-5)
    free = model.generate(music, genre, generator=_gens([5, 6]), **gen_kw)
    assert not torch.allclose(free[:, N], out[:, N])
    # frame N at temperature 0, against the parallel (teacher-forced) forward pass over [0, prefix[0..N-1], ...]
    # (causal in its input: the frames after N do not matter)
    mean = model.generate(music[:1], genre[:1], generator=_gens([5]), prefix=prefix, temperature=0.0)
    with torch.no_grad():
        prev = torch.cat([torch.zeros(1, 1, P), prefix, torch.zeros(1, T - N - 1, P)], dim=1)
        params = model(music[:1], prev, genre[:1])[:, N]
    want = model.predict(params, temperature=0.0)
    torch.testing.assert_close(mean[:, N], want, rtol=0, atol=1e-5)


def test_a_prefix_of_another_pose_size_is_refused():
    model = _model()
    with pytest.raises(ParameterError, match="prefix"):
        model.generate(torch.zeros(1, T, model.config.music_dim), torch.tensor([0]), generator=_gens([0]),
                       prefix=torch.zeros(1, 3, model.config.pose_dim + 1))
