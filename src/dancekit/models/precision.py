"""Reduced-precision, fused decoding for the autoregressive models (inference only).

:func:`to_precision` returns a copy of a trained model that generates at ``"fp32"`` (the model itself,
untouched: bit-identical output), ``"bf16"`` or ``"int8"``:

* ``int8``: weights quantised to int8 per output channel, activations quantised on the fly per call
  (dynamic quantisation, the fbgemm / x86 kernels of ``torch.ops.quantized.linear_dynamic`` that
  ``torch.ao.quantization.quantize_dynamic`` uses, with ``reduce_range`` as it does on x86). The paper-size
  Dance Revolution decoder (3 LSTM layers of 1024, 21 M weights) reads 21 MB per frame instead of 85 MB,
  which fits a 32 MB last-level cache: decoding stops being bound by DRAM bandwidth.
* ``bf16``: weights and the matrix products in bfloat16, the LSTM cell state and the gates' non-linearities
  in float32. Only faster on CPUs with native bf16 arithmetic (``avx512_bf16`` / AMX:
  :func:`native_bf16`); elsewhere it is correct but emulated.

Per family (the model files keep their own float32 code; each generate loop asks for the model's
``fast_decoder`` / ``fast_step`` when one is set):

* ``revolution`` — :class:`FusedLSTMDecoder` replaces :meth:`RevolutionModel._autoregress`: what does not
  depend on the previous output is computed for the whole chunk in one product (the head's music term
  ``z W_z + b`` and, with ``condition_on_music``, the first layer's music term), each layer's input and
  recurrent products are one matrix ``[W_ih | W_hh]`` on ``[x; h]``, and the LSTM gates are a few fused
  element-wise ops: one Python call per frame. int8 also quantises the music encoder's ``nn.Linear``
  layers (``quantize_dynamic``); bf16 keeps the encoder in float32.
* ``music2dance`` — :class:`FusedWaveNetStep` (or the same LSTM stack for ``generator="lstm"``) replaces
  :meth:`Music2DanceModel.step`, every product at the precision.
* ``dual`` — the ``nn.Linear`` layers of G_M→D's decoder side quantised (``quantize_dynamic``: the target
  embedding, the feed-forward layers and the head; the attention projections inside
  ``nn.MultiheadAttention`` and the encoder, run once per window, stay float32), or the whole generator
  in bfloat16.

The accuracy budget (how far the quantised dance may be from the fp32 dance) is measured in
``benchmarks/bench_paper_size.py`` and stated in docs/BENCHMARKS.md.
"""

from __future__ import annotations

import copy
import warnings

import torch
from torch import nn

from dancekit.errors import ParameterError

PRECISIONS = ("fp32", "bf16", "int8")


def check_precision(precision: str) -> str:
    """``precision`` if it is one of :data:`PRECISIONS`, else a one-line :class:`ParameterError`."""
    if precision not in PRECISIONS:
        raise ParameterError(f"unknown precision {precision!r}; choose one of {', '.join(PRECISIONS)}")
    return precision


def native_bf16() -> bool:
    """Whether this CPU has native bfloat16 arithmetic (AVX-512 BF16 or AMX; ``torch.backends.cpu``)."""
    cap = torch.backends.cpu.get_cpu_capability()
    if cap in ("AVX512_BF16", "AMX") or "AMX" in cap:
        return True
    try:
        with open("/proc/cpuinfo") as f:
            flags = f.read()
    except OSError:
        return False
    return "avx512_bf16" in flags or "amx_bf16" in flags


# --------------------------------------------------------------------------------------------------
# one linear map at a precision


class _Linear:
    """``y = x W^T + b`` at a precision: ``x (B, in)`` float32 → ``(B, out)`` float32.

    ``weight (out, in)``, ``bias (out,)`` or None, float32. int8: per-output-channel symmetric int8
    weights, activations quantised per call (uint8, 7-bit range on x86 as ``quantize_dynamic`` does).
    """

    def __init__(self, weight: torch.Tensor, bias: torch.Tensor | None, precision: str):
        self.precision = precision
        weight = weight.detach().float().contiguous()
        bias = None if bias is None else bias.detach().float().contiguous()
        self.out_features = weight.shape[0]
        if precision == "int8":
            scale = (weight.abs().amax(dim=1) / 127.0).clamp_min(1e-8).double()  # (out,)
            with warnings.catch_warnings():  # torch's quantized-tensor API warns about its own future
                warnings.simplefilter("ignore")
                qweight = torch.quantize_per_channel(weight, scale, torch.zeros_like(scale, dtype=torch.long),
                                                     0, torch.qint8)
                self.packed = torch.ops.quantized.linear_prepack(qweight, bias)
        elif precision == "bf16":
            self.weight = weight.to(torch.bfloat16)
            self.bias = None if bias is None else bias.to(torch.bfloat16)
        else:
            self.weight, self.bias = weight, bias

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        if self.precision == "int8":
            return torch.ops.quantized.linear_dynamic(x.contiguous(), self.packed, True)
        if self.precision == "bf16":
            return torch.nn.functional.linear(x.to(torch.bfloat16), self.weight, self.bias).float()
        return torch.nn.functional.linear(x, self.weight, self.bias)


def _gate_order(H: int) -> torch.Tensor:
    """Row permutation of ``nn.LSTM``'s gates ``[i, f, g, o]`` (each ``H`` rows) to ``[i, f, o, g]``: the three
    sigmoid gates contiguous, so that they are one ``sigmoid_`` and ``g`` one ``tanh_``."""
    return torch.cat([torch.arange(2 * H), torch.arange(3 * H, 4 * H), torch.arange(2 * H, 3 * H)])


class LSTMStack:
    """The layers of an ``nn.LSTM`` (unidirectional, batch-first or not) as one step function at a precision.

    Layer ``l`` computes its gates as one product ``[W_ih | W_hh] [x; h_l] + b_ih + b_hh`` (gate rows
    reordered to ``[i, f, o, g]``, :func:`_gate_order`, so that the sigmoid gates are one kernel); for int8
    the first layer's input product (its input, e.g. a normalised pose, is narrow and has another range than
    ``h`` in [-1, 1]) stays float32 and only ``W_hh h`` is int8. ``first_input`` selects the first ``first_input`` columns of layer 0's input weights
    (the rest, e.g. a music term, is added by the caller as ``extra0``, rows in the stack's order:
    :meth:`order_rows`).

    :meth:`step_` runs one frame in preallocated buffers (:meth:`buffers`): per layer one product (for
    int8's first layer one int8 product and one float32 ``addmm`` into the gates), one copy of the gates into a persistent buffer whose gate views are made once, six
    element-wise kernels in place and one copy of ``h``; no ``torch.cat``, no slicing and no state
    allocation per frame (at batch 1 and paper size every dispatch costs a few µs against ~0.3 ms of
    product per layer).
    """

    def __init__(self, lstm: nn.LSTM, precision: str, *, first_input: int | None = None):
        if lstm.bidirectional or getattr(lstm, "proj_size", 0):
            raise ParameterError("only a unidirectional nn.LSTM without projections can be fused")
        self.hidden = H = lstm.hidden_size
        self.order = _gate_order(H)
        self.inputs: list[int] = []  # width of each layer's input x
        self.layers: list[tuple[_Linear, torch.Tensor | None]] = []  # (gates product, float32 input map (in, 4H))
        for layer in range(lstm.num_layers):
            w_ih = getattr(lstm, f"weight_ih_l{layer}")[self.order]
            w_hh = getattr(lstm, f"weight_hh_l{layer}")[self.order]
            b = (getattr(lstm, f"bias_ih_l{layer}") + getattr(lstm, f"bias_hh_l{layer}"))[self.order] if lstm.bias else None
            if layer == 0 and first_input is not None:
                w_ih = w_ih[:, :first_input]
            self.inputs.append(w_ih.shape[1])
            if layer == 0 and precision == "int8":
                # the input (e.g. a normalised pose, a few dozen columns) stays float32, one small addmm: in the
                # int8 product its range would coarsen h's activation scale, and a second int8 call costs more
                self.layers.append((_Linear(w_hh, b, precision), w_ih.detach().float().contiguous().T))
            else:
                self.layers.append((_Linear(torch.cat([w_ih, w_hh], dim=1), b, precision), None))

    def order_rows(self, w: torch.Tensor) -> torch.Tensor:
        """``w (4H, ...)`` in ``nn.LSTM``'s gate order → the stack's order (for a caller's ``extra0`` weights)."""
        return w[self.order]

    def buffers(self, x: torch.Tensor, hs: list[torch.Tensor], cs: list[torch.Tensor]) -> _StackBuffers:
        """Preallocated per-layer ``[x | h]`` buffers (float32) holding input ``x (B, in)`` and states ``hs``,
        ``cs`` (lists of ``(B, H)``), for :meth:`step_`."""
        return _StackBuffers(self, x, hs, cs)

    def step_(self, buf: _StackBuffers, extra0: torch.Tensor | None = None) -> None:
        """One frame in the buffers (input ``buf.x``, set by the caller): every layer's ``h`` and ``c``
        updated in place; ``extra0 (B, 4H)`` (stack gate order) added to the first layer's gates. The last
        layer's ``h`` is ``buf.h[-1]``."""
        last = len(self.layers) - 1
        G, (i, f, o, g, ifo), c, tmp = buf.gates, buf.views, buf.c, buf.tmp
        for layer, (lin, input_T) in enumerate(self.layers):
            if input_T is None:
                G.copy_(lin(buf.xh[layer]))
            else:  # int8 first layer: W_hh h (int8, with the bias) + x W_ih^T (float32)
                torch.addmm(lin(buf.h[0]), buf.x, input_T, out=G)
            if layer == 0 and extra0 is not None:
                G.add_(extra0)
            ifo.sigmoid_()
            g.tanh_()
            c[layer].mul_(f).addcmul_(i, g)  # c = f c + i g
            torch.tanh(c[layer], out=tmp)
            if layer < last:  # h = o tanh(c): into the next layer's input, then into this layer's own slot
                torch.mul(o, tmp, out=buf.x_next[layer])
                buf.h[layer].copy_(buf.x_next[layer])
            else:
                torch.mul(o, tmp, out=buf.h[layer])

    def step(self, x: torch.Tensor, hs: list[torch.Tensor], cs: list[torch.Tensor],
             extra0: torch.Tensor | None = None) -> torch.Tensor:
        """One frame: input ``x (B, in)``, per-layer states ``hs``, ``cs`` (lists of ``(B, H)``, replaced in
        the lists); ``extra0 (B, 4H)`` (stack gate order) added to the first layer's gates. Returns the last
        layer's ``h``."""
        buf = self.buffers(x, hs, cs)
        self.step_(buf, extra0)
        hs[:], cs[:] = [h.clone() for h in buf.h], buf.c
        return hs[-1]


class _StackBuffers:
    """:meth:`LSTMStack.buffers`: ``xh[l] = [x_l | h_l] (B, in_l + H)``, views ``x`` (layer 0's input),
    ``h[l]`` (layer ``l``'s state inside ``xh[l]``) and ``x_next[l]`` (layer ``l + 1``'s input inside
    ``xh[l + 1]``, which is layer ``l``'s output), cells ``c[l] (B, H)``, the gates ``(B, 4H)`` with their
    views ``i, f, o, g`` and ``[i f o]``, scratch ``tmp (B, H)``."""

    def __init__(self, stack: LSTMStack, x: torch.Tensor, hs: list[torch.Tensor], cs: list[torch.Tensor]):
        B, H = x.shape[0], stack.hidden
        self.xh = [x.new_empty(B, n + H, dtype=torch.float32) for n in stack.inputs]
        self.x = self.xh[0][:, : stack.inputs[0]]
        self.x.copy_(x)
        self.h = [xh[:, n:] for xh, n in zip(self.xh, stack.inputs)]
        self.x_next = [xh[:, :H] for xh in self.xh[1:]]
        for layer, h in enumerate(hs):  # (x_next is written by each frame's lower layer before it is read)
            self.h[layer].copy_(h)
        self.c = [c.float().clone().contiguous() for c in cs]
        self.gates = x.new_empty(B, 4 * H, dtype=torch.float32)
        self.views = (*self.gates.split(H, dim=1), self.gates[:, : 3 * H])
        self.tmp = x.new_empty(B, H, dtype=torch.float32)


# --------------------------------------------------------------------------------------------------
# Dance Revolution


class FusedLSTMDecoder:
    """:meth:`RevolutionModel._autoregress` at a precision, one call per frame (see the module docstring).

    The frames run in :meth:`LSTMStack.step_`'s preallocated buffers, under ``torch.inference_mode`` (less
    bookkeeping per dispatch); the head is one ``addmm`` written straight into the next frame's input.
    """

    def __init__(self, model: nn.Module, precision: str):
        c = model.config
        self.config = c
        H, P = c.decoder_hidden, c.pose_dim
        self.stack = LSTMStack(model.decoder, precision, first_input=P)
        w_ih0 = model.decoder.weight_ih_l0.detach()
        # music term of layer 0 (applied per chunk), rows in the stack's gate order
        self.music0 = self.stack.order_rows(w_ih0[:, P:]).clone() if c.condition_on_music else None
        w = model.head.weight.detach()  # (P, H + d): ŷ = [h; z] W^S + b
        self.head_hT = w[:, :H].clone().T  # (H, P) view of a (P, H) matrix; small, on the feedback path: float32
        self.head_z, self.head_b = w[:, H:].clone(), model.head.bias.detach().clone()

    def __call__(self, z: torch.Tensor, prev: torch.Tensor, state):
        """``z (B, L, d)`` latents, ``prev (B, 1, P)``, ``state`` (h, c) each ``(layers, B, H)`` →
        ``(ŷ (B, L, P), last ŷ (B, 1, P), state)``, as :meth:`RevolutionModel._autoregress`."""
        B, L = z.shape[:2]
        if L == 0:
            return z.new_zeros(B, 0, self.config.pose_dim), prev, state
        with torch.inference_mode():
            z = z.float()
            head_z = torch.nn.functional.linear(z, self.head_z, self.head_b).unbind(1)  # L × (B, P), whole chunk
            music0 = None if self.music0 is None else torch.nn.functional.linear(z, self.music0).unbind(1)
            buf = self.stack.buffers(prev[:, 0].float(), list(state[0].float().unbind(0)),
                                     list(state[1].float().unbind(0)))
            out = z.new_empty(B, L, self.config.pose_dim)
            rows = out.unbind(1)
            for t in range(L):
                self.stack.step_(buf, None if music0 is None else music0[t])
                torch.addmm(head_z[t], buf.h[-1], self.head_hT, out=buf.x)  # ŷ_t (B, P): the next input
                rows[t].copy_(buf.x)
            h, c = torch.stack(buf.h), torch.stack(buf.c)
        out, h, c = out.clone(), h.clone(), c.clone()  # normal tensors again (not inference tensors)
        return out, out[:, -1:], (h, c)

    def step(self, y: torch.Tensor, hs: list[torch.Tensor], cs: list[torch.Tensor], head_z: torch.Tensor,
             music0: torch.Tensor | None) -> torch.Tensor:
        """One frame: previous pose ``y (B, P)`` → next pose ``(B, P)``; ``hs``, ``cs`` replaced in the lists."""
        h = self.stack.step(y, hs, cs, music0)
        return torch.addmm(head_z, h, self.head_hT)


# --------------------------------------------------------------------------------------------------
# Music2Dance


class FusedWaveNetStep:
    """:meth:`Music2DanceModel.step` at a precision (same arguments; ``weights`` is ignored)."""

    def __init__(self, model: nn.Module, precision: str):
        c = model.config
        self.config = c
        w = model._step_weights()
        self.inp = _Linear(w["in_w"].T, w["in_b"], precision)
        self.conv = [_Linear(cw.T, cb, precision) for cw, cb in zip(w["conv_w"], w["conv_b"])]
        self.res = [_Linear(rw.T, rb, precision) for rw, rb in zip(w["res_w"], w["res_b"])]
        self.skip = _Linear(w["skip_w"].T, w["skip_b"], precision)
        self.out1 = _Linear(model.out1.weight[:, :, 0], model.out1.bias, precision)
        self.out2 = _Linear(model.out2.weight[:, :, 0], model.out2.bias, precision)

    def __call__(self, cond_t: torch.Tensor, g: torch.Tensor, prev_t: torch.Tensor, state: list,
                 weights: dict | None = None) -> torch.Tensor:
        c = self.config
        C = c.channels
        x = self.inp(prev_t)  # (B, C)
        zs = []
        for i, d in enumerate(c.dilations):
            queue = state[i]  # inputs at t - (k-1)d, ..., t - 1
            taps = torch.cat([queue[j * d] for j in range(c.kernel - 1)] + [x], -1)  # (B, k·C)
            h = self.conv[i](taps) + cond_t[:, i]  # (B, 2C)
            queue.pop(0)
            queue.append(x)
            z = torch.tanh(h[:, :C]) * torch.sigmoid(h[:, C:])  # (B, C)
            zs.append(z)
            x = x + self.res[i](z)
        skips = self.skip(torch.cat(zs, -1))  # (B, S)
        return self.out2(torch.relu(self.out1(torch.relu(skips))))


class FusedLSTMStep:
    """The Music2Dance LSTM baseline's :meth:`Music2DanceModel.step` at a precision."""

    def __init__(self, model: nn.Module, precision: str):
        self.lstm_in = _Linear(model.lstm_in.weight, model.lstm_in.bias, precision)
        self.stack = LSTMStack(model.lstm, precision)
        self.head = _Linear(model.head.weight, model.head.bias, precision)
        self.layers, self.hidden = model.lstm.num_layers, model.lstm.hidden_size

    def __call__(self, cond_t: torch.Tensor, g: torch.Tensor, prev_t: torch.Tensor, state: list,
                 weights: dict | None = None) -> torch.Tensor:
        x = self.lstm_in(torch.cat([prev_t, cond_t, g], -1))
        if state[0] is None:
            zeros = x.new_zeros(x.shape[0], self.hidden)
            hs, cs = [zeros] * self.layers, [zeros] * self.layers
        else:
            hs, cs = list(state[0][0].unbind(0)), list(state[0][1].unbind(0))
        h = self.stack.step(x, hs, cs)
        state[0] = (torch.stack(hs), torch.stack(cs))
        return self.head(h)


# --------------------------------------------------------------------------------------------------
# dual


class _Bf16Seq2Seq(nn.Module):
    """A :class:`~dancekit.models.dual.Seq2Seq` run in bfloat16 behind float32 inputs and outputs."""

    def __init__(self, net: nn.Module):
        super().__init__()
        self.net = net.to(torch.bfloat16)
        self.out_dim = net.out_dim

    def generate(self, src: torch.Tensor, start: torch.Tensor, cond: torch.Tensor | None = None) -> torch.Tensor:
        cond = None if cond is None else cond.to(torch.bfloat16)  # G_M→D's projected latent (latent_dim > 0)
        return self.net.generate(src.to(torch.bfloat16), start.to(torch.bfloat16), cond).float()


# --------------------------------------------------------------------------------------------------


def _quantize_linears(module: nn.Module) -> nn.Module:
    """``quantize_dynamic`` of every ``nn.Linear`` in ``module`` (in place), quietly."""
    with warnings.catch_warnings():  # torch.ao.quantization warns that it moves to torchao
        warnings.simplefilter("ignore")
        from torch.ao.quantization import quantize_dynamic

        return quantize_dynamic(module, {nn.Linear}, dtype=torch.qint8, inplace=True)


def to_precision(model: nn.Module, precision: str = "fp32") -> nn.Module:
    """A model that generates at ``precision`` (``"fp32"``: ``model`` itself; otherwise an eval-mode copy,
    for inference only: do not train or save it).

    Supports the autoregressive families: ``revolution``, ``music2dance`` and ``dual`` (G_M→D).

    Raises
    ------
    ParameterError
        For an unknown precision, or a model family without reduced-precision decoding.
    """
    check_precision(precision)
    if precision == "fp32":
        return model
    family = getattr(model, "family", type(model).__name__)
    if family not in ("revolution", "music2dance", "dual"):
        raise ParameterError(f"precision {precision!r} is not available for {family!r} models (only fp32)")
    out = copy.deepcopy(model).eval()
    out.requires_grad_(False)
    if family == "revolution":
        out.fast_decoder = FusedLSTMDecoder(out, precision)
        if precision == "int8":
            _quantize_linears(out.encoder)
    elif family == "music2dance":
        fused = FusedWaveNetStep if out.config.generator == "wavenet" else FusedLSTMStep
        out.fast_step = fused(out, precision)
    else:  # dual: the dance generator G_M→D
        if precision == "int8":  # the decoder side (the encoder runs once per window; and torch's fast path
            # of nn.TransformerEncoderLayer cannot take quantised linears)
            for name in ("tgt_embed", "head", "decoder"):
                _quantize_linears(getattr(out.m2d, name))
        else:
            out.m2d = _Bf16Seq2Seq(out.m2d)
    out.precision = precision
    return out
