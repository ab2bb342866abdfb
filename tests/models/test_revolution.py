"""Dance Revolution model: local attention, curriculum, shapes, seeds, chunked inference (tiny CPU configs)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.revolution import (
    ENCODERS,
    RevolutionConfig,
    RevolutionModel,
    _runs,
    auto_condition_mask,
    band_attention,
    band_mask,
    global_attention,
    local_attention,
)

D, P = 8, 6


def tiny(**kw) -> RevolutionConfig:
    base = dict(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32, window=6, decoder_hidden=24,
                decoder_layers=2, dropout=0.0)
    return RevolutionConfig(**{**base, **kw})


def gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


@pytest.fixture
def batch():
    g = gen(123)
    return torch.randn(2, 30, D, generator=g), torch.randn(2, 30, P, generator=g)


# ---- local attention ----------------------------------------------------------------------------


@pytest.mark.parametrize("half", [0, 1, 3, 5, 50])
@pytest.mark.parametrize("n", [1, 7, 24, 31])
def test_local_attention_equals_band_masked_global(half, n):
    g = gen(n * 100 + half)
    q, k, v = (torch.randn(2, 3, n, 4, generator=g, dtype=torch.float64) for _ in range(3))
    bias = torch.randn(3, 2 * half + 1, generator=g, dtype=torch.float64)
    for b in (None, bias):
        local = local_attention(q, k, v, half_window=half, bias=b)
        ref = global_attention(q, k, v, half_window=half, bias=b, mask=band_mask(n, half))
        assert local.shape == (2, 3, n, 4)
        torch.testing.assert_close(local, ref, rtol=0, atol=1e-12)


def test_local_attention_float32_matches_to_1e5():
    g = gen(1)
    q, k, v = (torch.randn(1, 2, 40, 8, generator=g) for _ in range(3))
    ref = global_attention(q, k, v, half_window=4, mask=band_mask(40, 4))
    assert (local_attention(q, k, v, half_window=4) - ref).abs().max() < 1e-5


def test_local_attention_ignores_keys_outside_the_band():
    g = gen(2)
    q, k, v = (torch.randn(1, 1, 20, 4, generator=g) for _ in range(3))
    out = local_attention(q, k, v, half_window=2)
    k2, v2 = k.clone(), v.clone()
    k2[..., 10:, :] += 100.0  # keys/values 10.. are out of reach of queries 0..7
    v2[..., 10:, :] += 100.0
    out2 = local_attention(q, k2, v2, half_window=2)
    torch.testing.assert_close(out[..., :8, :], out2[..., :8, :])
    assert not torch.allclose(out[..., 8:, :], out2[..., 8:, :])


@pytest.mark.parametrize("half", [0, 1, 3, 5])
def test_attention_of_a_range_of_queries_equals_band_masked_global(half):
    """Queries ``[s, e)`` of a sequence of n frames against the keys within ``half`` of them (``q_offset``: where
    the first query sits among those keys), blocked and with one score matrix: the rows of the whole sequence's
    band-masked attention, at its start, in its middle and at its end."""
    n = 23
    g = gen(half)
    q, k, v = (torch.randn(2, 3, n, 4, generator=g, dtype=torch.float64) for _ in range(3))
    bias = torch.randn(3, 2 * half + 1, generator=g, dtype=torch.float64)
    for b in (None, bias):
        ref = global_attention(q, k, v, half_window=half, bias=b, mask=band_mask(n, half))
        for s, e in [(0, 1), (0, 5), (2, 3), (4, 16), (10, 23), (22, 23), (0, 23)]:
            ka, kb = max(0, s - half), min(n, e + half)
            for fn in (local_attention, band_attention):
                out = fn(q[:, :, s:e], k[:, :, ka:kb], v[:, :, ka:kb], half_window=half, bias=b, q_offset=s - ka)
                torch.testing.assert_close(out, ref[:, :, s:e], rtol=0, atol=1e-12)
            # more keys than the band on either side: those beyond it are not looked at
            out = local_attention(q[:, :, s:e], k, v, half_window=half, bias=b, q_offset=s)
            torch.testing.assert_close(out, ref[:, :, s:e], rtol=0, atol=1e-12)


def _ahead_mask(n: int, half: int, ahead: int) -> torch.Tensor:
    """(n, n) True where ``-half <= j - i <= ahead``: written from the definition, apart from the code under test."""
    return torch.tensor([[-half <= j - i <= ahead for j in range(n)] for i in range(n)])


@pytest.mark.parametrize("half, ahead", [(3, 0), (3, 1), (5, 2), (5, 5), (50, 1)])
def test_attention_with_a_shorter_lookahead_equals_its_masked_global(half, ahead):
    """``ahead``: keys from ``half`` frames back to ``ahead`` frames ahead, for the whole sequence (blocked) and for a
    range of queries (blocked and one score matrix); the relative bias as in the symmetric band."""
    n = 23
    g = gen(half * 10 + ahead)
    q, k, v = (torch.randn(2, 3, n, 4, generator=g, dtype=torch.float64) for _ in range(3))
    bias = torch.randn(3, 2 * half + 1, generator=g, dtype=torch.float64)
    for b in (None, bias):
        ref = global_attention(q, k, v, half_window=half, bias=b, mask=_ahead_mask(n, half, ahead))
        torch.testing.assert_close(local_attention(q, k, v, half_window=half, bias=b, ahead=ahead), ref, rtol=0,
                                   atol=1e-12)
        for s, e in [(0, 1), (2, 3), (4, 16), (22, 23)]:
            ka, kb = max(0, s - half), min(n, e + ahead)
            for fn in (local_attention, band_attention):
                out = fn(q[:, :, s:e], k[:, :, ka:kb], v[:, :, ka:kb], half_window=half, bias=b, q_offset=s - ka,
                         ahead=ahead)
                torch.testing.assert_close(out, ref[:, :, s:e], rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match="ahead"):
        local_attention(q, k, v, half_window=half, ahead=half + 1)


def test_encoder_with_a_lookahead_depends_on_no_later_music():
    """``lookahead=1`` with 2 layers: latent t depends on the music up to frame t + 2 and not after (changing
    frame t + 3 leaves it, changing t + 2 moves it); forward_range on the music up to t + 2 gives it."""
    from dancekit.models.revolution import MusicEncoder

    enc = _random_weights(MusicEncoder(tiny(window=10, lookahead=1)))
    music = torch.randn(1, 40, D, generator=gen(4))
    with torch.no_grad():
        whole = enc(music)
        for t in (0, 12, 30, 37):
            later = music.clone()
            later[:, t + 3 :] += 5.0
            torch.testing.assert_close(enc(later)[:, t], whole[:, t], rtol=0, atol=1e-5)
            nearer = music.clone()
            nearer[:, t + 2] += 5.0
            assert (enc(nearer)[:, t] - whole[:, t]).abs().max() > 1e-4  # far above the 1e-5 of float rounding
            torch.testing.assert_close(enc.forward_range(music[:, : t + 3], t, t + 1)[:, 0], whole[:, t], rtol=0,
                                       atol=1e-5)


@pytest.mark.parametrize("n_layers, lookahead", [(2, 1), (3, 2), (1, 0)])
def test_streaming_encoder_gives_each_latent_once_as_forward_does(n_layers, lookahead):
    """Music pushed in uneven chunks: the latents come out once each, in order, as soon as the music up to
    ``n_layers · lookahead`` frames after them has come, and equal the whole stream's forward pass."""
    from dancekit.models.revolution import MusicEncoder, StreamingEncoder

    enc = _random_weights(MusicEncoder(tiny(window=10, lookahead=lookahead, n_layers=n_layers)))
    music = torch.randn(1, 70, D, generator=gen(5))
    with torch.no_grad():
        whole = enc(music)
        for sizes in ((1,), (4,), (3, 1, 12, 2)):
            stream, out, a, i = StreamingEncoder(enc), [], 0, 0
            assert stream.latency == n_layers * lookahead
            while a < 70:
                n = sizes[i % len(sizes)]
                z = stream.push(enc.embed(music[:, a : a + n]))
                a, i = min(70, a + n), i + 1
                assert sum(o.shape[1] for o in out) + z.shape[1] == max(0, a - stream.latency)
                out.append(z)
            torch.testing.assert_close(torch.cat(out, 1), whole[:, : 70 - stream.latency], rtol=0, atol=1e-5)
    with pytest.raises(ParameterError, match="lookahead"):
        StreamingEncoder(MusicEncoder(tiny()))


def _random_weights(model: torch.nn.Module, seed: int = 0) -> torch.nn.Module:
    torch.manual_seed(seed)
    with torch.no_grad():
        for p in model.parameters():
            p.normal_(0.0, 0.3)  # the relative bias and layer norms too (zeros and ones at initialisation)
    return model.eval()


@pytest.mark.parametrize("encoder, window, n_layers, pos", [("local", 6, 2, "relative"), ("local", 7, 3, "relative"),
                                                            ("local", 0, 2, "relative"), ("local", 6, 1, "sinusoidal"),
                                                            ("conv", 6, 2, "relative"), ("lstm", 6, 2, "relative")])
def test_encoder_forward_range_equals_forward(encoder, window, n_layers, pos):
    """The latents of frames ``[s, e)`` computed on what they see equal those of the whole sequence's forward
    pass, wherever the range lies (the sequence's start and end included), short ranges (one score matrix) and
    long ones (blocked attention) alike."""
    from dancekit.models.revolution import MusicEncoder

    enc = _random_weights(MusicEncoder(tiny(encoder=encoder, window=window, n_layers=n_layers, pos_encoding=pos)))
    n = 41
    music = torch.randn(2, n, D, generator=gen(3))
    with torch.no_grad():
        whole = enc(music)
        for s in range(n):
            for e in range(s + 1, n + 1):
                torch.testing.assert_close(enc.forward_range(music, s, e), whole[:, s:e], rtol=0, atol=1e-5)
        assert enc.forward_range(music, 5, 5).shape == (2, 0, 16)


def test_embedded_encoder_forward_range_equals_forward():
    """The embedded model (2 layers, ±25 frames): a frame's latent at the stream's start, in its middle and at
    its end, and a block of frames, from the frames it sees alone."""
    from dancekit.pipelines import load_pipeline

    enc = load_pipeline("revolution").model.encoder.eval()
    n = 160
    music = torch.randn(1, n, enc.config.music_dim, generator=gen(4))
    with torch.no_grad():
        whole = enc(music)
        for s, e in [(0, 1), (3, 4), (80, 81), (80, 87), (24, 136), (157, 158), (159, 160), (150, 160), (0, 160)]:
            torch.testing.assert_close(enc.forward_range(music, s, e), whole[:, s:e], rtol=0, atol=1e-5)
        # the window a live step passes: 100 frames of history, the new frame and 2 frames of lookahead; the
        # frames embedded beforehand
        window = music[:, 40:143]
        torch.testing.assert_close(enc.forward_range(window, 100, 101), enc(window)[:, 100:101], rtol=0, atol=1e-5)
        torch.testing.assert_close(enc.forward_range(enc.embed(window), 100, 101, embedded=True),
                                   enc(window)[:, 100:101], rtol=0, atol=1e-5)
        # the first layer's projections of the embedded rows computed beforehand, row by row as a stream keeps
        # them: the same latents
        emb = enc.embed(window)
        qkv0 = torch.cat([enc.layers[0].projections(emb[:, k : k + 1]) for k in range(emb.shape[1])], dim=1)
        for s, e in [(100, 101), (0, 1), (60, 70), (102, 103)]:
            torch.testing.assert_close(enc.forward_range(emb, s, e, embedded=True, qkv0=qkv0), enc(window)[:, s:e],
                                       rtol=0, atol=1e-5)
        with pytest.raises(ParameterError, match="qkv0"):
            enc.forward_range(emb, 100, 101, embedded=True, qkv0=qkv0[:, 1:])
        with pytest.raises(ParameterError, match="qkv0"):
            enc.forward_range(window, 100, 101, qkv0=qkv0)


def test_quantised_encoder_forward_range_stays_within_its_quantisation():
    """An int8 copy (dancekit.models.precision: its linear layers quantised dynamically, each call's activations
    scaled by their own range, so no two calls on different frames agree exactly): its latents of a range are
    as near the float32 ones as its whole forward pass is (measured: both within 0.03)."""
    from dancekit.models.precision import to_precision
    from dancekit.pipelines import load_pipeline

    model = load_pipeline("revolution").model
    enc = to_precision(model, "int8").encoder.eval()
    music = torch.randn(1, 160, enc.config.music_dim, generator=gen(6))
    with torch.no_grad():
        ref = model.encoder.eval()(music)
        assert (enc(music) - ref).abs().max() < 0.06
        for s, e in [(0, 1), (80, 83), (158, 160)]:
            assert (enc.forward_range(music, s, e) - ref[:, s:e]).abs().max() < 0.06


def test_encoder_relative_bias_known_answer():
    """A one-layer local encoder attention with zero queries and keys, identity values and projection: only the
    hand-set relative bias decides where each frame looks. Head 0 is biased to offset j - i = +1 (the next
    frame), head 1 to j - i = -2; where that key does not exist, the frame averages the keys in its band."""
    from dancekit.models.revolution import MusicEncoder

    config = tiny(d_model=8, n_heads=2, window=6, n_layers=1)  # half window 3, 4 dims per head
    attn = MusicEncoder(config).layers[0].attn
    assert attn.local and attn.rel_bias.shape == (2, 7)
    n, d = 12, 8
    with torch.no_grad():
        attn.qkv.weight.zero_()
        attn.qkv.bias.zero_()
        attn.qkv.weight[2 * d :] = torch.eye(d)  # v = x; q = k = 0: every score is the bias alone
        attn.proj.weight.copy_(torch.eye(d))
        attn.proj.bias.zero_()
        attn.rel_bias.zero_()
        attn.rel_bias[0, 3 + 1] = 40.0  # index half + offset
        attn.rel_bias[1, 3 - 2] = 40.0
    x = torch.randn(1, n, d, generator=gen(5), dtype=torch.float32)
    with torch.no_grad():
        y = attn(x)[0]
    expected = torch.empty(n, d)
    for i in range(n):
        band = x[0, max(0, i - 3) : i + 4]
        expected[i, :4] = x[0, i + 1, :4] if i + 1 < n else band[:, :4].mean(0)
        expected[i, 4:] = x[0, i - 2, 4:] if i >= 2 else band[:, 4:].mean(0)
    torch.testing.assert_close(y, expected, rtol=0, atol=1e-5)
    # the same bias through the functions: local and global attention agree with the hand-computed answer
    q = torch.zeros(1, 2, n, 4, dtype=torch.float64)
    v = x[0].double().view(n, 2, 4).permute(1, 0, 2)[None]  # (1, H, n, 4)
    for out in (local_attention(q, q, v, half_window=3, bias=attn.rel_bias.detach().double()),
                global_attention(q, q, v, half_window=3, bias=attn.rel_bias.detach().double(), mask=band_mask(n, 3))):
        torch.testing.assert_close(out[0].permute(1, 0, 2).reshape(n, d).float(), expected, rtol=0, atol=1e-5)


# ---- curriculum mask ------------------------------------------------------------------------------


def test_auto_condition_mask_alternates_generated_then_ground_truth():
    # Y_in = {y0, ŷ1, ŷ2, y3, y4, y5, ŷ6, ŷ7, y8, y9, y10, ŷ11}
    assert auto_condition_mask(12, p=2, q=3).int().tolist() == [1, 0, 0, 1, 1, 1, 0, 0, 1, 1, 1, 0]
    assert auto_condition_mask(7, p=1, q=1).int().tolist() == [1, 0, 1, 0, 1, 0, 1]
    assert auto_condition_mask(5, p=0, q=10).all()  # teacher forcing
    assert auto_condition_mask(5, p=0, q=0).all()
    assert auto_condition_mask(5, p=3, q=0).int().tolist() == [1, 0, 0, 0, 0]  # fully autoregressive
    assert auto_condition_mask(0, p=2, q=2).numel() == 0


def test_auto_condition_mask_rejects_negative_values():
    with pytest.raises(ParameterError, match="p=-1"):
        auto_condition_mask(5, p=-1, q=2)


def test_runs_of_mask():
    assert _runs(torch.tensor([True, False, False, True])) == [(0, 1, True), (1, 3, False), (3, 4, True)]


@pytest.mark.parametrize("p,q", [(0, 10), (2, 3), (3, 1), (4, 0)])
def test_forward_feeds_ground_truth_exactly_where_the_mask_says(p, q):
    """Perturbing target frame j changes prediction j+1 iff decoder input j+1 is ground truth."""
    torch.manual_seed(0)
    model = RevolutionModel(tiny()).eval()
    n = 12
    music, dance = torch.randn(1, n, D), torch.randn(1, n, P)
    mask = auto_condition_mask(n, p=p, q=q)
    base, _ = model(music, dance, schedule_p=p, schedule_q=q, generator=gen())
    for j in range(n - 1):
        d2 = dance.clone()
        d2[0, j] += 1.0
        pred, _ = model(music, d2, schedule_p=p, schedule_q=q, generator=gen())
        changed = (pred - base).abs().amax(dim=(0, 2)) > 1e-7
        assert not changed[: j + 1].any()  # the past never sees the future
        assert bool(changed[j + 1]) == bool(mask[j + 1]), (j, mask.tolist())


def test_fully_autoregressive_forward_matches_generate(batch):
    music, dance = batch
    model = RevolutionModel(tiny())
    free, loss = model(music, None, generator=gen(3))
    assert loss is None
    curriculum, _ = model(music, dance, schedule_p=5, schedule_q=0, generator=gen(3))
    generated = model.generate(music, generator=gen(3))
    torch.testing.assert_close(free, curriculum)
    torch.testing.assert_close(free, generated)


# ---- shapes, settings, seeds -----------------------------------------------------------------------


@pytest.mark.parametrize("pos_encoding", ["relative", "sinusoidal"])
@pytest.mark.parametrize("encoder", ENCODERS)
def test_shapes_and_finite_gradients_for_every_encoder(encoder, pos_encoding, batch):
    music, dance = batch
    model = RevolutionModel(tiny(encoder=encoder, pos_encoding=pos_encoding, dropout=0.1))
    pred, loss = model(music, dance, schedule_p=4, schedule_q=3, generator=gen())
    assert pred.shape == (2, 30, P) and loss.ndim == 0
    torch.testing.assert_close(loss, (pred - dance).abs().mean())  # Eq. 5, mean L1
    loss.backward()
    grads = [p.grad for p in model.parameters() if p.requires_grad]
    assert all(g is not None and torch.isfinite(g).all() for g in grads)
    assert model.generate(music, generator=gen(), chunk=7).shape == (2, 30, P)
    assert model.encode(music).shape == (2, 30, 16)


@pytest.mark.parametrize("pose_dim", [72, 50])  # positions3d of tang2018, keypoints2d BODY_25
def test_pose_settings(pose_dim):
    model = RevolutionModel(tiny(pose_dim=pose_dim, music_dim=438))
    music, dance = torch.randn(1, 20, 438), torch.randn(1, 20, pose_dim)
    pred, loss = model(music, dance, schedule_p=2, schedule_q=2)
    assert pred.shape == (1, 20, pose_dim) and torch.isfinite(loss)


def test_music_enters_only_through_the_output_layer_without_conditioning():
    model = RevolutionModel(tiny(condition_on_music=False))
    assert model.decoder.input_size == P
    assert RevolutionModel(tiny()).decoder.input_size == P + 16
    pred, _ = model(torch.randn(1, 10, D), torch.randn(1, 10, P), schedule_p=2, schedule_q=2)
    assert pred.shape == (1, 10, P)


def test_zero_begin_of_pose_is_not_trained():
    model = RevolutionModel(tiny(bop="zero"))
    assert not model.bop.requires_grad and model.bop.abs().sum() == 0
    assert model.num_parameters() == RevolutionModel(tiny()).num_parameters() - P


def test_same_seed_same_dance_other_seed_other_dance(batch):
    music, _ = batch
    model = RevolutionModel(tiny())
    a = model.generate(music, generator=gen(0))
    b = model.generate(music, generator=gen(0))
    c = model.generate(music, generator=gen(1))
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert (a - c).abs().mean() > 1e-3


def test_initial_state_is_standard_normal():
    model = RevolutionModel(tiny(decoder_hidden=256, decoder_layers=2))
    h, c = model.initial_state(64, generator=gen(5))
    assert h.shape == c.shape == (2, 64, 256)
    assert abs(float(h.mean())) < 0.02 and abs(float(h.std()) - 1.0) < 0.02


@pytest.mark.parametrize("encoder", ["local", "conv"])
def test_chunked_encoding_and_generation_equal_whole_song(encoder):
    """Translation-equivariant encoders give the same result in overlapping chunks (bounded memory)."""
    model = RevolutionModel(tiny(encoder=encoder, n_layers=2, window=6, conv_kernel=3)).eval()
    music = torch.randn(1, 103, D, generator=gen(9))
    with torch.no_grad():
        whole = model.encode(music)
        for chunk in (5, 16, 50):
            torch.testing.assert_close(model.encode(music, chunk=chunk), whole, atol=1e-5, rtol=1e-5)
    full = model.generate(music, generator=gen(2), chunk=1000)
    torch.testing.assert_close(model.generate(music, generator=gen(2), chunk=16), full, atol=1e-5, rtol=1e-5)


def test_generate_restores_training_mode():
    model = RevolutionModel(tiny(dropout=0.5)).train()
    model.generate(torch.randn(1, 5, D), generator=gen())
    assert model.training


# ---- configuration errors ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"encoder": "rnn"}, "encoder"),
        ({"pos_encoding": "rope"}, "pos_encoding"),
        ({"d_model": 15}, "divisible"),
        ({"decoder_hidden": 0}, "decoder_hidden"),
        ({"dropout": 1.0}, "dropout"),
        ({"bop": "mean"}, "bop"),
        ({"baseline": True}, "baseline"),
        ({"window": -2}, "window"),
        ({"window": 10, "lookahead": 6}, "lookahead"),
        ({"lookahead": -1}, "lookahead"),
        ({"encoder": "conv", "lookahead": 1}, "lookahead"),
    ],
)
def test_bad_config_names_the_field(kw, match):
    with pytest.raises(ParameterError, match=match):
        tiny(**kw)


def test_lstm_baseline_configuration():
    cfg = RevolutionConfig.lstm_baseline(music_dim=D, pose_dim=P, d_model=16, n_heads=2)
    assert cfg.encoder == "lstm" and cfg.baseline
    assert RevolutionModel(cfg).encoder.receptive_field is None


def test_bad_input_shapes_are_named_errors():
    model = RevolutionModel(tiny())
    with pytest.raises(ParameterError, match=r"\(B, n, 8\)"):
        model(torch.randn(1, 10, D + 1))
    with pytest.raises(ParameterError, match="dance must have shape"):
        model(torch.randn(1, 10, D), torch.randn(1, 9, P))


def test_default_config_is_the_recommended_size():
    cfg = RevolutionConfig()
    model = RevolutionModel(cfg)
    assert (cfg.music_dim, cfg.pose_dim, cfg.encoder) == (438, 72, "local")
    assert 1.0e6 < model.num_parameters() < 2.0e6  # sized for ~30 min of training on 2 CPU cores
    out = model.generate(torch.zeros(1, 3, 438), generator=gen())
    assert out.shape == (1, 3, 72) and np.isfinite(out.numpy()).all()


def test_genre_condition_starts_neutral_and_then_steers():
    torch.manual_seed(0)
    model = RevolutionModel(tiny(n_genres=4))
    music = torch.randn(1, 20, D, generator=gen(5))
    auto = model.generate(music, generator=gen(0))
    waltz = model.generate(music, generator=gen(0), genre=torch.tensor([0]))
    torch.testing.assert_close(auto, waltz)  # zero-initialised: no effect before training
    with torch.no_grad():
        model.genre_embedding.weight.normal_()
    auto = model.generate(music, generator=gen(0))
    torch.testing.assert_close(model.generate(music, generator=gen(0), genre=torch.tensor([-1])), auto)  # -1 = auto
    assert (model.generate(music, generator=gen(0), genre=torch.tensor([0])) - auto).abs().max() > 1e-3
    with pytest.raises(ParameterError, match="genre"):
        model.generate(music, genre=torch.tensor([7]))
    with pytest.raises(ParameterError, match="not genre-conditioned"):
        RevolutionModel(tiny()).generate(music, genre=torch.tensor([0]))
