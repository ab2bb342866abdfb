"""Reduced-precision, fused decoding (dancekit.models.precision): the fused maths equals the model's own loop,
int8 / bf16 dances stay within their budget of the fp32 dance, fp32 is the model itself, bad values fail
on one line.

Budgets (normalised pose units, i.e. the training data's standard deviation per coordinate; mean absolute
difference over frames and coordinates to the fp32 dance of the same seed): bf16 ≤ 0.005, int8 ≤ 0.02 (bf16 runs the
whole dual generator in bfloat16, activations included: ~0.003 there; ~5e-5 for the LSTM decoders).
The fused float32 decoder must equal the reference loop to float32 rounding (1e-5).
"""

from __future__ import annotations

import copy

import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.dual import DualConfig, DualModel
from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel
from dancekit.models.precision import (
    PRECISIONS,
    FusedLSTMDecoder,
    FusedLSTMStep,
    FusedWaveNetStep,
    _gate_order,
    check_precision,
    to_precision,
)
from dancekit.models.revolution import RevolutionConfig, RevolutionModel

BUDGET = {"bf16": 0.005, "int8": 0.02}


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _revolution(condition_on_music: bool) -> RevolutionModel:
    torch.manual_seed(0)
    cfg = RevolutionConfig(music_dim=20, pose_dim=12, d_model=32, n_heads=2, d_ff=64, decoder_hidden=64,
                           decoder_layers=2, condition_on_music=condition_on_music, encoder_chunk=50)
    return RevolutionModel(cfg).eval()


@pytest.mark.parametrize("condition_on_music", [True, False])
def test_fused_fp32_decoder_equals_the_reference_loop(condition_on_music):
    model = _revolution(condition_on_music)
    music = torch.randn(2, 130, 20)  # 3 chunks of 50: the state crosses chunk borders
    ref = model.generate(music, generator=_gen(0))
    fused = copy.deepcopy(model)
    fused.fast_decoder = FusedLSTMDecoder(fused, "fp32")
    out = fused.generate(music, generator=_gen(0))
    assert out.shape == ref.shape
    torch.testing.assert_close(out, ref, atol=1e-5, rtol=0)


@pytest.mark.parametrize("precision", ["bf16", "int8"])
@pytest.mark.parametrize("condition_on_music", [True, False])
def test_revolution_reduced_precision_within_budget(precision, condition_on_music):
    model = _revolution(condition_on_music)
    music = torch.randn(1, 150, 20)
    ref = model.generate(music, generator=_gen(3))
    quick = to_precision(model, precision)
    out = quick.generate(music, generator=_gen(3))
    err = (out - ref).abs().mean().item()
    assert err <= BUDGET[precision], err
    assert err > 0  # it really ran at another precision
    assert model.generate(music, generator=_gen(3)).equal(ref)  # the original is untouched


def test_fp32_is_the_model_itself():
    model = _revolution(True)
    assert to_precision(model, "fp32") is model
    assert getattr(model, "fast_decoder", None) is None


def _music2dance(generator: str) -> Music2DanceModel:
    torch.manual_seed(0)
    cfg = Music2DanceConfig(music_dim=15, pose_dim=20, n_layers=6, channels=8, skip_channels=8, generator=generator,
                            music_condition="raw", lstm_hidden=32, lstm_layers=2)
    return Music2DanceModel(cfg).eval()


@pytest.mark.parametrize("generator", ["wavenet", "lstm"])
def test_music2dance_fused_step_equals_step(generator):
    model = _music2dance(generator)
    music, prev = torch.randn(2, 40, 15), torch.randn(2, 40, 20)
    with torch.no_grad():
        cond, g = model._conditions(music, None)
        fused = (FusedWaveNetStep if generator == "wavenet" else FusedLSTMStep)(model, "fp32")
        s1, s2 = model.init_state(2), model.init_state(2)
        w = model._step_weights() if generator == "wavenet" else None
        for t in range(40):
            torch.testing.assert_close(fused(cond[:, t], g, prev[:, t], s1), model.step(cond[:, t], g, prev[:, t], s2, w),
                                       atol=1e-5, rtol=0)


@pytest.mark.parametrize("precision", ["bf16", "int8"])
def test_music2dance_reduced_precision_within_budget(precision):
    model = _music2dance("wavenet")
    music = torch.randn(1, 60, 15)
    ref = model.generate(music, temperature=0.0, generator=_gen(0))  # the mixture means: no sampling noise
    out = to_precision(model, precision).generate(music, temperature=0.0, generator=_gen(0))
    err = (out - ref)[..., : model.config.gmm_dim].abs().mean().item()
    assert 0 < err <= BUDGET[precision], err


@pytest.mark.parametrize("precision", ["bf16", "int8"])
def test_dual_reduced_precision_within_budget(precision):
    torch.manual_seed(0)
    cfg = DualConfig(music_dim=53, pose_dim=15, window=12, m2d_d_model=16, m2d_layers=1, m2d_heads=2, m2d_ff=32,
                     d2m_d_model=16, d2m_layers=1, d2m_heads=2, d2m_ff=32)
    model = DualModel(cfg).eval()
    music, start = torch.rand(1, 30, 53), torch.randn(1, 15)
    ref = model.generate_dance(music, start=start)
    out = to_precision(model, precision).generate_dance(music, start=start)
    assert out.shape == ref.shape and out.dtype == torch.float32
    err = (out - ref).abs().mean().item()
    assert 0 < err <= BUDGET[precision], err


@pytest.mark.parametrize("bad", ["fp16", "INT8", "", "int4"])
def test_unknown_precision_is_a_one_line_error(bad):
    with pytest.raises(ParameterError) as info:
        check_precision(bad)
    assert "\n" not in str(info.value) and repr(bad) in str(info.value)
    with pytest.raises(ParameterError):
        to_precision(_revolution(True), bad)


def test_precisions():
    assert PRECISIONS == ("fp32", "bf16", "int8")


def test_pipeline_precision(tmp_path):
    """load_pipeline(precision=...) decodes close to fp32, and an unknown precision fails first.

    A trained decoder is chaotic: any perturbation (bf16 rounding too) grows until, after some 10 s, the dance
    is as far from the fp32 dance as another seed's (docs/research/speed-memory.md). Pointwise, only the first frames
    are compared; the whole-song budget is on the metrics."""
    from dancekit.pipelines import load_pipeline

    with pytest.raises(ParameterError, match="precision"):
        load_pipeline("revolution", precision="fp64")
    fp32 = load_pipeline("revolution")
    int8 = load_pipeline("revolution", precision="int8")
    assert int8.model is not fp32.model and getattr(fp32.model, "fast_decoder", None) is None
    music = torch.randn(1, 25, fp32.model.config.music_dim)  # the first second at 25 fps
    ref = fp32.model.generate(music, generator=_gen(0))
    out = int8.model.generate(music, generator=_gen(0))
    seed1 = fp32.model.generate(music, generator=_gen(1))
    err = (out - ref).abs().mean().item()
    assert 0 < err <= BUDGET["int8"], err
    assert err < 0.5 * (seed1 - ref).abs().mean().item()  # closer to its fp32 dance than another seed is


def test_cli_unknown_precision_is_one_line(tmp_path, capsys):
    from dancekit.cli.main import main

    song = tmp_path / "song.wav"
    song.write_bytes(b"")
    out = tmp_path / "out"
    assert main(["dance", str(song), "-o", str(out), "--precision", "fp16"]) != 0
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and "fp16" in err and err.startswith("dancekit dance: error:"), err
    assert not out.exists()
    code = main(["evaluate", "--pred", str(tmp_path), "--ref", str(tmp_path), "-o", str(tmp_path / "r.json"),
                 "--precision", "int8"])
    assert code != 0 and "--precision" in capsys.readouterr().err


def test_lstm_gate_order_known_answer():
    # nn.LSTM's rows [i, f, g, o] (H = 2 each) → [i, f, o, g]
    assert _gate_order(2).tolist() == [0, 1, 2, 3, 6, 7, 4, 5]


@pytest.mark.parametrize("precision", ["fp32", "int8"])
def test_fused_decoder_state_carries_across_calls(precision):
    """Two calls (the state and last pose of the first handed to the second) give exactly the dance of one call,
    at batch 2: the preallocated buffers take the state in and hand it back (h and c of every layer)."""
    model = _revolution(True)
    dec = FusedLSTMDecoder(model, precision)
    z, prev = torch.randn(2, 30, 32), torch.randn(2, 1, 12)
    state = model.initial_state(2, generator=_gen(1))
    whole, last, (h, c) = dec(z, prev, state)
    a, last_a, state_a = dec(z[:, :13], prev, state)
    b, last_b, (h_b, c_b) = dec(z[:, 13:], last_a, state_a)
    assert torch.equal(torch.cat([a, b], 1), whole) and torch.equal(last_b, last)
    assert torch.equal(h_b, h) and torch.equal(c_b, c) and h.shape == (2, 2, 64)
    assert not whole.is_inference() and not h.is_inference()  # usable outside inference_mode
    assert torch.equal(state[0], model.initial_state(2, generator=_gen(1))[0])  # the caller's state untouched


def test_int8_first_layer_input_product_is_float32():
    """int8 quantises only ``W_hh h`` in the first layer; its input map is the float32 weights (gate order)."""
    model = _revolution(False)
    stack = FusedLSTMDecoder(model, "int8").stack
    lin, input_T = stack.layers[0]
    assert lin.precision == "int8"
    assert torch.equal(input_T, model.decoder.weight_ih_l0[_gate_order(64)].T)
    assert all(extra is None for _, extra in stack.layers[1:])
