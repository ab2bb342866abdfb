"""The NumPy frame loop of the Dance Revolution decoder (:class:`~dancekit.models.revolution.NumpyDecoder`)
against torch's own ``nn.LSTM`` and ``nn.Linear`` stepped one frame at a time (the reference it must equal to float
rounding), and when it is used."""

from __future__ import annotations

import pytest
import torch

from dancekit.models.revolution import NumpyDecoder, RevolutionConfig, RevolutionModel

D, P = 8, 6


def model_of(**kw) -> RevolutionModel:
    torch.manual_seed(0)
    cfg = dict(music_dim=D, pose_dim=P, d_model=16, n_layers=1, n_heads=2, d_ff=32, window=8, decoder_hidden=24)
    cfg.update(kw)
    model = RevolutionModel(RevolutionConfig(**cfg)).eval()
    with torch.no_grad():  # weights larger than the default init, so the gates saturate somewhere too
        for p in (*model.decoder.parameters(), *model.head.parameters()):
            p.mul_(3.0)
    return model


def reference(model: RevolutionModel, z, prev, state):
    """Frame by frame with ``nn.LSTM`` (one step of length 1) and ``nn.Linear``: ŷ_t = [h_t; z_t] W^S + b."""
    y, outputs = prev, []
    for t in range(z.shape[1]):
        x = torch.cat([y, z[:, t : t + 1]], -1) if model.config.condition_on_music else y
        h, state = model.decoder(x, state)
        y = model.head(torch.cat([h, z[:, t : t + 1]], -1))
        outputs.append(y)
    return torch.cat(outputs, 1), state


@pytest.mark.parametrize("layers", [1, 2, 3])
@pytest.mark.parametrize("condition_on_music", [True, False])
def test_numpy_decoder_equals_nn_lstm_stepped_frame_by_frame(layers, condition_on_music):
    model = model_of(decoder_layers=layers, condition_on_music=condition_on_music)
    g = torch.Generator().manual_seed(1)
    B, L, H = 3, 60, model.config.decoder_hidden
    z = torch.randn(B, L, 16, generator=g)
    prev = torch.randn(B, 1, P, generator=g)
    state = (torch.randn(layers, B, H, generator=g), torch.randn(layers, B, H, generator=g))
    given = (state[0].clone(), state[1].clone())
    with torch.no_grad():
        want, (h_want, c_want) = reference(model, z, prev, state)
        got, last, (h_got, c_got) = NumpyDecoder.of(model)(z, prev, state)
    assert want.abs().max() > 1.0  # the dance moves: the comparison is not of zeros
    torch.testing.assert_close(got, want, rtol=0, atol=1e-5)
    torch.testing.assert_close(h_got, h_want, rtol=0, atol=1e-5)
    torch.testing.assert_close(c_got, c_want, rtol=0, atol=1e-5)
    assert torch.equal(last, got[:, -1:])
    assert torch.equal(state[0], given[0]) and torch.equal(state[1], given[1])  # the caller's state is not written


def test_generate_uses_the_numpy_decoder_and_training_keeps_torch():
    model = model_of(decoder_layers=2)
    z = torch.randn(1, 5, 16)
    assert not NumpyDecoder.usable(model, z)  # grad mode on, weights that require gradients: torch
    with torch.no_grad():
        assert NumpyDecoder.usable(model, z)
        assert not NumpyDecoder.usable(model, z.double())
    model.train()
    music = torch.randn(1, 12, D)
    pred, _ = model(music, None, generator=torch.Generator().manual_seed(0))
    assert pred.requires_grad  # the generated run kept its graph


def test_a_changed_weight_rebuilds_the_numpy_decoder():
    model = model_of()
    z, prev = torch.randn(1, 10, 16), torch.randn(1, 1, P)
    state = model.initial_state(1, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        before = NumpyDecoder.of(model)(z, prev, state)[0]
        model.head.bias.add_(1.0)  # an optimiser step writes in place
        after = NumpyDecoder.of(model)(z, prev, state)[0]
        want, _ = reference(model, z, prev, state)
    assert (after - before).abs().max() > 0.5
    torch.testing.assert_close(after, want, rtol=0, atol=1e-5)


def test_decoding_a_block_at_a_time_is_bit_for_bit_one_pass():
    """Stepped 1, 7 or an uneven number of frames at a time with the state carried (as ``dancekit live`` does), the
    NumPy decoder gives one pass's numbers exactly: every product is a frame's own."""
    model = model_of(decoder_layers=2)
    g = torch.Generator().manual_seed(2)
    z, prev = torch.randn(2, 40, 16, generator=g), torch.randn(2, 1, P, generator=g)
    state = model.initial_state(2, generator=g)
    with torch.no_grad():
        whole, _, (h, c) = NumpyDecoder.of(model)(z, prev, state)
        for cuts in ([1] * 40, [7] * 5 + [5], [3, 11, 1, 25]):
            ys, y, st, a = [], prev, state, 0
            for n in cuts:
                out, y, st = NumpyDecoder.of(model)(z[:, a : a + n], y, st)
                ys.append(out)
                a += n
            assert torch.equal(torch.cat(ys, 1), whole) and torch.equal(st[0], h) and torch.equal(st[1], c), cuts


def test_the_decoder_runs_its_products_on_one_blas_thread(monkeypatch):
    """A frame's products are too small to share between BLAS threads (a second thread waiting for a busy core
    tripled the time a frame under load): the loop runs with one BLAS thread, and the caller's setting is back
    after it."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads() -> set[int]:
        return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}

    seen, real = [], NumpyDecoder._run

    def spy(decoders, z, prev, state):
        seen.append(blas_threads())
        return real(decoders, z, prev, state)

    monkeypatch.setattr(NumpyDecoder, "_run", staticmethod(spy))
    model = model_of()
    z, prev = torch.randn(1, 5, 16), torch.randn(1, 1, P)
    with threadpool_limits(2, user_api="blas"), torch.no_grad():
        assert blas_threads() == {2}
        NumpyDecoder.of(model)(z, prev, model.initial_state(1))
        assert blas_threads() == {2}
    assert seen == [{1}]


# ---- the local encoder's frames in NumPy (a live block's encoder work) -----------------------------------------

@pytest.mark.parametrize("layers,window,lookahead", [(1, 8, None), (2, 8, None), (2, 10, 2), (3, 6, 0)])
def test_numpy_encoder_range_equals_the_whole_sequence_encoder(layers, window, lookahead):
    import numpy as np

    from dancekit.models.revolution import NumpyLocalEncoder

    model = model_of(n_layers=layers, window=window, lookahead=lookahead, n_heads=4)
    enc = model.encoder
    with torch.no_grad():  # a relative bias that is not zero, so its gather is checked too
        for layer in enc.layers:
            layer.attn.rel_bias.copy_(torch.randn(layer.attn.rel_bias.shape, generator=torch.Generator().manual_seed(2)))
    assert NumpyLocalEncoder.usable(enc)
    music = torch.randn(1, 40, D, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        want = enc(music)[0].numpy()  # (40, d): every frame, the whole sequence at once
    ne = NumpyLocalEncoder.of(enc)
    x = ne.embed_rows(music[0].numpy())
    qkv0 = ne.projections(x)
    for start, stop in [(0, 1), (0, 40), (17, 18), (20, 26), (39, 40), (35, 50)]:
        for given in (None, qkv0):
            got = ne.forward_range(x, start, stop, qkv0=given)
            np.testing.assert_allclose(got, want[start:stop], atol=2e-5, rtol=0)
    assert np.abs(want).max() > 1.0


def test_numpy_encoder_refuses_what_it_does_not_compute():
    from dancekit.models.revolution import NumpyLocalEncoder

    assert not NumpyLocalEncoder.usable(model_of(pos_encoding="sinusoidal").encoder)
    assert not NumpyLocalEncoder.usable(model_of(encoder="conv").encoder)
    assert not NumpyLocalEncoder.usable(model_of().double().encoder)
