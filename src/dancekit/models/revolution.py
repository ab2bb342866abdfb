"""Dance Revolution (Huang et al., ICLR 2021): music encoder with local self-attention + LSTM dance decoder.

One file, one model: :class:`RevolutionConfig` (a dataclass that travels with the weights) and
:class:`RevolutionModel` (an ``nn.Module(config)``).

Architecture (paper §3.2)
    * Music encoder: linear embedding ``U = X W^E`` + positional encoding + ``n_layers`` transformer
      layers whose self-attention is *local*: frame ``i`` attends to frames ``|i - j| <= window // 2``
      (Eq. 1–2). It is computed block-wise (blocks of ``window // 2`` frames attend to their own and the
      two neighbouring blocks), so memory is O(n·k), never an n×n score matrix.
      Ablations of Table 3: ``encoder="global"`` (full self-attention, O(n²)), ``"lstm"`` (bidirectional
      LSTM) and ``"conv"`` (ConvS2S-style gated convolutions with residual connections).
    * Dance decoder: a multi-layer LSTM whose initial hidden and cell states are drawn from N(0, 1)
      with the caller's ``torch.Generator`` (same song, another seed → another dance), and
      ``ŷ_i = [h_i; z_i] W^S + b`` (Eq. 3). The LSTM input is the previous pose ``ŷ_{i-1}`` (Eq. 4),
      concatenated with ``z_i`` when ``condition_on_music`` (the default; with ``False`` the music enters
      only through the output layer, exactly as Eq. 3–4 are written). ``y_0`` is a learned
      begin-of-pose (``bop="learned"``) or zeros (``bop="zero"``). Inference steps the decoder in NumPy
      (:class:`NumpyDecoder`, the same maths; a frame is some 20 small operations, each about a microsecond in
      NumPy where a torch call costs several); training steps it in torch.
    * Dynamic auto-condition (§3.3): in training the decoder input alternates ``p`` generated frames and
      ``q`` ground-truth frames, ``Y_in = {y_0, ŷ_1..ŷ_p, y_{p+1}..y_{p+q}, ŷ_{p+q+1}, ...}``
      (:func:`auto_condition_mask`); ``p = 0`` is teacher forcing. Ground-truth runs go through
      ``nn.LSTM`` in one call, generated runs step by step. Loss: mean L1 (Eq. 5).

Positional encoding
    ``pos_encoding="relative"`` (default): a learned bias per head and relative offset
    ``clip(j - i, -window//2, window//2)`` added to the attention logits (as in the Music Transformer the
    paper builds on). The local encoder is then translation-equivariant, so a whole song encoded in
    overlapping chunks (:meth:`RevolutionModel.encode`) equals the song encoded in one go, and training
    windows and 10-minute songs see the same encoder. ``"sinusoidal"``: the absolute encoding of
    Vaswani et al., restarted at 0 in every chunk.

The LSTM baseline of the paper (Shlizerman et al. 2018, Table 2 "LSTM") is ``baseline=True``: an LSTM
music encoder (``encoder="lstm"`` is required) and the same LSTM decoder trained with plain teacher
forcing (the training objective ignores the curriculum for such a model).

The model is agnostic to the pose representation: ``pose_dim=72`` is ``positions3d`` of the tang2018
skeleton, ``pose_dim=50`` the ``keypoints2d`` BODY_25 setting. Inputs are normalised features
``(B, n, music_dim)`` at the dataset's fps (one feature frame per motion frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancekit.errors import ParameterError

ENCODERS = ("local", "global", "lstm", "conv")
POS_ENCODINGS = ("relative", "sinusoidal")


@dataclass
class RevolutionConfig:
    """Hyper-parameters of :class:`RevolutionModel` (saved as ``config.json`` with the weights).

    The defaults are sized to train on the tang2018 training split on 2 CPU cores in well under an
    hour (0.45 s a step of 16 windows on 2 cores: ``benchmarks/bench_train.py``); the paper's own sizes are ``d_model=256,
    n_heads=8, d_ff=1024, window=100, decoder_layers=3, decoder_hidden=1024``.
    """

    music_dim: int = 438  # D, acoustic features per frame (the `revolution` preset)
    pose_dim: int = 72  # P, 72 = positions3d of tang2018 (23 joints), 50 = keypoints2d BODY_25
    d_model: int = 128  # d_z, width of the music encoder
    n_layers: int = 2  # encoder layers
    n_heads: int = 4
    d_ff: int = 512  # hidden units of the position-wise feed-forward sublayer
    window: int = 100  # k: frame i attends to |i - j| <= k // 2 (frames at the dataset fps; ±2 s at 25 fps)
    lookahead: int | None = None  # local encoder: frames after frame i that it attends to (None: k // 2, symmetric)
    dropout: float = 0.1
    encoder: str = "local"  # local | global | lstm | conv (Table 3)
    pos_encoding: str = "relative"  # relative | sinusoidal
    conv_kernel: int = 5  # kernel of the "conv" encoder
    decoder_layers: int = 2
    decoder_hidden: int = 256  # d_s
    condition_on_music: bool = True  # feed z_i to the decoder LSTM as well as to its output layer
    bop: str = "learned"  # begin-of-pose y_0: learned | zero
    baseline: bool = False  # the paper's LSTM baseline (encoder="lstm", teacher forcing)
    encoder_chunk: int = 1024  # frames per encoder chunk in `generate` (bounds memory on long songs)
    n_genres: int = 0  # > 0: a learned dance-genre embedding added to the music latents (index n_genres = "auto")
    style_dim: int = 0  # > 0: a learned latent per segment (CVAE), sampled per seed at inference (issue 15)
    style_segment: int = 75  # frames per style-latent segment (3 s at 25 fps)
    style_beta: float = 0.02  # weight of the KL term (mean nats per latent dimension) in the training loss
    style_free_bits: float = 0.1  # KL per dimension below this many nats is not penalised (keeps the latent used)
    # livelier motion (issue 15): L1 terms on the frame-to-frame differences of the normalised poses
    velocity_weight: float = 0.0  # x mean |Δŷ − Δy| (each frame's velocity against the target's)
    speed_weight: float = 0.0  # x mean over windows and coordinates of |mean_t |Δŷ| − mean_t |Δy||
    kinetic_weight: float = 0.0  # x mean over windows and coordinates of |rms_t Δŷ − rms_t Δy|

    def __post_init__(self) -> None:
        if not isinstance(self.n_genres, int) or self.n_genres < 0:
            raise ParameterError(f"RevolutionConfig.n_genres must be a non-negative integer, got {self.n_genres!r}")
        for name in ("music_dim", "pose_dim", "d_model", "n_layers", "n_heads", "d_ff", "decoder_layers",
                     "decoder_hidden", "conv_kernel", "encoder_chunk"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ParameterError(f"RevolutionConfig.{name} must be a positive integer, got {value!r}")
        if not isinstance(self.style_dim, int) or isinstance(self.style_dim, bool) or self.style_dim < 0:
            raise ParameterError(f"RevolutionConfig.style_dim must be a non-negative integer, got {self.style_dim!r}")
        if not isinstance(self.style_segment, int) or isinstance(self.style_segment, bool) or self.style_segment < 2:
            raise ParameterError(f"RevolutionConfig.style_segment must be an integer >= 2, got {self.style_segment!r}")
        if not self.velocity_weight >= 0 or not self.speed_weight >= 0 or not self.kinetic_weight >= 0:
            raise ParameterError("RevolutionConfig.velocity_weight, speed_weight and kinetic_weight must be >= 0, "
                                 f"got {self.velocity_weight!r}, {self.speed_weight!r}, {self.kinetic_weight!r}")
        if not self.style_beta >= 0 or not self.style_free_bits >= 0:
            raise ParameterError("RevolutionConfig.style_beta and style_free_bits must be >= 0, got "
                                 f"{self.style_beta!r}, {self.style_free_bits!r}")
        if not isinstance(self.window, int) or self.window < 0:
            raise ParameterError(f"RevolutionConfig.window must be a non-negative integer, got {self.window!r}")
        if self.lookahead is not None:
            if isinstance(self.lookahead, bool) or not isinstance(self.lookahead, int) \
                    or not 0 <= self.lookahead <= self.window // 2:
                raise ParameterError(f"RevolutionConfig.lookahead must be None or an integer in [0, window // 2 = "
                                     f"{self.window // 2}], got {self.lookahead!r}")
            if self.encoder != "local":
                raise ParameterError(f"RevolutionConfig.lookahead is for the local encoder, not {self.encoder!r}")
        if self.encoder not in ENCODERS:
            raise ParameterError(f"RevolutionConfig.encoder must be one of {ENCODERS}, got {self.encoder!r}")
        if self.pos_encoding not in POS_ENCODINGS:
            raise ParameterError(
                f"RevolutionConfig.pos_encoding must be one of {POS_ENCODINGS}, got {self.pos_encoding!r}"
            )
        if self.bop not in ("learned", "zero"):
            raise ParameterError(f"RevolutionConfig.bop must be 'learned' or 'zero', got {self.bop!r}")
        if self.d_model % self.n_heads:
            raise ParameterError(
                f"RevolutionConfig.d_model ({self.d_model}) must be divisible by n_heads ({self.n_heads})"
            )
        if self.encoder == "lstm" and self.d_model % 2:
            raise ParameterError(f"the lstm encoder needs an even d_model, got {self.d_model}")
        if not 0.0 <= self.dropout < 1.0:
            raise ParameterError(f"RevolutionConfig.dropout must be in [0, 1), got {self.dropout!r}")
        if self.baseline and self.encoder != "lstm":
            raise ParameterError(
                f"baseline=True is the paper's LSTM baseline and needs encoder='lstm', got {self.encoder!r}"
            )

    @property
    def half_window(self) -> int:
        """``k // 2``: the attention reaches this many frames back (and ahead, unless ``lookahead`` is set)."""
        return self.window // 2

    @property
    def ahead(self) -> int:
        """Frames ahead that a local attention layer reaches: ``lookahead``, else ``k // 2``."""
        return self.window // 2 if self.lookahead is None else self.lookahead

    @classmethod
    def lstm_baseline(cls, **overrides) -> RevolutionConfig:
        """The paper's LSTM baseline: LSTM encoder + LSTM decoder, trained with teacher forcing."""
        return cls(**{"encoder": "lstm", "baseline": True, **overrides})


@dataclass(frozen=True)
class SeedVariety:
    """How the seed keeps changing the dance after its opening (inference only; issue 15).

    Without it the seed only draws the decoder's initial LSTM state, and the dances of one song converge
    to nearly the same motion after a few seconds. With it, every ``phrase`` frames (a musical phrase,
    ~2–4 s) the seed's generator perturbs the decoding:

    * ``state_noise`` a ∈ [0, 1]: at each phrase boundary the decoder state is mixed with fresh noise,
      ``h ← √(1 − a²)·h + a·ε`` (and the same for the cell state; ε ~ N(0, 1), the distribution of the
      initial state). a = 1 re-draws the state as at the start of the song.
    * ``latent_noise`` σ ≥ 0: an offset ``σ·s·u(t)`` is added to the music latents z_t, where u(t) is
      linearly interpolated between N(0, I) knots at the phrase boundaries (a smooth random path that
      changes the dance's character from phrase to phrase without jumps) and ``s`` is the spread (std over
      the song's frames) of z per dimension: the latents of a trained encoder move little over a song
      (median std 0.06 against values of ±0.4), and unscaled offsets freeze the dance.
    * ``dance_latent`` τ ≥ 0: one more offset ``τ·s·v`` (v ~ N(0, I), one per dance) added to every z_t:
      a character that holds through the whole dance (with any ``phrase``, 0 included).

    * ``style`` t ≥ 0 (models with ``style_dim > 0`` only): the learned per-segment latent w is drawn from
      its prior at temperature t, one knot per ``style_segment`` frames, linearly interpolated as in
      training; ``style_share`` ρ ∈ [0, 1] of its variance is one draw per dance (the knots are
      ``t·(√ρ·v + √(1 − ρ)·e_s)``): a character that holds through the dance. With ``style`` 0 the
      latent is 0 (the prior's mean).

    All draws come after the initial state's from the same generator(s), for the whole song at once, so a
    seed still fully determines the dance (independent of the encoder chunking). ``SeedVariety()`` (all
    zero) is the paper's decoding: no draw beyond the initial state.
    """

    phrase: int = 0  # frames between perturbations (0: off)
    state_noise: float = 0.0
    latent_noise: float = 0.0
    dance_latent: float = 0.0
    style: float = 0.0
    style_share: float = 0.0

    def __post_init__(self) -> None:
        if not self.style >= 0.0:
            raise ParameterError(f"SeedVariety.style must be >= 0, got {self.style!r}")
        if not 0.0 <= self.style_share <= 1.0:
            raise ParameterError(f"SeedVariety.style_share must be in [0, 1], got {self.style_share!r}")
        if not isinstance(self.phrase, int) or isinstance(self.phrase, bool) or self.phrase < 0:
            raise ParameterError(f"SeedVariety.phrase must be a non-negative integer (frames), got {self.phrase!r}")
        if not 0.0 <= self.state_noise <= 1.0:
            raise ParameterError(f"SeedVariety.state_noise must be in [0, 1], got {self.state_noise!r}")
        if not self.latent_noise >= 0.0:
            raise ParameterError(f"SeedVariety.latent_noise must be >= 0, got {self.latent_noise!r}")
        if not self.dance_latent >= 0.0:
            raise ParameterError(f"SeedVariety.dance_latent must be >= 0, got {self.dance_latent!r}")

    @property
    def active(self) -> bool:
        return (self.phrase > 0 and (self.state_noise > 0 or self.latent_noise > 0) or self.dance_latent > 0
                or self.style > 0)


def _randn(shape: tuple[int, ...], generators: list[torch.Generator | None], axis: int) -> torch.Tensor:
    """N(0, 1) of ``shape`` whose slices along ``axis`` (the batch) come from one generator each (CPU)."""
    if len(generators) == 1:
        g = generators[0]
        return torch.randn(shape, generator=g, device=g.device if g is not None else "cpu")
    one = shape[:axis] + (1,) + shape[axis + 1 :]
    return torch.cat([torch.randn(one, generator=g, device=g.device if g is not None else "cpu")
                      for g in generators], dim=axis)


# --------------------------------------------------------------------------------------------------
# curriculum: which decoder inputs are ground truth


def auto_condition_mask(length: int, *, p: int, q: int) -> torch.Tensor:
    """Which decoder inputs are ground truth under the dynamic auto-condition (paper §3.3).

    The decoder input for target frame ``t`` (0-based) is the begin-of-pose ``y_0`` at ``t = 0`` and
    the previous frame otherwise, ground truth ``y_{t-1}`` or generated ``ŷ_{t-1}``. Inputs
    alternate ``p`` generated then ``q`` ground-truth frames after the begin-of-pose::

        Y_in = {y_0, ŷ_1, ..., ŷ_p, y_{p+1}, ..., y_{p+q}, ŷ_{p+q+1}, ...}

    Parameters
    ----------
    length : number of decoder steps n
    p : generated frames per period; 0 is teacher forcing
    q : ground-truth frames per period; 0 (with p > 0) is fully autoregressive

    Returns
    -------
    mask : (n,) bool tensor, True where the input is given (begin-of-pose or ground truth)

    Examples
    --------
    >>> auto_condition_mask(8, p=2, q=3).int().tolist()
    [1, 0, 0, 1, 1, 1, 0, 0]
    """
    if length < 0 or p < 0 or q < 0:
        raise ParameterError(f"length, p and q must be non-negative, got length={length}, p={p}, q={q}")
    t = torch.arange(length)
    if p == 0:
        mask = torch.ones(length, dtype=torch.bool)
    elif q == 0:
        mask = torch.zeros(length, dtype=torch.bool)
    else:
        mask = ((t - 1) % (p + q)) >= p
    if length:
        mask[0] = True  # y_0, the begin-of-pose
    return mask


def _runs(mask: torch.Tensor) -> list[tuple[int, int, bool]]:
    """Maximal runs ``(start, end, value)`` of a 1-D bool mask."""
    values = mask.tolist()
    runs, start = [], 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            runs.append((start, i, values[start]))
            start = i
    return runs


# --------------------------------------------------------------------------------------------------
# attention


def _relative_bias(bias: torch.Tensor, offsets: torch.Tensor, half: int) -> torch.Tensor:
    """Gather ``bias (H, 2h+1)`` at clipped relative ``offsets (...)`` → ``(H, ...)``."""
    return bias[:, offsets.clamp(-half, half) + half]


def local_attention(
    q: torch.Tensor,
    k: torch.Tensor,
    v: torch.Tensor,
    *,
    half_window: int,
    bias: torch.Tensor | None = None,
    dropout: float = 0.0,
    training: bool = False,
    q_offset: int = 0,
    ahead: int | None = None,
) -> torch.Tensor:
    """Banded scaled dot-product attention: query ``i`` attends to keys ``-half_window <= j - i <= ahead``
    (``ahead`` None: ``half_window``, the symmetric band).

    Computed in blocks of ``w = max(half_window, 1)`` frames: each query block scores the keys of its
    own block and of its two neighbours, so the score tensor is ``(B, H, n/w, w, 3w)`` — O(n·k)
    memory, never n×n.

    Parameters
    ----------
    q : (B, H, n, d) tensor, query ``i`` at frame ``q_offset + i`` of the keys
    k, v : (B, H, m, d) tensors, key ``j`` at frame ``j`` (``m = n`` and ``q_offset = 0``: self-attention over
        one sequence); the keys are the whole sequence there is: a query near either end sees fewer of them
    half_window : h = k // 2
    bias : optional (H, 2h + 1) learned bias per head and relative offset ``j - i``
    q_offset : frame of the first query among the keys (≥ 0)
    ahead : keys after a query that it sees (0 … ``half_window``; None: ``half_window``)

    Returns
    -------
    (B, H, n, d) tensor, equal to full attention with the band mask applied.
    """
    B, H, n, d = q.shape
    h = int(half_window)
    ahead = h if ahead is None else int(ahead)
    if not 0 <= ahead <= h:
        raise ParameterError(f"ahead must be in [0, half_window = {h}], got {ahead}")
    w = max(h, 1)
    if q_offset < 0:
        raise ParameterError(f"q_offset must be >= 0, got {q_offset}")
    if q_offset > h:  # keys before the first query's band are never looked at
        k, v = k[:, :, q_offset - h :], v[:, :, q_offset - h :]
        q_offset = h
    m = min(k.shape[2], q_offset + n + ahead)  # nor are keys after the last query's band
    k, v = k[:, :, :m], v[:, :, :m]
    nb = -(-n // w)  # number of blocks
    pad = nb * w - n
    left = w - q_offset  # the keys padded so that query block b's neighbourhood is key blocks b … b + 2
    right = (nb + 1) * w + q_offset - m
    qb = F.pad(q, (0, 0, 0, pad)).view(B, H, nb, w, d)  # (B, H, nb, w, d)
    kp = F.pad(k, (0, 0, left, right)).view(B, H, nb + 2, w, d)
    vp = F.pad(v, (0, 0, left, right)).view(B, H, nb + 2, w, d)
    kb = torch.cat([kp[:, :, :-2], kp[:, :, 1:-1], kp[:, :, 2:]], dim=3)  # (B, H, nb, 3w, d)
    vb = torch.cat([vp[:, :, :-2], vp[:, :, 1:-1], vp[:, :, 2:]], dim=3)  # (B, H, nb, 3w, d)
    scores = torch.einsum("bhnqd,bhnkd->bhnqk", qb, kb) / math.sqrt(d)  # (B, H, nb, w, 3w)

    dev = q.device
    offsets = torch.arange(3 * w, device=dev)[None, :] - w - torch.arange(w, device=dev)[:, None]  # (w, 3w)
    key_pos = torch.arange(nb, device=dev)[:, None] * w - left + torch.arange(3 * w, device=dev)[None, :]  # (nb, 3w)
    query_pos = torch.arange(nb, device=dev)[:, None] * w + torch.arange(w, device=dev)[None, :]  # (nb, w)
    key_ok = (key_pos >= 0) & (key_pos < m)
    # padded queries (beyond n) may look at padded keys so that no row is empty (their output is dropped)
    band = (offsets >= -h) & (offsets <= ahead)
    allowed = band[None] & (key_ok[:, None, :] | (query_pos >= n)[:, :, None])  # (nb, w, 3w)
    if bias is not None:
        scores = scores + _relative_bias(bias, offsets, h)[:, None]  # (H, 1, w, 3w) broadcast
    scores = scores.masked_fill(~allowed, float("-inf"))
    attn = torch.softmax(scores, dim=-1)
    if dropout and training:
        attn = F.dropout(attn, p=dropout)
    out = torch.einsum("bhnqk,bhnkd->bhnqd", attn, vb)  # (B, H, nb, w, d)
    return out.reshape(B, H, nb * w, d)[:, :, :n]


def band_attention(
    q: torch.Tensor,
    k: torch.Tensor,
    v: torch.Tensor,
    *,
    half_window: int,
    bias: torch.Tensor | None = None,
    dropout: float = 0.0,
    training: bool = False,
    q_offset: int = 0,
    ahead: int | None = None,
) -> torch.Tensor:
    """:func:`local_attention` with one ``(B, H, n, m)`` score matrix: fewer operations for a few queries
    (O(n·m) memory). Shapes and arguments as :func:`local_attention`."""
    n, m, d = q.shape[2], k.shape[2], q.shape[3]
    h = int(half_window)
    ahead = h if ahead is None else int(ahead)
    offsets = torch.arange(m, device=q.device)[None, :] - torch.arange(q_offset, q_offset + n, device=q.device)[:, None]
    scores = q @ k.transpose(-1, -2) / math.sqrt(d)  # (B, H, n, m)
    if bias is not None:
        scores = scores + _relative_bias(bias, offsets, h)  # (H, n, m) broadcast
    scores = scores.masked_fill((offsets < -h) | (offsets > ahead), float("-inf"))
    attn = torch.softmax(scores, dim=-1)
    if dropout and training:
        attn = F.dropout(attn, p=dropout)
    return attn @ v  # (B, H, n, d)


def global_attention(
    q: torch.Tensor,
    k: torch.Tensor,
    v: torch.Tensor,
    *,
    half_window: int,
    bias: torch.Tensor | None = None,
    mask: torch.Tensor | None = None,
    dropout: float = 0.0,
    training: bool = False,
) -> torch.Tensor:
    """Full scaled dot-product attention with an (n, n) score matrix (O(n²) memory).

    ``bias (H, 2h+1)`` is indexed at ``clip(j - i, -h, h)``; ``mask (n, n)`` (True = allowed) is optional
    (a band mask makes it the reference for :func:`local_attention`). Shapes as :func:`local_attention`.
    """
    n, d = q.shape[-2], q.shape[-1]
    scores = q @ k.transpose(-1, -2) / math.sqrt(d)  # (B, H, n, n)
    if bias is not None:
        idx = torch.arange(n, device=q.device)
        scores = scores + _relative_bias(bias, idx[None, :] - idx[:, None], half_window)  # (H, n, n)
    if mask is not None:
        scores = scores.masked_fill(~mask, float("-inf"))
    attn = torch.softmax(scores, dim=-1)
    if dropout and training:
        attn = F.dropout(attn, p=dropout)
    return attn @ v


def band_mask(n: int, half_window: int, *, device: torch.device | str | None = None) -> torch.Tensor:
    """(n, n) bool mask, True where ``|i - j| <= half_window``."""
    idx = torch.arange(n, device=device)
    return (idx[None, :] - idx[:, None]).abs() <= half_window


def sinusoidal_encoding(n: int, d: int, *, device: torch.device | str | None = None) -> torch.Tensor:
    """Vaswani et al.'s positional encoding for positions ``0..n-1`` → (n, d) float32."""
    pos = torch.arange(n, dtype=torch.float32, device=device)[:, None]
    div = torch.exp(torch.arange(0, d, 2, dtype=torch.float32, device=device) * (-math.log(10000.0) / d))
    pe = torch.zeros(n, d, device=device)
    pe[:, 0::2] = torch.sin(pos * div)
    pe[:, 1::2] = torch.cos(pos * div)[:, : d // 2]
    return pe


class SelfAttention(nn.Module):
    """Multi-head self-attention, local (banded, O(n·k)) or global (O(n²))."""

    def __init__(self, config: RevolutionConfig, *, local: bool):
        super().__init__()
        self.local = local
        self.n_heads = config.n_heads
        self.half = config.half_window
        self.ahead = config.ahead
        self.dropout = config.dropout
        self.qkv = nn.Linear(config.d_model, 3 * config.d_model)
        self.proj = nn.Linear(config.d_model, config.d_model)
        self.rel_bias = (
            nn.Parameter(torch.zeros(config.n_heads, 2 * self.half + 1)) if config.pos_encoding == "relative" else None
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        B, n, d = x.shape
        q, k, v = self.qkv(x).view(B, n, 3, self.n_heads, d // self.n_heads).permute(2, 0, 3, 1, 4)  # (B, H, n, dh)
        if self.local:
            y = local_attention(q, k, v, half_window=self.half, bias=self.rel_bias, dropout=self.dropout,
                                training=self.training, ahead=self.ahead)
        else:
            y = global_attention(q, k, v, half_window=self.half, bias=self.rel_bias, dropout=self.dropout,
                                 training=self.training)
        return self.proj(y.transpose(1, 2).reshape(B, n, d))  # (B, n, d)

    def forward_range(self, x: torch.Tensor, start: int, stop: int, *, qkv: torch.Tensor | None = None) -> torch.Tensor:
        """The outputs ``(B, stop - start, d)`` of frames ``[start, stop)`` of :meth:`forward` on ``x (B, n, d)``
        (local attention only): the queries of those frames alone, the keys and values of the frames within
        ``half_window`` of them. ``qkv``: ``self.qkv(x)`` ``(B, n, 3d)`` already computed (a live stream keeps each
        frame's projections: :meth:`MusicEncoder.forward_range`'s ``qkv0``)."""
        if not self.local:
            raise ParameterError("forward_range needs the local (banded) attention")
        B, n, d = x.shape
        h, H = self.half, self.n_heads
        a, b = max(0, start - h), min(n, stop + self.ahead)  # the keys looked at
        if qkv is not None:
            q = qkv[:, start:stop, :d].reshape(B, stop - start, H, d // H).transpose(1, 2)
            kv = qkv[:, a:b, d:]
        elif type(self.qkv) is nn.Linear:  # the queries of [start, stop) alone
            W, c = self.qkv.weight, self.qkv.bias
            q = F.linear(x[:, start:stop], W[:d], c[:d]).view(B, stop - start, H, d // H).transpose(1, 2)
            kv = F.linear(x[:, a:b], W[d:], c[d:])  # (B, m, 2d)
        else:  # a quantised copy (dancekit.models.precision): its projection of every key frame
            qkv = self.qkv(x[:, a:b])  # (B, m, 3d)
            q = qkv[:, start - a : stop - a, :d].reshape(B, stop - start, H, d // H).transpose(1, 2)
            kv = qkv[:, :, d:]
        k, v = kv.reshape(B, b - a, 2, H, d // H).permute(2, 0, 3, 1, 4)  # (B, H, m, dh) each
        fn = band_attention if stop - start <= 4 * max(h, 1) else local_attention  # few queries: one score matrix
        y = fn(q, k, v, half_window=h, bias=self.rel_bias, dropout=self.dropout, training=self.training,
               q_offset=start - a, ahead=self.ahead)
        return self.proj(y.transpose(1, 2).reshape(B, stop - start, d))  # (B, stop - start, d)


class TransformerLayer(nn.Module):
    """Pre-norm transformer layer: self-attention sublayer + position-wise feed-forward sublayer."""

    def __init__(self, config: RevolutionConfig, *, local: bool):
        super().__init__()
        self.ln1 = nn.LayerNorm(config.d_model)
        self.attn = SelfAttention(config, local=local)
        self.ln2 = nn.LayerNorm(config.d_model)
        self.ff = nn.Sequential(
            nn.Linear(config.d_model, config.d_ff), nn.GELU(), nn.Linear(config.d_ff, config.d_model)
        )
        self.drop = nn.Dropout(config.dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x + self.drop(self.attn(self.ln1(x)))  # (B, n, d)
        return x + self.drop(self.ff(self.ln2(x)))

    def forward_range(self, x: torch.Tensor, start: int, stop: int, *, qkv: torch.Tensor | None = None) -> torch.Tensor:
        """Frames ``[start, stop)`` of :meth:`forward` on ``x (B, n, d)`` → ``(B, stop - start, d)`` (local
        attention; ``x`` need only hold the frames within ``half_window`` of them, the sequence's ends aside).
        ``qkv``: :meth:`projections` of ``x`` ``(B, n, 3d)``, already computed."""
        attended = self.attn.forward_range(x if qkv is not None else self.ln1(x), start, stop, qkv=qkv)
        y = x[:, start:stop] + self.drop(attended)
        return y + self.drop(self.ff(self.ln2(y)))


    def projections(self, x: torch.Tensor) -> torch.Tensor:
        """The attention's queries, keys and values ``(B, n, 3d)`` of the frames ``x (B, n, d)`` (each frame's
        own: a stream computes them once per frame)."""
        return self.attn.qkv(self.ln1(x))


class GatedConvLayer(nn.Module):
    """ConvS2S encoder block: Conv1d to 2d channels → GLU → residual, scaled by sqrt(1/2)."""

    def __init__(self, config: RevolutionConfig):
        super().__init__()
        self.conv = nn.Conv1d(config.d_model, 2 * config.d_model, config.conv_kernel, padding=config.conv_kernel // 2)
        self.drop = nn.Dropout(config.dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = F.glu(self.conv(self.drop(x).transpose(1, 2)), dim=1).transpose(1, 2)  # (B, n, d)
        return (x + y[:, : x.shape[1]]) * math.sqrt(0.5)


class MusicEncoder(nn.Module):
    """Music features (B, n, D) → latent sequence Z (B, n, d_model)."""

    def __init__(self, config: RevolutionConfig):
        super().__init__()
        self.config = config
        self.embed = nn.Linear(config.music_dim, config.d_model)  # W^E
        self.drop = nn.Dropout(config.dropout)
        kind = config.encoder
        if kind in ("local", "global"):
            self.layers = nn.ModuleList(
                TransformerLayer(config, local=kind == "local") for _ in range(config.n_layers)
            )
            self.norm = nn.LayerNorm(config.d_model)
        elif kind == "conv":
            self.layers = nn.ModuleList(GatedConvLayer(config) for _ in range(config.n_layers))
            self.norm = nn.LayerNorm(config.d_model)
        else:  # lstm
            self.lstm = nn.LSTM(
                config.d_model, config.d_model // 2, num_layers=config.n_layers, batch_first=True,
                bidirectional=True, dropout=config.dropout if config.n_layers > 1 else 0.0,
            )

    @property
    def receptive_field(self) -> int | None:
        """Frames on each side that influence an output frame (None: the whole sequence)."""
        c = self.config
        if c.encoder == "local":
            return c.n_layers * c.half_window
        if c.encoder == "conv":
            return c.n_layers * (c.conv_kernel // 2)
        return None

    @property
    def bounded_lookahead(self) -> int | None:
        """Frames after a frame that its latent depends on, where the encoder itself bounds them (the local
        encoder with ``lookahead`` set: ``n_layers · lookahead``); None otherwise (the sequence's end decides)."""
        c = self.config
        return c.n_layers * c.ahead if c.encoder == "local" and c.lookahead is not None else None

    def forward(self, music: torch.Tensor) -> torch.Tensor:
        x = self.embed(music)  # (B, n, d)
        if self.config.pos_encoding == "sinusoidal" and self.config.encoder in ("local", "global"):
            x = x + sinusoidal_encoding(x.shape[1], x.shape[2], device=x.device)
        x = self.drop(x)
        if self.config.encoder == "lstm":
            return self.lstm(x)[0]  # (B, n, d)
        for layer in self.layers:
            x = layer(x)
        return self.norm(x)  # (B, n, d)

    def forward_range(self, music: torch.Tensor, start: int, stop: int, *, embedded: bool = False,
                      qkv0: torch.Tensor | None = None) -> torch.Tensor:
        """``forward(music)[:, start:stop]`` — music features ``(B, n, D)`` → latents ``(B, stop - start, d)`` —
        computed on what those frames see alone: for the local encoder the last layer's queries at
        ``[start, stop)``, each layer below over ``half_window`` frames more on each side (clipped to
        ``[0, n)``: the sequence's ends are its ends, as in :meth:`forward`), the embedding over
        ``n_layers · half_window`` more; the other encoders run :meth:`forward` and keep those frames.
        ``embedded``: ``music`` is already ``embed(music)`` ``(B, n, d)`` (the local encoder only). ``qkv0``: with
        ``embedded`` and relative positions, the first layer's :meth:`TransformerLayer.projections` of those rows
        ``(B, n, 3d)``, already computed (a live stream keeps each frame's: they do not change as the music comes)."""
        n = music.shape[1]
        start, stop = max(0, int(start)), min(n, int(stop))
        c = self.config
        if embedded and c.encoder != "local":
            raise ParameterError(f"embedded frames are for the local encoder, not {c.encoder!r}")
        if qkv0 is not None and (not embedded or c.pos_encoding != "relative" or qkv0.shape[:2] != music.shape[:2]):
            raise ParameterError("qkv0 needs embedded frames, relative positions and one row per frame of music")
        if c.encoder != "local" or stop <= start:
            return self.forward(music)[:, start:stop]
        h, ah, L = c.half_window, c.ahead, len(self.layers)
        lo, hi = max(0, start - L * h), min(n, stop + L * ah)  # the frames embedded
        x = music[:, lo:hi] if embedded else self.embed(music[:, lo:hi])  # (B, hi - lo, d)
        if c.pos_encoding == "sinusoidal":
            x = x + sinusoidal_encoding(hi, x.shape[2], device=x.device)[lo:]
        x = self.drop(x)
        for i, layer in enumerate(self.layers):
            r = L - 1 - i  # the frames this layer's outputs are needed at: [start - r·h, stop + r·ahead)
            a, b = max(0, start - r * h), min(n, stop + r * ah)
            qkv = qkv0[:, lo:hi] if i == 0 and qkv0 is not None else None
            x = layer.forward_range(x, a - lo, b - lo, qkv=qkv)  # (B, b - a, d)
            lo = a
        return self.norm(x)  # (B, stop - start, d)


class StreamingEncoder:
    """The latents of a local encoder with a bounded lookahead (``lookahead`` set), computed as the music comes.

    Layer ``i``'s output at frame ``s`` depends on layer ``i - 1``'s outputs at ``[s - h, s + a]`` (``h`` the half
    window, ``a`` the lookahead): it is final once those have come, and is computed once and kept (the last ``h``
    frames of each layer, what later frames still need). :meth:`push` takes the embedded rows
    (``encoder.embed(music)``, ``(1, k, d)``) and returns the latents ``(1, m, d)`` of the frames that became
    final: frame ``s`` once the music up to ``s + n_layers · a`` has come. They equal
    :meth:`MusicEncoder.forward` of the whole stream at those frames (``tests/models/test_revolution.py``); the
    last ``n_layers · a`` frames of a stream that ends see its end as a song's end: ``forward_range`` gives them.
    """

    def __init__(self, encoder: MusicEncoder):
        c = encoder.config
        if encoder.bounded_lookahead is None or c.pos_encoding != "relative":
            raise ParameterError("a streaming encoder needs the local encoder with a lookahead and relative positions")
        self.encoder, self.h, self.a = encoder, c.half_window, c.ahead
        L = len(encoder.layers)
        # per level (0: the embedded input, i: layer i's output): kept frames and the frame of the first one
        self.levels: list[torch.Tensor] = [torch.zeros(1, 0, c.d_model) for _ in range(L + 1)]
        self.first = [0] * (L + 1)
        self.done = 0  # latents given out so far

    @property
    def latency(self) -> int:
        """Frames of music after a frame that its latent waits for (``n_layers · lookahead``)."""
        return self.encoder.bounded_lookahead

    def end(self, level: int) -> int:
        return self.first[level] + self.levels[level].shape[1]

    @torch.no_grad()
    def push(self, embedded: torch.Tensor) -> torch.Tensor:
        self.levels[0] = torch.cat([self.levels[0], embedded], dim=1)
        for i, layer in enumerate(self.encoder.layers, start=1):
            below, b0 = self.levels[i - 1], self.first[i - 1]
            start, stop = self.end(i), self.end(i - 1) - self.a  # the outputs whose inputs have all come
            if stop > start:
                lo = max(b0, start - self.h)  # frames before b0 were never there (the stream's start) or not needed
                new = layer.forward_range(below[:, lo - b0 : stop + self.a - b0], start - lo, stop - lo)
                self.levels[i] = torch.cat([self.levels[i], new], dim=1)
            keep = max(self.first[i - 1], self.end(i) - self.h)  # what layer i's next outputs may still read
            cut = keep - self.first[i - 1]
            if cut > 0:
                self.levels[i - 1] = self.levels[i - 1][:, cut:]
                self.first[i - 1] = keep
        top = len(self.encoder.layers)
        out = self.encoder.norm(self.levels[top][:, self.done - self.first[top] :])
        self.done = self.end(top)
        cut = max(0, self.levels[top].shape[1] - self.h)
        self.levels[top], self.first[top] = self.levels[top][:, cut:], self.first[top] + cut
        return out  # (1, m, d)


# --------------------------------------------------------------------------------------------------
# the model


class RevolutionModel(nn.Module):
    """Dance Revolution: normalised music features (B, n, D) → normalised poses (B, n, P).

    Examples
    --------
    >>> model = RevolutionModel(RevolutionConfig(music_dim=8, pose_dim=6, d_model=16, n_heads=2, d_ff=32,
    ...                                          decoder_hidden=32))
    >>> music, dance = torch.randn(2, 40, 8), torch.randn(2, 40, 6)
    >>> pred, loss = model(music, dance, schedule_p=4, schedule_q=4)
    >>> pred.shape
    torch.Size([2, 40, 6])
    >>> model.generate(music[:1], generator=torch.Generator().manual_seed(0)).shape
    torch.Size([1, 40, 6])
    """

    family: ClassVar[str] = "revolution"

    def __init__(self, config: RevolutionConfig):
        super().__init__()
        self.config = config
        c = config
        self.encoder = MusicEncoder(c)
        dec_in = c.pose_dim + (c.d_model if c.condition_on_music else 0)
        self.decoder = nn.LSTM(dec_in, c.decoder_hidden, num_layers=c.decoder_layers, batch_first=True)
        self.head = nn.Linear(c.decoder_hidden + c.d_model, c.pose_dim)  # W^S, b
        self.bop = nn.Parameter(torch.zeros(c.pose_dim), requires_grad=c.bop == "learned")  # y_0
        if c.n_genres:
            # dance-genre condition (an extension, not in the paper): one vector per genre plus "auto"
            # (index n_genres, the music decides), added to every latent z_i. Zero-initialised, so a
            # model fine-tuned with it starts out as the unconditioned model.
            self.genre_embedding = nn.Embedding(c.n_genres + 1, c.d_model)
            nn.init.zeros_(self.genre_embedding.weight)
        if c.style_dim:
            # a CVAE-style latent per segment of style_segment frames (an extension, issue 15): the posterior
            # reads the target dance of a segment (training), the prior is N(0, I) (inference, drawn per seed);
            # w(t), interpolated between the segments' centres, is projected and added to every z_t.
            # The projection is zero-initialised, so a model fine-tuned with it starts out as the model without.
            self.style_posterior = nn.Sequential(nn.Linear(c.pose_dim, 128), nn.GELU())
            self.style_stats = nn.Linear(128, 2 * c.style_dim)
            self.style_proj = nn.Linear(c.style_dim, c.d_model, bias=False)
            nn.init.zeros_(self.style_proj.weight)

    def _condition(self, z: torch.Tensor, genre: torch.Tensor | None) -> torch.Tensor:
        """Latents (B, n, d) plus the genre embedding; ``genre`` (B,) int64 indices, None or -1 = auto."""
        c = self.config
        if not c.n_genres:
            if genre is not None:
                raise ParameterError("this model is not genre-conditioned (n_genres = 0); pass genre=None")
            return z
        B = z.shape[0]
        if genre is None:
            genre = torch.full((B,), c.n_genres, dtype=torch.long, device=z.device)
        genre = torch.as_tensor(genre, dtype=torch.long, device=z.device).reshape(-1).expand(B)
        if bool(((genre < -1) | (genre > c.n_genres)).any()):
            raise ParameterError(f"genre indices must be in [0, {c.n_genres}) or -1 (auto), got {genre.tolist()}")
        genre = torch.where(genre < 0, torch.full_like(genre, c.n_genres), genre)
        return z + self.genre_embedding(genre)[:, None, :]  # (B, n, d)

    # ---- style latent (style_dim > 0) -------------------------------------------------------------

    def style_knots(self, dance: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Posterior of the style latent: normalised poses (B, n, P) → (mean, log-variance), each
        (B, ceil(n / style_segment), style_dim), one per segment (the last may be shorter)."""
        c = self.config
        B, n, _ = dance.shape
        S = c.style_segment
        m = -(-n // S)
        h = self.style_posterior(dance)  # (B, n, 128)
        pad = m * S - n
        h = F.pad(h, (0, 0, 0, pad)).view(B, m, S, -1).sum(2)  # (B, m, 128)
        count = torch.full((m,), float(S), device=dance.device)
        count[-1] = S - pad
        stats = self.style_stats(h / count[None, :, None])  # (B, m, 2k)
        return stats[..., : c.style_dim], stats[..., c.style_dim :].clamp(-8.0, 4.0)

    def style_path(self, knots: torch.Tensor, n: int) -> torch.Tensor:
        """Knots (B, m, k) at the segments' centres → w(t) (B, n, k), linear between centres, constant
        before the first and after the last."""
        S = self.config.style_segment
        m = knots.shape[1]
        centres = torch.arange(m, device=knots.device, dtype=torch.float32) * S + (S - 1) / 2.0
        t = torch.arange(n, device=knots.device, dtype=torch.float32)
        pos = ((t - centres[0]) / S).clamp(0.0, float(m - 1))  # (n,) in knot units
        i0 = pos.floor().long().clamp(max=m - 1)
        i1 = (i0 + 1).clamp(max=m - 1)
        f = (pos - i0.float())[None, :, None]
        return (1 - f) * knots[:, i0] + f * knots[:, i1]

    # ---- encoder ---------------------------------------------------------------------------------

    def encode(self, music: torch.Tensor, *, chunk: int | None = None) -> torch.Tensor:
        """Music features (B, n, D) → Z (B, n, d_model), in overlapping chunks of ``chunk`` frames.

        Each chunk is encoded with ``context`` extra frames on both sides (the receptive field of the
        local / conv encoders, which makes the result identical to encoding the whole sequence at
        once when ``pos_encoding="relative"``; ``window`` frames for the global / lstm encoders,
        an approximation). ``chunk=None`` encodes the whole sequence in one call.
        """
        self._check_music(music)
        n = music.shape[1]
        if chunk is None or n <= chunk:
            return self.encoder(music)
        context = self.encoder.receptive_field
        if context is None:
            context = self.config.window
        out = []
        for start in range(0, n, chunk):
            a, b = max(0, start - context), min(n, start + chunk + context)
            z = self.encoder(music[:, a:b])  # (B, b - a, d)
            out.append(z[:, start - a : start - a + min(chunk, n - start)])
        return torch.cat(out, dim=1)

    # ---- decoder ---------------------------------------------------------------------------------

    def initial_state(
        self, batch: int, *, generator: torch.Generator | list[torch.Generator] | None = None,
        device: torch.device | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(h_0, c_0), each (decoder_layers, B, decoder_hidden), drawn from N(0, 1) with ``generator``
        (or a list of B generators, one per batch row: row k then equals a batch of one drawn with
        ``generator[k]``)."""
        c = self.config
        device = device or self.bop.device
        gens = _generators(generator, batch)
        if len(gens) == 1:
            shape = (c.decoder_layers, batch, c.decoder_hidden)
            gen_device = gens[0].device if gens[0] is not None else torch.device("cpu")
            h0 = torch.randn(shape, generator=gens[0], device=gen_device)
            c0 = torch.randn(shape, generator=gens[0], device=gen_device)
            return h0.to(device), c0.to(device)
        rows = [self.initial_state(1, generator=g, device=device) for g in gens]
        return torch.cat([h for h, _ in rows], dim=1), torch.cat([c_ for _, c_ in rows], dim=1)

    def _variety_noise(self, n: int, batch: int, variety: SeedVariety, generator, device,
                       scale: torch.Tensor | float = 1.0) -> dict[str, torch.Tensor]:
        """All of a song's variety draws at once (after the initial state's): ``state`` (boundaries, 2, layers,
        B, H) and ``latent`` (B, n, d), the latent offsets (σ·u(t) + τ·v) times ``scale`` (the song's spread
        of z per dimension, (B, 1, d))."""
        c = self.config
        gens = _generators(generator, batch)
        out: dict[str, torch.Tensor] = {}
        if not variety.active:
            return out
        p = variety.phrase
        if variety.state_noise > 0 and p > 0:
            bounds = max((n - 1) // p, 0)  # boundaries at frames p, 2p, ... < n
            out["state"] = _randn((bounds, 2, c.decoder_layers, batch, c.decoder_hidden), gens, axis=3).to(device)
        if variety.latent_noise > 0 and p > 0:
            knots = _randn((batch, n // p + 2, c.d_model), gens, axis=0).to(device)  # at frames 0, p, 2p, ...
            t = torch.arange(n, device=device)
            k, f = t // p, ((t % p).float() / p)[None, :, None]
            out["latent"] = variety.latent_noise * ((1 - f) * knots[:, k] + f * knots[:, k + 1])  # (B, n, d)
        if variety.dance_latent > 0:
            v = variety.dance_latent * _randn((batch, 1, c.d_model), gens, axis=0).to(device)  # (B, 1, d)
            out["latent"] = out["latent"] + v if "latent" in out else v.expand(batch, n, c.d_model)
        if "latent" in out:
            out["latent"] = out["latent"] * scale
        if variety.style > 0 and c.style_dim:
            m = -(-n // c.style_segment)
            e = _randn((batch, m, c.style_dim), gens, axis=0).to(device)  # per segment
            v = _randn((batch, 1, c.style_dim), gens, axis=0).to(device)  # per dance
            rho = variety.style_share
            out["style"] = variety.style * (math.sqrt(rho) * v + math.sqrt(1.0 - rho) * e)  # (B, m, k)
        return out

    def _decoder_input(self, prev: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Previous poses (B, L, P) and latents (B, L, d) → LSTM input (B, L, P [+ d])."""
        return torch.cat([prev, z], dim=-1) if self.config.condition_on_music else prev

    def _step(self, prev: torch.Tensor, z: torch.Tensor, state):
        """Run the decoder over L frames with inputs ``prev (B, L, P)`` → (ŷ (B, L, P), state)."""
        h, state = self.decoder(self._decoder_input(prev, z), state)  # (B, L, H)
        return self.head(torch.cat([h, z], dim=-1)), state  # (B, L, P)

    def forward(
        self,
        music: torch.Tensor,
        dance: torch.Tensor | None = None,
        *,
        schedule_p: int = 0,
        schedule_q: int = 10,
        generator: torch.Generator | None = None,
        genre: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Predict poses for ``music``; with targets, under the dynamic auto-condition.

        Parameters
        ----------
        music : (B, n, music_dim) normalised features
        dance : (B, n, pose_dim) normalised target poses, or None (then the decoder runs fully
            autoregressively, like :meth:`generate` without chunking)
        schedule_p, schedule_q : generated / ground-truth frames per period of the decoder input
            (:func:`auto_condition_mask`); ``schedule_p=0`` is teacher forcing
        generator : draws the initial decoder state (None: torch's global generator)
        genre : (B,) genre indices for a genre-conditioned model (``n_genres > 0``); None or -1: auto

        Returns
        -------
        pred : (B, n, pose_dim)
        loss : mean absolute error to ``dance`` (Eq. 5), or None without targets
        """
        self._check_music(music)
        B, n, _ = music.shape
        z = self._condition(self.encoder(music), genre)  # (B, n, d)
        state = self.initial_state(B, generator=generator, device=music.device)
        y0 = self.bop.expand(B, 1, -1)  # (B, 1, P)
        if dance is None:
            pred = self._autoregress(z, y0, state)[0]
            return pred, None
        if dance.shape[:2] != (B, n) or dance.shape[2] != self.config.pose_dim:
            raise ParameterError(
                f"dance must have shape ({B}, {n}, {self.config.pose_dim}) to match music, got {tuple(dance.shape)}"
            )
        kl = None
        if self.config.style_dim:
            mu, logvar = self.style_knots(dance)  # (B, m, k)
            eps = torch.randn(mu.shape, generator=generator, device=generator.device if generator is not None
                              else "cpu").to(mu.device) if self.training else torch.zeros_like(mu)
            w = mu + torch.exp(0.5 * logvar) * eps
            z = z + self.style_proj(self.style_path(w, n))
            kl_dim = 0.5 * (mu.pow(2) + logvar.exp() - 1.0 - logvar).mean(dim=(0, 1))  # (k,) nats per dimension
            kl = kl_dim.clamp(min=self.config.style_free_bits).mean()
        given = torch.cat([y0, dance[:, :-1]], dim=1)  # (B, n, P): y_0, y_1, ..., y_{n-1}
        outputs: list[torch.Tensor] = []
        for a, b, is_given in _runs(auto_condition_mask(n, p=schedule_p, q=schedule_q)):
            if is_given:  # ground-truth inputs: one nn.LSTM call for the whole run
                y, state = self._step(given[:, a:b], z[:, a:b], state)  # (B, b - a, P)
            else:  # generated inputs: step by step from the latest prediction (a >= 1: input 0 is y_0)
                y, _, state = self._autoregress(z[:, a:b], outputs[-1][:, -1:], state)
            outputs.append(y)
        pred = torch.cat(outputs, dim=1)  # (B, n, P)
        loss = F.l1_loss(pred, dance) + self.motion_loss(pred, dance)
        if kl is not None:
            loss = loss + self.config.style_beta * kl
        return pred, loss

    def motion_loss(self, pred: torch.Tensor, dance: torch.Tensor) -> torch.Tensor:
        """The velocity, speed and kinetic terms of the training loss (0 with all three weights 0).

        ``pred``, ``dance``: (B, n, P) normalised poses. With Δ the difference of consecutive frames
        (B, n − 1, P): ``velocity_weight`` × mean |Δŷ − Δy| + ``speed_weight`` × mean over (B, P) of
        |mean_t |Δŷ| − mean_t |Δy|| + ``kinetic_weight`` × mean over (B, P) of |rms_t Δŷ − rms_t Δy|
        (``rms_t Δ = sqrt(mean_t Δ² + 1e-8)``). The speed term asks each coordinate of a window to move as much
        as the target's, whatever the phase: L1 on poses alone lets an autoregressive decoder settle on calmer
        motion than the data's (docs/BENCHMARKS.md, "the default's FID_k"); the kinetic term asks the same of
        the root mean square, which weighs a quick burst (a heel's rise) more than a steady drift, as the
        kinetic features of FID_k (mean squared velocity) do.
        """
        c = self.config
        loss = pred.new_zeros(())
        if (c.velocity_weight or c.speed_weight or c.kinetic_weight) and pred.shape[1] > 1:
            dp, dy = pred.diff(dim=1), dance.diff(dim=1)  # (B, n - 1, P)
            if c.velocity_weight:
                loss = loss + c.velocity_weight * F.l1_loss(dp, dy)
            if c.speed_weight:
                loss = loss + c.speed_weight * F.l1_loss(dp.abs().mean(dim=1), dy.abs().mean(dim=1))  # over (B, P)
            if c.kinetic_weight:
                rms_p = (dp.square().mean(dim=1) + 1e-8).sqrt()  # (B, P)
                rms_y = (dy.square().mean(dim=1) + 1e-8).sqrt()
                loss = loss + c.kinetic_weight * F.l1_loss(rms_p, rms_y)
        return loss

    def _autoregress(self, z: torch.Tensor, prev: torch.Tensor, state):
        """Generate ``L = z.shape[1]`` frames from the input pose ``prev (B, 1, P)``, one step at a time.

        Inference on the CPU in float32 (no gradient needed) runs :class:`NumpyDecoder` (the same maths in
        NumPy, about 4× faster per frame: a NumPy call costs about a microsecond, a torch call several); with
        gradients (training's generated runs), or on another device or dtype, :meth:`_autoregress_torch`
        (``torch.lstm_cell`` on the weights of ``self.decoder``, the maths of ``nn.LSTM``). Returns
        ``(ŷ (B, L, P), last ŷ (B, 1, P), state)``. A copy made by :func:`dancekit.models.precision.to_precision`
        decodes with its ``fast_decoder``.
        """
        fast = getattr(self, "fast_decoder", None)  # reduced-precision, fused decoder (models/precision.py)
        if fast is not None:
            return fast(z, prev, state)
        if NumpyDecoder.usable(self, z):
            return NumpyDecoder.of(self)(z, prev, state)
        return self._autoregress_torch(z, prev, state)

    def _autoregress_torch(self, z: torch.Tensor, prev: torch.Tensor, state):
        """:meth:`_autoregress` in torch (what training steps through, with gradients; the reference that
        :class:`NumpyDecoder` is tested against)."""
        c = self.config
        weights = [
            tuple(getattr(self.decoder, f"{kind}_l{layer}") for kind in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"))
            for layer in range(c.decoder_layers)
        ]
        hs, cs = list(state[0].unbind(0)), list(state[1].unbind(0))  # each (B, H)
        y = prev[:, 0]  # (B, P)
        outputs = []
        for t in range(z.shape[1]):
            zt = z[:, t]  # (B, d)
            x = torch.cat([y, zt], dim=-1) if c.condition_on_music else y
            for layer in range(c.decoder_layers):
                hs[layer], cs[layer] = torch.lstm_cell(x, (hs[layer], cs[layer]), *weights[layer])
                x = hs[layer]
            y = self.head(torch.cat([x, zt], dim=-1))  # (B, P)
            outputs.append(y)
        if not outputs:
            return z.new_zeros(z.shape[0], 0, c.pose_dim), prev, state
        out = torch.stack(outputs, dim=1)  # (B, L, P)
        return out, out[:, -1:], (torch.stack(hs), torch.stack(cs))

    @torch.no_grad()
    def generate(
        self,
        music: torch.Tensor,
        *,
        generator: torch.Generator | list[torch.Generator] | None = None,
        chunk: int | None = None,
        progress: bool = False,
        genre: torch.Tensor | None = None,
        variety: SeedVariety | None = None,
    ) -> torch.Tensor:
        """Dance for a whole song, autoregressively from the begin-of-pose (inference mode).

        The song is encoded in chunks of ``chunk`` frames (default ``config.encoder_chunk``), each with
        context on both sides (see :meth:`encode`), so the encoder's memory is bounded whatever the song
        length (e.g. 10-minute songs); the latents (n × d_model floats) are then decoded.

        Parameters
        ----------
        music : (B, n, music_dim) normalised features at the training fps; (1, n, music_dim) with a list of
            ``B`` generators: one song danced ``B`` times (its music encoded once)
        generator : seeds the initial decoder state (and the variety draws); the same seed gives the same
            dance. A list of generators (one per row, :meth:`initial_state`): many dances, row ``k`` exactly
            (bit for bit) the dance that ``generator[k]`` alone gives: the rows are decoded by
            :func:`decode_seeds`, each row's matrix products its own one-row products (a batched matrix product
            rounds differently for every batch size, and the autoregressive decoder carries a last-bit
            difference into another dance within ~20 s).
            One generator for ``B`` songs decodes them as one batch (rows not bit-equal to the songs alone).
        genre : (B,) or (1,) genre indices for a genre-conditioned model; None or -1: auto (the music decides)
        variety : per-phrase perturbations that keep the seeds' dances apart (:class:`SeedVariety`);
            None: the paper's decoding (the seed draws the initial state only)

        Returns
        -------
        (B, n, pose_dim) normalised poses
        """
        self._check_music(music)
        was_training = self.training
        self.eval()
        try:
            B, n, _ = music.shape
            if not isinstance(generator, (list, tuple)):  # one generator: the batch's rows share its draws
                z = self._latents(music, genre, chunk=chunk)
                return self._decode(z, generator, variety, device=music.device, chunk=chunk, progress=progress)
            if B == 1:  # one song, many seeds: the music encoded once, its latents shared by every seed
                B = len(generator)
            elif len(generator) != B:
                raise ParameterError(f"{len(generator)} generators for a batch of {B} songs")
            genres = None if genre is None else torch.as_tensor(genre).reshape(-1)
            if genres is not None and len(genres) not in (1, B):
                raise ParameterError(f"{len(genres)} genre indices for a batch of {B}")
            cache: dict[tuple[int, int], torch.Tensor] = {}
            latents = []
            for k in range(B):  # the music encoded once per (song, genre), its latents shared by the seeds
                song = k if music.shape[0] > 1 else 0
                index = genres[k : k + 1] if genres is not None and len(genres) > 1 else genres
                key = (song, -2 if index is None else int(index))
                if key not in cache:
                    cache[key] = self._latents(music[song : song + 1], index, chunk=chunk)
                latents.append(cache[key])
            return decode_seeds([self] * B, latents, list(generator), variety, chunk=chunk, progress=progress)
        finally:
            self.train(was_training)

    def _latents(self, music: torch.Tensor, genre: torch.Tensor | None, *, chunk: int | None = None) -> torch.Tensor:
        """The song's conditioned latents ``(B, n, d_model)`` for ``music (B, n, music_dim)``, encoded in chunks of
        ``chunk`` frames (default ``config.encoder_chunk``) with the encoder's receptive field as context."""
        if music.shape[1] == 0:
            return music.new_zeros(music.shape[0], 0, self.config.d_model)
        return self._condition(self.encode(music, chunk=chunk or self.config.encoder_chunk), genre)  # (B, n, d)

    def _decode(self, z: torch.Tensor, generator, variety: SeedVariety | None, *, device, chunk: int | None = None,
                progress: bool = False, prefix: torch.Tensor | None = None) -> torch.Tensor:
        """Decode the latents ``z (B, n, d_model)`` from the begin-of-pose with the initial state (and the
        variety's draws) of ``generator`` → (B, n, pose_dim); the steps are run in pieces of ``chunk`` frames
        (or the variety's phrases), the pieces shown by ``progress``. ``prefix`` (1 or B, N, pose_dim), normalised
        poses: the first N frames are those poses, fed to the decoder as its previous poses (teacher forcing: its
        state is built from them), and the dance continues from the last (:func:`_decode_piece`)."""
        B, n, _ = z.shape
        variety = variety or SeedVariety()
        z, state, noise = self._decode_start(z, generator, variety, device=device)
        if n == 0:
            return z.new_zeros(B, 0, self.config.pose_dim)
        prev = self.bop.expand(B, 1, -1)
        outputs = []
        for a0, b0 in _pieces(n, variety, chunk or self.config.encoder_chunk, progress):
            state = _perturb_state(state, noise, a0, variety)
            y, prev, state = _decode_piece(self._autoregress, z, None if prefix is None else prefix.expand(B, -1, -1),
                                           a0, b0, prev, state)
            outputs.append(y)
        return torch.cat(outputs, dim=1)

    def _decode_start(self, z: torch.Tensor, generator, variety: SeedVariety, *, device):
        """What :meth:`_decode` draws before its first step, in this order: the initial state ``(h_0, c_0)``, then
        (a song of ``n > 0`` frames, an active ``variety``) the variety's noise, whose latent offsets and style are
        added to ``z``. Returns ``(z (B, n, d), state, noise)`` (:meth:`_variety_noise`'s ``noise``, or ``{}``)."""
        B, n, _ = z.shape
        state = self.initial_state(B, generator=generator, device=device)
        noise: dict[str, torch.Tensor] = {}
        if n and variety.active:  # the whole song's spread of z per dimension scales the latent offsets
            noise = self._variety_noise(n, B, variety, generator, device,
                                        scale=z.std(dim=1, keepdim=True, correction=0))
            if "latent" in noise:
                z = z + noise["latent"]
            if "style" in noise:
                z = z + self.style_proj(self.style_path(noise["style"], n))
        return z, state, noise

    def _check_music(self, music: torch.Tensor) -> None:
        if music.ndim != 3 or music.shape[2] != self.config.music_dim:
            raise ParameterError(
                f"music must have shape (B, n, {self.config.music_dim}), got {tuple(music.shape)}"
            )

    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)


@torch.no_grad()
def decode_seeds(models: list[RevolutionModel], latents: list[torch.Tensor], generators: list[torch.Generator],
                 variety: SeedVariety | None = None, *, chunk: int | None = None, progress: bool = False,
                 workers: int = 1, prefixes: list[torch.Tensor] | None = None) -> torch.Tensor:
    """Many dances of one song: row ``k`` is ``models[k]``'s dance of the latents ``latents[k]``
    (1, n, ``models[k].config.d_model``) with the initial state and variety draws of ``generators[k]``, bit for bit
    ``models[k]._decode(latents[k], [generators[k]], variety)`` (a batch of one) → (B, n, pose_dim) normalised
    poses, whatever the rows beside it and ``workers``.

    The rows of one decoder architecture (genre models may differ in size) share a frame loop
    (:class:`_RowDecoder`): their draws are made row by row, as for a batch of one, then every frame steps all of
    them at once, each row's matrix products its own matrix-vector products (the same bits as a batch of one), the
    elementwise gate arithmetic and the per-frame overhead shared. A row alone in its loop, or of a
    reduced-precision model (``fast_decoder``), is decoded on its own.

    Parameters
    ----------
    chunk : the pieces without a phrase (default ``config.encoder_chunk``)
    progress : a progress bar over the pieces (of the first lane)
    workers : the rows are split into this many lanes of about equal cost (decoder weights per row), decoded side
        by side in threads (each row's arithmetic is unchanged: the torch calls of one row run in one thread); 1:
        one after the other in this thread. Rows that :class:`NumpyDecoder` decodes share one lane whatever
        ``workers``: a NumPy frame loop holds the interpreter between its short calls, and two such loops in
        threads spend more time waiting for it than they gain (8 seeds of a minute danced in 7.8 s with two lanes,
        5.0 s with one)
    prefixes : per row, normalised poses (1, N, P) (N the same for every row) that are the dance's first N frames
        and that the decoder is fed as its previous poses (teacher forcing): the dance continues them; None: none
    """
    B = len(models)
    if not (B == len(latents) == len(generators)) or B == 0:
        raise ParameterError(f"{B} models, {len(latents)} latents and {len(generators)} generators: one of each per "
                             "row, at least one row")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an integer >= 1, got {workers!r}")
    n = latents[0].shape[1]
    for m, z in zip(models, latents, strict=True):
        if z.shape != (1, n, m.config.d_model):
            raise ParameterError(f"every row's latents must have shape (1, {n}, d_model of its model), got "
                                 f"{[tuple(z.shape) for z in latents]}")
    if prefixes is not None:
        if len(prefixes) != B or len({tuple(p.shape) for p in prefixes}) != 1 or prefixes[0].ndim != 3 \
                or prefixes[0].shape[0] != 1 or prefixes[0].shape[2] != models[0].config.pose_dim:
            raise ParameterError(f"prefixes must be one (1, N, pose_dim) tensor per row, N the same for all; got "
                                 f"{[tuple(p.shape) for p in prefixes]}")
    variety = variety or SeedVariety()
    device = models[0].bop.device
    out: list[torch.Tensor | None] = [None] * B

    def lane(rows: list[int], shown: bool) -> None:
        with torch.no_grad():  # grad mode is per thread
            for loop in _RowDecoder.partition([models[k] for k in rows]):
                ks = [rows[j] for j in loop]
                if len(ks) == 1:
                    y = models[ks[0]]._decode(latents[ks[0]], [generators[ks[0]]], variety, device=device,
                                              chunk=chunk, progress=progress and shown,
                                              prefix=None if prefixes is None else prefixes[ks[0]])
                else:
                    y = _decode_rows([models[k] for k in ks], [latents[k] for k in ks], [generators[k] for k in ks],
                                     variety, device=device, chunk=chunk, progress=progress and shown,
                                     prefixes=None if prefixes is None else [prefixes[k] for k in ks])
                for j, k in enumerate(ks):
                    out[k] = y[j : j + 1]

    numpy_rows = all(getattr(m, "fast_decoder", None) is None and NumpyDecoder.usable(m, z)
                     for m, z in zip(models, latents, strict=True))
    lanes = _lanes(models, 1 if numpy_rows else workers)  # NumPy frame loops in threads wait on each other
    if len(lanes) == 1:
        lane(lanes[0], True)
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(len(lanes), thread_name_prefix="dancekit-decode") as pool:
            for future in [pool.submit(lane, rows, i == 0) for i, rows in enumerate(lanes)]:
                future.result()
    return torch.cat(out, dim=0)


def _decode_piece(step, z: torch.Tensor, prefix: torch.Tensor | None, a0: int, b0: int, prev: torch.Tensor,
                  state):
    """Frames ``[a0, b0)`` of a decoding stepped by ``step`` (``(z (B, L, d), prev (B, 1, P), state) -> (ŷ,
    last ŷ, state)``) from ``prev``. When the first ``N = prefix.shape[1]`` frames are given (``prefix`` not None,
    ``a0 < N``), each frame ``t < N`` is stepped from its given previous pose (the begin-of-pose or
    ``prefix[:, t - 1]``) and its output is ``prefix[:, t]``; the frames from N on are decoded from
    ``prefix[:, N - 1]``. Returns ``(y (B, b0 - a0, P), last pose (B, 1, P), state)``."""
    if prefix is None or a0 >= prefix.shape[1]:
        return step(z[:, a0:b0], prev, state)
    n_pre = prefix.shape[1]
    for t in range(a0, min(b0, n_pre)):
        _, _, state = step(z[:, t : t + 1], prev, state)
        prev = prefix[:, t : t + 1]
    ys = [prefix[:, a0 : min(b0, n_pre)]]
    if b0 > n_pre:
        y, prev, state = step(z[:, n_pre:b0], prev, state)
        ys.append(y)
    return torch.cat(ys, dim=1), prev, state


def _lanes(models: list[RevolutionModel], workers: int) -> list[list[int]]:
    """The rows split into at most ``workers`` lanes of about equal cost (a row costs its model's decoder weights:
    the matrix-vector products of a frame), each lane's rows in order; the largest rows placed first, each on the
    lane with the least cost so far."""
    cost = [sum(p.numel() for p in (*m.decoder.parameters(), *m.head.parameters())) for m in models]
    lanes: list[list[int]] = [[] for _ in range(min(workers, len(models)))]
    totals = [0] * len(lanes)
    for k in sorted(range(len(models)), key=lambda k: -cost[k]):
        i = totals.index(min(totals))
        lanes[i].append(k)
        totals[i] += cost[k]
    return [sorted(rows) for rows in lanes if rows]


def _decode_rows(models: list[RevolutionModel], latents: list[torch.Tensor], generators: list[torch.Generator],
                 variety: SeedVariety, *, device, chunk: int | None, progress: bool,
                 prefixes: list[torch.Tensor] | None = None) -> torch.Tensor:
    """:func:`decode_seeds` of rows of one architecture, rows of one model consecutive, in one frame loop
    (``prefixes``: each row's given first poses (1, N, P), or None)."""
    starts = [m._decode_start(z, [g], variety, device=device) for m, z, g in zip(models, latents, generators)]
    B, n = len(models), latents[0].shape[1]
    if n == 0:
        return latents[0].new_zeros(B, 0, models[0].config.pose_dim)
    z = torch.cat([s[0] for s in starts], dim=0)  # (B, n, d)
    state = tuple(torch.cat([s[1][i] for s in starts], dim=1) for i in range(2))  # each (layers, B, H)
    noise = {"state": torch.cat([s[2]["state"] for s in starts], dim=3)} if "state" in starts[0][2] else {}
    step = _RowDecoder(models)
    prev = torch.cat([m.bop.expand(1, 1, -1) for m in models], dim=0)  # (B, 1, P)
    given = None if prefixes is None else torch.cat(prefixes, dim=0)  # (B, N, P)
    outputs = []
    for a0, b0 in _pieces(n, variety, chunk or models[0].config.encoder_chunk, progress):
        state = _perturb_state(state, noise, a0, variety)
        y, prev, state = _decode_piece(step, z, given, a0, b0, prev, state)
        outputs.append(y)
    return torch.cat(outputs, dim=1)  # (B, n, P)


#: ``torch.baddbmm`` computes a product of fewer multiply-adds than this (per batch item) in its own loop, not by
#: one ``addmm`` per item: :class:`_RowDecoder` computes such small products row by row with ``nn.functional.linear``.
BMM_LOOP_MIN = 400


class _RowDecoder:
    """One decoder step for rows of one or more :class:`RevolutionModel` of one architecture (rows of one model
    consecutive), each row computed as :meth:`RevolutionModel._autoregress` computes a batch of one.

    On the CPU in float32 without gradients the rows run :meth:`NumpyDecoder.run` (a decoder per row's model, each
    row's products its own); otherwise this torch loop: ``torch.lstm_cell`` and ``nn.Linear`` on a batch of B rows use
    one (B × K) matrix product, which rounds
    differently from B products of one row (and the autoregressive decoder carries a last-bit difference into
    another dance within ~20 s). Here each row's products are one-row products, the same call, layout and bias
    handling as ``nn.Linear`` on one row (``addmm``), so the same bits: ``torch.baddbmm`` over the rows with the
    weight matrix expanded (stride 0) in the batch dimension, which runs one ``addmm`` per row, or, for a
    product of fewer than :data:`BMM_LOOP_MIN` multiply-adds (which ``baddbmm`` computes in a loop of its own),
    ``nn.functional.linear`` row by row. The gate arithmetic is ``torch.lstm_cell``'s (gates = hidden product +
    input product; sigmoid, tanh; ``c' = f c + i g``, ``h' = o tanh(c')``), elementwise, so the same bits for
    every row."""

    def __init__(self, models: list[RevolutionModel]):
        c = models[0].config
        self.config = c
        self.models = models
        #: per model: (first row, end row, {("ih" | "hh", layer) or "head": (weight (rows, K, N) and bias
        #: (rows, 1, N) expanded for baddbmm, or None, None for a small product; weight (N, K), bias (N,))})
        self.groups: list[tuple[int, int, dict]] = []
        k = 0
        while k < len(models):
            e = k
            while e < len(models) and models[e] is models[k]:
                e += 1
            m, rows = models[k], e - k

            def rowwise(weight: torch.Tensor, bias: torch.Tensor, rows: int = rows):
                if weight.numel() < BMM_LOOP_MIN:  # (N, K): row by row
                    return None, None, weight, bias
                return weight.t().expand(rows, *weight.t().shape), bias.expand(rows, 1, -1), weight, bias

            params = {"head": rowwise(m.head.weight, m.head.bias)}
            for layer in range(c.decoder_layers):
                for kind in ("ih", "hh"):
                    params[kind, layer] = rowwise(getattr(m.decoder, f"weight_{kind}_l{layer}"),
                                                  getattr(m.decoder, f"bias_{kind}_l{layer}"))
            self.groups.append((k, e, params))
            k = e

    @staticmethod
    def partition(models: list[RevolutionModel]) -> list[list[int]]:
        """The rows of ``models`` that can share a frame loop (one decoder architecture, full precision, biases as
        ``nn.LSTM`` and ``nn.Linear`` have by default), rows of one model consecutive; a list per loop, in the
        order of their first rows."""
        def key(m: RevolutionModel):
            c = m.config
            if getattr(m, "fast_decoder", None) is not None or not m.decoder.bias or m.head.bias is None:
                return ("alone", id(m))  # decoded on its own (a "fast_decoder" has its own loop)
            return (c.pose_dim, c.d_model, c.decoder_layers, c.decoder_hidden, c.condition_on_music)

        loops: dict = {}
        for k, m in enumerate(models):
            loops.setdefault(key(m), {}).setdefault(id(m), []).append(k)
        return [[k for rows in by_model.values() for k in rows] for by_model in loops.values()]

    def _product(self, x: torch.Tensor, key) -> torch.Tensor:
        """``x (B, 1, K)`` times the weight ``key`` of each row's model, plus its bias: (B, 1, N)."""
        parts = []
        for a, b, params in self.groups:
            rows_weight, rows_bias, weight, bias = params[key]
            xs = x if len(self.groups) == 1 else x[a:b]
            if rows_weight is not None:
                parts.append(torch.baddbmm(rows_bias, xs, rows_weight))
            else:
                parts.extend(F.linear(xs[k], weight, bias)[None] for k in range(b - a))
        return parts[0] if len(parts) == 1 else torch.cat(parts, dim=0)

    def __call__(self, z: torch.Tensor, prev: torch.Tensor, state):
        """``L = z.shape[1]`` frames from the input pose ``prev (B, 1, P)`` and ``state`` (each (layers, B, H)):
        ``(ŷ (B, L, P), last ŷ (B, 1, P), state)``, as :meth:`RevolutionModel._autoregress` (its
        :class:`NumpyDecoder` when every row's model may use it)."""
        if all(NumpyDecoder.usable(m, z) for m in self.models):
            return NumpyDecoder.run([NumpyDecoder.of(m) for m in self.models], z, prev, state)
        c = self.config
        hs = [h[:, None] for h in state[0].unbind(0)]  # each (B, 1, H)
        cs = [x[:, None] for x in state[1].unbind(0)]
        y = prev  # (B, 1, P)
        outputs = []
        for t in range(z.shape[1]):
            zt = z[:, t : t + 1]  # (B, 1, d)
            x = torch.cat([y, zt], dim=-1) if c.condition_on_music else y
            for layer in range(c.decoder_layers):
                gates = self._product(hs[layer], ("hh", layer)).add_(self._product(x, ("ih", layer)))  # (B, 1, 4H)
                i, f, g, o = gates.unsafe_chunk(4, 2)
                i, f, g, o = i.sigmoid_(), f.sigmoid_(), g.tanh_(), o.sigmoid_()
                cs[layer] = f.mul(cs[layer]).add_(i.mul(g))
                hs[layer] = o.mul(cs[layer].tanh())
                x = hs[layer]
            y = self._product(torch.cat([x, zt], dim=-1), "head")  # (B, 1, P)
            outputs.append(y)
        if not outputs:
            return z.new_zeros(z.shape[0], 0, c.pose_dim), prev, state
        out = torch.cat(outputs, dim=1)  # (B, L, P)
        return out, out[:, -1:], (torch.stack([h[:, 0] for h in hs]), torch.stack([x[:, 0] for x in cs]))


class NumpyDecoder:
    """:meth:`RevolutionModel._autoregress` in NumPy: inference on the CPU in float32 (weights copied once,
    :meth:`of`).

    Each frame is the products of one row at a time, as ``torch.lstm_cell`` and ``nn.Linear`` of a batch of one
    compute them: per layer ``x W_ih + h W_hh + (b_ih + b_hh)`` with ``x`` the layer's whole input (layer 0:
    ``[ŷ_{t-1}; z_t]``), and the head's ``[h_t; z_t] W^S + b``: vector-matrix products whose numbers depend neither
    on the rows beside it nor on how the frames are split into pieces, so a seed decoded among others (:meth:`run`,
    one decoder per row) is bit for bit the seed alone, and a decoding stepped a block at a time (``dancekit live``)
    is bit for bit the decoding in one go. Gates in the order i, f, o, g (the rows of ``nn.LSTM``'s i, f, g, o
    moved); σ(x) = (1 + tanh(x / 2)) / 2 with the halving folded into the i, f, o weight rows and biases (a power of
    two: exact), so one ``tanh`` over the four gates; ``c' = f c + i g``, ``h' = o tanh(c')``, elementwise. The same
    maths as ``nn.LSTM`` and ``nn.Linear``, rounded differently (float32 products summed in another order).
    """

    def __init__(self, model: RevolutionModel):
        c = model.config
        H = c.decoder_hidden
        self.config = c
        order = np.r_[0 : 2 * H, 3 * H : 4 * H, 2 * H : 3 * H]  # nn.LSTM's (i, f, g, o) rows → (i, f, o, g)
        half = np.ones(4 * H, np.float32)
        half[: 3 * H] = 0.5  # i, f, o: σ(x) = (1 + tanh(x / 2)) / 2

        def rows(name: str) -> np.ndarray:  # an LSTM weight or bias, rows reordered and halved; zeros if absent
            w = getattr(model.decoder, name, None)
            if w is None:
                return np.zeros(4 * H, np.float32)
            w = w.detach().cpu().numpy().astype(np.float32)[order]
            return w * (half[:, None] if w.ndim == 2 else half)

        #: per layer: (W_ih (K, 4H), W_hh (H, 4H), b_ih + b_hh (4H,)), K the layer's input size
        self.layers = [(np.ascontiguousarray(rows(f"weight_ih_l{layer}").T),
                        np.ascontiguousarray(rows(f"weight_hh_l{layer}").T),
                        rows(f"bias_ih_l{layer}") + rows(f"bias_hh_l{layer}")) for layer in range(c.decoder_layers)]
        self.head_w = np.ascontiguousarray(model.head.weight.detach().cpu().numpy().astype(np.float32).T)  # (H+d, P)
        self.head_b = (np.zeros(c.pose_dim, np.float32) if model.head.bias is None
                       else model.head.bias.detach().cpu().numpy().astype(np.float32))

    @staticmethod
    def usable(model: RevolutionModel, z: torch.Tensor) -> bool:
        """Whether :meth:`RevolutionModel._autoregress` runs this decoder: CPU float32 latents and weights, and no
        gradient to keep (grad mode off, or nothing that requires one)."""
        w = model.head.weight
        if z.device.type != "cpu" or w.device.type != "cpu" or z.dtype != torch.float32 or w.dtype != torch.float32:
            return False
        return not torch.is_grad_enabled() or not (z.requires_grad or any(
            p.requires_grad for p in (*model.decoder.parameters(), *model.head.parameters())))

    @staticmethod
    def of(model: RevolutionModel) -> NumpyDecoder:
        """The model's decoder, built once and rebuilt when a decoder or head weight has changed since (an
        optimiser step between two validations)."""
        key = tuple((p.data_ptr(), p._version) for p in (*model.decoder.parameters(), *model.head.parameters()))
        cached = model.__dict__.get("_numpy_decoder")
        if cached is None or cached[0] != key:
            cached = (key, NumpyDecoder(model))
            model.__dict__["_numpy_decoder"] = cached
        return cached[1]

    def __call__(self, z: torch.Tensor, prev: torch.Tensor, state):
        """``z (B, L, d)`` latents, ``prev (B, 1, P)``, ``state`` (h, c) each ``(layers, B, H)`` →
        ``(ŷ (B, L, P), last ŷ (B, 1, P), state)``, as :meth:`RevolutionModel._autoregress`."""
        return NumpyDecoder.run([self] * z.shape[0], z, prev, state)

    @staticmethod
    def run(decoders: list[NumpyDecoder], z: torch.Tensor, prev: torch.Tensor, state):
        """Row ``k`` of ``z (B, L, d)``, ``prev (B, 1, P)`` and ``state`` (h, c) each ``(layers, B, H)`` decoded
        by ``decoders[k]`` (one architecture) → ``(ŷ (B, L, P), last ŷ (B, 1, P), state)``, each row bit for bit
        that row decoded alone."""
        if z.shape[1] == 0:
            return z.new_zeros(z.shape[0], 0, decoders[0].config.pose_dim), prev, state
        with _one_blas_thread():
            return NumpyDecoder._run(decoders, z, prev, state)

    @staticmethod
    def _run(decoders: list[NumpyDecoder], z: torch.Tensor, prev: torch.Tensor, state):
        c = decoders[0].config
        B, L = z.shape[:2]
        H, P = c.decoder_hidden, c.pose_dim
        zs = z.detach().cpu().numpy()
        hs = state[0].detach().cpu().numpy().astype(np.float32)  # (layers, B, H), copies
        cs = state[1].detach().cpu().numpy().astype(np.float32)
        out = np.empty((B, L, P), np.float32)
        x0 = np.empty((B, P + zs.shape[2] if c.condition_on_music else P), np.float32)  # [ŷ_{t-1}; z_t]
        x0[:, :P] = prev[:, 0].detach().cpu().numpy()
        xh = np.empty((B, H + zs.shape[2]), np.float32)  # [h_t; z_t], the head's input
        gates = np.empty((B, 4 * H), np.float32)
        tmp = np.empty((B, 4 * H), np.float32)
        sig, g = gates[:, : 3 * H], gates[:, 3 * H :]
        i, f, o = gates[:, :H], gates[:, H : 2 * H], gates[:, 2 * H : 3 * H]
        part = tmp[:, :H]
        biases = [np.stack([d.layers[layer][2] for d in decoders]) for layer in range(c.decoder_layers)]  # (B, 4H)
        head_b = np.stack([d.head_b for d in decoders])  # (B, P)
        for t in range(L):
            if c.condition_on_music:
                x0[:, P:] = zs[:, t]
            xh[:, H:] = zs[:, t]
            x = x0
            for layer, bias in enumerate(biases):
                h, cell = hs[layer], cs[layer]
                for k, d in enumerate(decoders):
                    w_ih, w_hh, _ = d.layers[layer]
                    np.matmul(x[k], w_ih, out=gates[k])
                    np.matmul(h[k], w_hh, out=tmp[k])
                gates += tmp
                gates += bias
                np.tanh(gates, out=gates)
                sig *= 0.5
                sig += 0.5
                cell *= f
                np.multiply(i, g, out=part)
                cell += part
                np.tanh(cell, out=part)
                np.multiply(o, part, out=h)
                x = h
            xh[:, :H] = x
            y = x0[:, :P]
            for k, d in enumerate(decoders):
                np.matmul(xh[k], d.head_w, out=y[k])
            y += head_b
            out[:, t] = y
        result = torch.from_numpy(out)
        return result, result[:, -1:], (torch.from_numpy(hs), torch.from_numpy(cs))



class NumpyLocalEncoder:
    """:meth:`MusicEncoder.forward_range` of one stream (a batch of one) in NumPy, for the local encoder with
    relative positions: inference on the CPU in float32 (weights copied once, :meth:`of`). A live block's encoder
    work is a few dozen small products (the first layer's outputs over ``half_window`` frames on each side of the
    new ones, the last layer's at the new frames), where a torch call's overhead outweighs its arithmetic.

    The same maths as the torch modules (``nn.Linear``, ``nn.LayerNorm``, exact ``nn.GELU``, the banded attention
    with its relative bias and its ``[-half_window, ahead]`` mask), rounded differently (float32 sums in another
    order): within 1e-5 of the torch encoder (``tests/models/test_revolution_numpy.py``).
    """

    def __init__(self, encoder: MusicEncoder):
        c = encoder.config

        def a(t: torch.Tensor) -> np.ndarray:
            return t.detach().cpu().numpy().astype(np.float32)

        def lin(m: nn.Linear) -> tuple[np.ndarray, np.ndarray]:  # (W^T (in, out), b (out,))
            return np.ascontiguousarray(a(m.weight).T), a(m.bias)

        def ln(m: nn.LayerNorm) -> tuple[np.ndarray, np.ndarray, float]:
            return a(m.weight), a(m.bias), float(m.eps)

        self.config = c
        self.h, self.ahead, self.n_heads = c.half_window, c.ahead, c.n_heads
        self.embed = lin(encoder.embed)
        #: per layer: ln1, qkv, proj, relative bias (H, 2h + 1), ln2, ff1, ff2
        self.layers = [(ln(layer.ln1), lin(layer.attn.qkv), lin(layer.attn.proj), a(layer.attn.rel_bias),
                        ln(layer.ln2), lin(layer.ff[0]), lin(layer.ff[2])) for layer in encoder.layers]
        self.norm = ln(encoder.norm)
        self._bands: dict[tuple[int, int, int, int], np.ndarray] = {}

    @staticmethod
    def usable(encoder: MusicEncoder) -> bool:
        """Whether this encoder applies: the local encoder with relative positions, plain float32 ``nn.Linear``
        and ``nn.LayerNorm`` modules on the CPU (not a quantised copy), exact GELU."""
        c = encoder.config
        if c.encoder != "local" or c.pos_encoding != "relative":
            return False
        mods = [encoder.embed, encoder.norm]
        for layer in encoder.layers:
            mods += [layer.ln1, layer.attn.qkv, layer.attn.proj, layer.ln2, layer.ff[0], layer.ff[2]]
            if not isinstance(layer.ff[1], nn.GELU) or layer.ff[1].approximate != "none":
                return False
        return all(type(m) in (nn.Linear, nn.LayerNorm) and m.weight.device.type == "cpu"
                   and m.weight.dtype == torch.float32 for m in mods)

    @staticmethod
    def of(encoder: MusicEncoder) -> NumpyLocalEncoder:
        """The encoder's NumPy copy, built once and rebuilt when a weight has changed since."""
        key = tuple((p.data_ptr(), p._version) for p in encoder.parameters())
        cached = encoder.__dict__.get("_numpy_encoder")
        if cached is None or cached[0] != key:
            cached = (key, NumpyLocalEncoder(encoder))
            encoder.__dict__["_numpy_encoder"] = cached
        return cached[1]

    @staticmethod
    def _linear(x: np.ndarray, wb: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        return x @ wb[0] + wb[1]

    @staticmethod
    def _layer_norm(x: np.ndarray, p: tuple[np.ndarray, np.ndarray, float]) -> np.ndarray:
        inv = np.float32(1.0 / x.shape[-1])
        xc = x - np.add.reduce(x, axis=-1, keepdims=True) * inv
        var = np.add.reduce(xc * xc, axis=-1, keepdims=True) * inv
        return xc / np.sqrt(var + np.float32(p[2])) * p[0] + p[1]

    def _band(self, i: int, q0: int, nq: int, nk: int) -> np.ndarray:
        """Layer ``i``'s relative bias ``(H, nq, nk)`` of queries ``q0 .. q0 + nq`` (in the keys' rows) against
        keys ``0 .. nk``, ``-inf`` outside ``[-half_window, ahead]``; kept per shape (a stream repeats a few)."""
        key = (i, q0, nq, nk)
        band = self._bands.get(key)
        if band is None:
            h = self.h
            offsets = np.arange(nk)[None, :] - np.arange(q0, q0 + nq)[:, None]  # (nq, nk): key - query
            band = self.layers[i][3][:, np.clip(offsets, -h, h) + h]  # (H, nq, nk)
            band[:, (offsets < -h) | (offsets > self.ahead)] = -np.inf
            if len(self._bands) > 64:
                self._bands.clear()
            self._bands[key] = band
        return band

    def embed_rows(self, music: np.ndarray) -> np.ndarray:
        """``embed(music)``: feature rows ``(k, D)`` → ``(k, d)``."""
        return self._linear(np.asarray(music, np.float32), self.embed)

    def projections(self, x: np.ndarray) -> np.ndarray:
        """The first layer's queries, keys and values ``(k, 3d)`` of embedded rows ``x (k, d)``
        (:meth:`TransformerLayer.projections`)."""
        p = self.layers[0]
        return self._linear(self._layer_norm(x, p[0]), p[1])

    def forward_range(self, x: np.ndarray, start: int, stop: int, *, qkv0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`MusicEncoder.forward_range` of embedded rows ``x (n, d)`` with ``embedded=True``: the latents
        ``(stop - start, d)`` of frames ``[start, stop)``. ``qkv0``: :meth:`projections` of ``x`` ``(n, 3d)``. The
        products run on one BLAS thread (they are small; see :class:`NumpyDecoder`)."""
        with _one_blas_thread():
            return self._forward_range(x, start, stop, qkv0=qkv0)

    def _forward_range(self, x: np.ndarray, start: int, stop: int, *, qkv0: np.ndarray | None = None) -> np.ndarray:
        from scipy.special import erf

        n, d = x.shape
        start, stop = max(0, int(start)), min(n, int(stop))
        h, ah, L, H = self.h, self.ahead, len(self.layers), self.n_heads
        dh = d // H
        if stop <= start:
            return np.zeros((0, d), np.float32)
        lo = max(0, start - L * h)
        x = np.asarray(x[lo : min(n, stop + L * ah)], np.float32)
        for i, (ln1, qkv_w, proj, _, ln2, ff1, ff2) in enumerate(self.layers):
            r = L - 1 - i
            s0, s1 = max(0, start - r * h) - lo, min(n, stop + r * ah) - lo  # this layer's outputs, in x's rows
            k0, k1 = max(0, s0 - h), min(len(x), s1 + ah)  # the keys they look at
            if i == 0 and qkv0 is not None:
                q = qkv0[lo + s0 : lo + s1, :d]
                kv = qkv0[lo + k0 : lo + k1, d:]
            else:
                xn = self._layer_norm(x[k0:k1], ln1)
                q = xn[s0 - k0 : s1 - k0] @ qkv_w[0][:, :d] + qkv_w[1][:d]
                kv = xn @ qkv_w[0][:, d:] + qkv_w[1][d:]
            nq, nk = s1 - s0, k1 - k0
            qh = (q * np.float32(1.0 / math.sqrt(dh))).reshape(nq, H, dh).transpose(1, 0, 2)  # (H, nq, dh)
            kh = kv[:, :d].reshape(nk, H, dh).transpose(1, 2, 0)  # (H, dh, nk)
            vh = kv[:, d:].reshape(nk, H, dh).transpose(1, 0, 2)  # (H, nk, dh)
            scores = qh @ kh  # (H, nq, nk)
            scores += self._band(i, s0 - k0, nq, nk)
            scores -= scores.max(-1, keepdims=True)
            np.exp(scores, out=scores)
            scores /= scores.sum(-1, keepdims=True)
            y = (scores @ vh).transpose(1, 0, 2).reshape(nq, d)  # (nq, d)
            y = x[s0:s1] + self._linear(y, proj)
            f = self._linear(self._layer_norm(y, ln2), ff1)
            f = f * np.float32(0.5) * (np.float32(1.0) + erf(f * np.float32(1.0 / math.sqrt(2.0))))
            x = y + self._linear(f, ff2)
            lo += s0
        return np.asarray(self._layer_norm(x, self.norm), np.float32)


_BLAS = None


def _one_blas_thread():
    """A context in which the BLAS libraries (NumPy's among them) run one thread: a frame's vector-matrix
    products are too small to share, and a second BLAS thread waiting for a busy core made the decoder three
    times slower under load (2.3-2.6 against 0.8-0.9 ms a frame beside a test run; the same numbers either way).
    The controller is built once (listing the loaded libraries takes a millisecond; limiting then 0.03 ms)."""
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def _generators(generator, batch: int) -> list[torch.Generator | None]:
    """One generator for the batch, or a list of ``batch`` generators (one per row)."""
    if isinstance(generator, (list, tuple)):
        if len(generator) != batch:
            raise ParameterError(f"{len(generator)} generators for a batch of {batch}")
        return list(generator)
    return [generator]


def _pieces(n: int, variety: SeedVariety, chunk: int, progress: bool):
    """The pieces ``(a, b)`` of frames ``[0, n)`` a decoder runs in one go: the variety's phrases (an active variety
    with a phrase), else ``chunk`` frames; shown by a progress bar with ``progress``."""
    if variety.active and variety.phrase:
        pieces = _phrases(0, n, variety.phrase)
    else:
        pieces = [(a, min(n, a + chunk)) for a in range(0, n, chunk)]
    if progress:
        from tqdm import tqdm

        return tqdm(pieces, desc="generate", unit="piece")
    return pieces


def _phrases(a: int, b: int, phrase: int) -> list[tuple[int, int]]:
    """Frames ``[a, b)`` split at the multiples of ``phrase``."""
    cuts = [a, *range((a // phrase + 1) * phrase, b, phrase), b]
    return [(x, y) for x, y in zip(cuts[:-1], cuts[1:]) if y > x]


def _perturb_state(state, noise: dict[str, torch.Tensor], frame: int, variety: SeedVariety):
    """The decoder state mixed with the seed's noise when ``frame`` starts a phrase (not the song's first)."""
    if "state" not in noise or frame == 0 or frame % variety.phrase:
        return state
    eps = noise["state"][frame // variety.phrase - 1]  # (2, layers, B, H)
    a = variety.state_noise
    keep = math.sqrt(1.0 - a * a)
    return keep * state[0] + a * eps[0], keep * state[1] + a * eps[1]
