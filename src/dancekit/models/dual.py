"""Dual learning of music and dance (Wu et al., ACM MM 2021): G_M→D and G_D→M transformers, one module.

One file, one model family: :class:`DualConfig` and :class:`DualModel`, which holds both generators
(joint training couples them through the Gromov-Wasserstein and cycle losses, so they share one
checkpoint, one optimiser and one training step).

Representations (§3.1)
    * music in: the ``dual`` feature preset, 53 columns ``[mfcc 20, mfcc_delta 20, chroma 12, beat 1]``.
      Columns ``[music_raw_from, 53)`` (chroma + beat) are *not* normalised, so they are at once the
      input of G_M→D and the output space of G_D→M (12-d chroma in [0, 1] + 1-d beat in {0, 1}).
    * dance: ``rot6d`` (:mod:`dancekit.motion.representations`): root translation (3, normalised with
      the training statistics) + a raw 6D rotation per rig joint (first two matrix columns). Columns
      ``[dance_raw_from, P)`` are never normalised (the geodesic loss needs them as they are).

Generators (§3.3, §4.2): :class:`Seq2Seq`, a transformer encoder (full, unmasked self-attention) and an
autoregressive transformer decoder (causal self-attention + cross-attention to the encoder) over windows
of ``window`` frames (T = 75 in the paper). The decoder starts from a start token, the first frame of the
window: the first ground-truth frame in training, a pose (given or sampled from a pool of training start
poses) or a chord (root of 12 pitch classes × major/minor, :func:`chord_token`) in inference. The output
of a window is ``[start, ŷ_1, ..., ŷ_{T-1}]``; longer sequences are windows that overlap by one frame, each
starting from the last generated frame of the previous one (§4.2).

Losses (§3.4)
    * L_Y (Eq. 7–8): L1 on the root translation + squared geodesic distance of every joint rotation,
      summed over the components of a frame, averaged over frames.
    * L_X (Eq. 9): L1 on the 12 chroma + L1 on the beat, summed per frame, averaged over frames.
    * reconstruction (Eq. 6) and cycle (Eq. 10) losses of both generators; the entropic Gromov-Wasserstein
      distance (Algorithm 1, :mod:`dancekit.models.gromov`) between the time-averaged music embeddings of
      Enc_M→D and the time-averaged dance embeddings of Enc_D→M.
    * which loss updates which network, exactly as the paper's prescription::

          L_GW + L_dance^rec + L_dance^cycle  → G_M→D   (GW reaches Enc_M→D only: the dance embeddings are detached)
          [L_dance^vel + L_dance^acc + L_roll] → G_M→D  (not the paper; off by default)
          L_music^rec + L_music^cycle         → G_D→M

      i.e. in the dance cycle G_M→D(G_D→M(y)) the composed music is detached, in the music cycle
      G_D→M(G_M→D(x)) the generated dance is detached.
    * ablations (Table 4): ``gw``, ``cycle`` switches, and ``generators="m2d"`` / ``"d2m"`` to train one
      generator alone (separate training; then ``gw`` and ``cycle`` must be off).

Choices the paper leaves open (documented, not from the paper): decoders are trained with teacher forcing
(the cycle losses run on the teacher-forced outputs); G_M→D reads composed music as its MFCC blocks at their
training mean (zeros after normalisation) with the composed chroma + beat; embeddings for GW are the time
average of the encoder output.

Departures from the paper, each a switch (docs/DUAL.md): GW on L1 cost matrices divided by their mean with
the printed Algorithm 1's unit marginals (``gw_normalize="mean"``, ``gw_marginals="unit"``: the raw costs
of a training encoder are hundreds of times ε and the term was noise); the beat frames of L_X weighted 5×
(``beat_pos_weight``: with the plain L1 the sparse beat output collapsed to 0); Gaussian noise of std 0.1 on
G_M→D's teacher-forced decoder inputs (``decoder_noise``, against the freezing of teacher-forced decoders).
Against the flicker of the free-running G_M→D (docs/DUAL.md, "velocity term"): ``velocity_weight`` /
``accel_weight`` add L1 terms on the frame-to-frame first / second differences of the reconstructed dance
(:func:`dance_difference_loss`, on G_M→D's teacher-forced output, so they reach G_M→D only), and ``self_feed``
replaces a share of the decoder's inputs by its own detached predictions (scheduled sampling);
``rollout_frames`` / ``rollout_weight`` decode the first frames of each window free-running (fed back, with
gradients) and score their velocities and accelerations. All default to 0: the paper's objective.
``m2d_decoder="parallel"`` decodes each window of G_M→D in one pass instead of frame by frame: every decoder input
is the window's start pose (plus the latent and the position), the self-attention unmasked, so training and
inference run the same computation and there is no closed loop to drift (the autoregressive decoder, trained on
true previous frames, drifts into poses the training dances never hold when it is fed its own;
docs/research/dual-latent.md).
``DualConfig(beat_pos_weight=1, decoder_noise=0, gw_normalize="none", gw_marginals="uniform")`` is the paper.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
from torch import nn

from dancekit.errors import ParameterError
from dancekit.models.gromov import entropic_gromov_wasserstein
from dancekit.motion.rotations import rotation_6d_to_matrix

GENERATORS = ("both", "m2d", "d2m")
M2D_DECODERS = ("autoregressive", "parallel")
PITCH_CLASSES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
IDENTITY_6D = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)


@dataclass
class DualConfig:
    """Hyper-parameters of :class:`DualModel` (saved as ``config.json`` with the weights).

    The defaults are small enough to train on 2 CPU cores; :meth:`paper` gives §4.2's sizes (6 layers,
    8 heads, 512 hidden units for G_M→D and 256 for G_D→M).
    """

    music_dim: int = 53  # the `dual` preset
    pose_dim: int = 171  # rot6d of tang2018: 3 + 6 · 28 rig joints
    window: int = 75  # T, frames per window (3 s at 25 fps)
    music_raw_from: int = 40  # music columns [40, 53) = chroma (12) + beat (1): raw, and G_D→M's output
    dance_raw_from: int = 3  # dance columns [3, P) = 6D rotations: raw; [0, 3) = normalised root translation
    m2d_d_model: int = 128
    m2d_layers: int = 2
    m2d_heads: int = 4
    m2d_ff: int = 256
    d2m_d_model: int = 64
    d2m_layers: int = 2
    d2m_heads: int = 4
    d2m_ff: int = 128
    dropout: float = 0.1
    gw: bool = True  # Gromov-Wasserstein loss (Table 4 "GW")
    cycle: bool = True  # cycle consistency losses (Table 4 "CC")
    generators: str = "both"  # both | m2d | d2m: which generators are trained (one alone: separate training)
    gw_weight: float = 1.0
    cycle_weight: float = 1.0
    gw_epsilon: float = 0.2  # ε of Algorithm 1
    gw_sinkhorn_iters: int = 30  # L
    gw_projection_iters: int = 20  # M
    gw_normalize: str = "mean"  # L1 cost matrices divided by their mean (not the paper; "none": raw costs)
    gw_marginals: str = "unit"  # the printed Algorithm 1 (a = 1 ⊘ K b); "uniform": p = q = 1/m (Eq. 4)
    beat_pos_weight: float = 15.0  # weight of the beat frames in L_X's beat term (1: the paper's plain L1)
    decoder_noise: float = 0.1  # std of Gaussian noise on G_M→D's teacher-forced decoder inputs (0: the paper)
    pool_size: int = 64  # start poses kept from the training windows (sampled at inference)
    velocity_weight: float = 0.0  # weight of the L1 on frame-to-frame differences of G_M→D's output (0: the paper)
    accel_weight: float = 0.0  # weight of the L1 on second differences of G_M→D's output (0: the paper)
    self_feed: float = 0.0  # share of G_M→D's decoder inputs replaced by its own (detached) outputs (0: the paper)
    rollout_frames: int = 0  # frames G_M→D decodes free-running from each window's start in training (0: off)
    rollout_weight: float = 0.0  # weight of the velocity + acceleration L1 on that free-running rollout
    latent_dim: int = 0  # G_M→D's per-window dance latent z (a conditional VAE; 0: off, the paper)
    kl_weight: float = 0.05  # weight of KL(q(z | dance window) || N(0, I)) (with latent_dim > 0)
    kl_free_bits: float = 0.25  # nats per latent dimension below which the KL is not penalised
    m2d_decoder: str = "autoregressive"  # G_M→D's decoder: "autoregressive" (the paper) | "parallel" (below)
    posterior_position: bool = False  # q(z | window) reads each frame with its position in the window (else a bag)

    def __post_init__(self) -> None:
        for name in ("music_dim", "pose_dim", "m2d_d_model", "m2d_layers", "m2d_heads", "m2d_ff", "d2m_d_model",
                     "d2m_layers", "d2m_heads", "d2m_ff", "gw_sinkhorn_iters", "gw_projection_iters", "pool_size"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ParameterError(f"DualConfig.{name} must be a positive integer, got {value!r}")
        if not isinstance(self.window, int) or self.window < 2:
            raise ParameterError(f"DualConfig.window must be an integer >= 2, got {self.window!r}")
        if not 0 <= self.music_raw_from < self.music_dim:
            raise ParameterError(f"DualConfig.music_raw_from must be in [0, {self.music_dim}), got {self.music_raw_from}")
        if not 0 <= self.dance_raw_from < self.pose_dim or (self.pose_dim - self.dance_raw_from) % 6:
            raise ParameterError(f"DualConfig: pose_dim - dance_raw_from must be a positive multiple of 6 (6D "
                                 f"rotations), got {self.pose_dim} - {self.dance_raw_from}")
        for prefix in ("m2d", "d2m"):
            d, h = getattr(self, f"{prefix}_d_model"), getattr(self, f"{prefix}_heads")
            if d % h:
                raise ParameterError(f"DualConfig.{prefix}_d_model ({d}) must be divisible by {prefix}_heads ({h})")
        if self.generators not in GENERATORS:
            raise ParameterError(f"DualConfig.generators must be one of {GENERATORS}, got {self.generators!r}")
        if self.generators != "both" and (self.gw or self.cycle):
            raise ParameterError("separate training (generators='m2d' or 'd2m') needs gw=False and cycle=False: "
                                 "both losses need the other generator")
        if not 0.0 <= self.dropout < 1.0 or not self.gw_epsilon > 0:
            raise ParameterError("DualConfig.dropout must be in [0, 1) and gw_epsilon positive")
        if self.gw_normalize not in ("none", "mean") or self.gw_marginals not in ("uniform", "unit"):
            raise ParameterError(f"DualConfig.gw_normalize must be none|mean and gw_marginals uniform|unit, got "
                                 f"{self.gw_normalize!r}, {self.gw_marginals!r}")
        if isinstance(self.rollout_frames, bool) or not isinstance(self.rollout_frames, int) \
                or not 0 <= self.rollout_frames < self.window:
            raise ParameterError(f"DualConfig.rollout_frames must be an integer in [0, window), got "
                                 f"{self.rollout_frames!r}")
        for name in ("velocity_weight", "accel_weight", "rollout_weight"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise ParameterError(f"DualConfig.{name} must be a number >= 0, got {value!r}")
        if isinstance(self.self_feed, bool) or not isinstance(self.self_feed, (int, float)) \
                or not 0.0 <= self.self_feed <= 1.0:
            raise ParameterError(f"DualConfig.self_feed must be a share in [0, 1], got {self.self_feed!r}")
        if not isinstance(self.posterior_position, bool):
            raise ParameterError(f"DualConfig.posterior_position must be true or false, got {self.posterior_position!r}")
        if self.m2d_decoder not in M2D_DECODERS:
            raise ParameterError(f"DualConfig.m2d_decoder must be one of {M2D_DECODERS}, got {self.m2d_decoder!r}")
        if self.m2d_decoder == "parallel" and (self.self_feed > 0 or self.rollout_frames > 0):
            raise ParameterError("DualConfig: self_feed and rollout_frames train the autoregressive decoder's "
                                 "closed loop; the parallel decoder has none (set them to 0)")
        if isinstance(self.latent_dim, bool) or not isinstance(self.latent_dim, int) or self.latent_dim < 0:
            raise ParameterError(f"DualConfig.latent_dim must be an integer >= 0, got {self.latent_dim!r}")
        for name in ("kl_weight", "kl_free_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise ParameterError(f"DualConfig.{name} must be a number >= 0, got {value!r}")
        if not self.beat_pos_weight > 0 or not self.decoder_noise >= 0:
            raise ParameterError(f"DualConfig.beat_pos_weight must be positive and decoder_noise >= 0, got "
                                 f"{self.beat_pos_weight!r}, {self.decoder_noise!r}")

    @property
    def music_out_dim(self) -> int:
        """Columns G_D→M composes: chroma + beat (13)."""
        return self.music_dim - self.music_raw_from

    @classmethod
    def paper(cls, **overrides) -> DualConfig:
        """§4.2: 6 layers and 8 heads in both generators, 512 hidden units for G_M→D and 256 for G_D→M."""
        sizes = dict(m2d_d_model=512, m2d_layers=6, m2d_heads=8, m2d_ff=2048,
                     d2m_d_model=256, d2m_layers=6, d2m_heads=8, d2m_ff=1024)
        return cls(**{**sizes, **overrides})


# --------------------------------------------------------------------------------------------------
# losses


def geodesic_squared(R1: torch.Tensor, R2: torch.Tensor, *, eps: float = 1e-7) -> torch.Tensor:
    """Squared geodesic distance ``(...)`` between rotation matrices ``(..., 3, 3)`` (Eq. 8, squared).

    ``θ = atan2(|skew(R1 R2ᵀ)| / 2, (tr(R1 R2ᵀ) - 1) / 2)``, the same angle as Eq. 8's arccos but accurate
    and with finite gradients everywhere (the norm is smoothed by ``eps²``, which adds at most ``eps²``
    to θ² at θ = 0 and nothing measurable at θ = π).
    """
    R = R1 @ R2.transpose(-1, -2)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    skew = torch.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    sin = 0.5 * torch.sqrt((skew**2).sum(-1) + eps**2)
    return torch.atan2(sin, 0.5 * (tr - 1.0)) ** 2


def dance_loss(pred: torch.Tensor, target: torch.Tensor, *, raw_from: int = 3) -> torch.Tensor:
    """L_Y (Eq. 7): per frame, L1 of the translation ``[:raw_from]`` + Σ_joints geodesic² of the 6D rotations
    ``[raw_from:]``; averaged over batch and frames. ``pred``, ``target``: (B, T, P)."""
    trans = (pred[..., :raw_from] - target[..., :raw_from]).abs().sum(-1)  # (B, T)
    shape = pred.shape[:-1] + (-1, 6)
    R1 = rotation_6d_to_matrix(pred[..., raw_from:].reshape(shape))  # (B, T, J, 3, 3)
    R2 = rotation_6d_to_matrix(target[..., raw_from:].reshape(shape))
    return (trans + geodesic_squared(R1, R2).sum(-1)).mean()


def dance_difference_loss(pred: torch.Tensor, target: torch.Tensor, *, order: int = 1) -> torch.Tensor:
    """L1 between the ``order``-th frame-to-frame differences of ``pred`` and ``target`` (B, T, P) (not the paper).

    ``order=1``: velocities ``y_t - y_{t-1}``, ``order=2``: accelerations ``y_t - 2 y_{t-1} + y_{t-2}``, of every
    column (the normalised root translation and the raw 6D rotation components, per frame at the data's fps),
    summed over the columns of a frame and averaged over the ``T - order`` differences of each window and the
    batch. L_Y scores each frame alone, so a prediction that flickers around the right poses costs as little as a
    smooth one; this term makes the flicker cost what it moves. 0 when ``T <= order``.
    """
    if pred.shape[-2] <= order:
        return pred.new_zeros(())
    dp, dt = pred, target
    for _ in range(order):
        dp, dt = dp[..., 1:, :] - dp[..., :-1, :], dt[..., 1:, :] - dt[..., :-1, :]
    return (dp - dt).abs().sum(-1).mean()


def music_loss(pred: torch.Tensor, target: torch.Tensor, *, beat_pos_weight: float = 1.0) -> torch.Tensor:
    """L_X (Eq. 9): per frame, L1 of the 12 chroma + L1 of the beat; averaged over batch and frames.
    ``pred``, ``target``: (B, T, 13).

    ``beat_pos_weight`` multiplies the beat term on the beat frames (target beat ≥ 0.5). Beats are sparse
    (about 5 % of the frames of tang2018), and the plain L1 (weight 1, the paper) is minimised by a beat
    output of 0 everywhere unless a frame is a beat with probability above 1/2: G_D→M then composes no beats
    at all. With weight w a frame is worth marking when its beat probability exceeds 1 / (1 + w).
    """
    err = (pred - target).abs()  # (B, T, 13)
    if beat_pos_weight != 1.0:
        w = torch.where(target[..., -1] >= 0.5, beat_pos_weight, 1.0)  # (B, T)
        return (err[..., :-1].sum(-1) + w * err[..., -1]).mean()
    return err.sum(-1).mean()


def chord_token(root: int | str, minor: bool = False) -> torch.Tensor:
    """The music start token of a chord: a 12-d chroma with 1 on the triad's pitch classes + beat 0 → (13,).

    ``root``: a pitch class 0..11 (C = 0) or its name (``"F#"``); ``minor``: minor instead of major third.
    """
    if isinstance(root, str):
        if root not in PITCH_CLASSES:
            raise ParameterError(f"unknown chord root {root!r}; choose one of {', '.join(PITCH_CLASSES)}")
        root = PITCH_CLASSES.index(root)
    if not 0 <= int(root) < 12:
        raise ParameterError(f"chord root must be a pitch class 0..11, got {root!r}")
    token = torch.zeros(13)
    for interval in (0, 3 if minor else 4, 7):
        token[(int(root) + interval) % 12] = 1.0
    return token


# --------------------------------------------------------------------------------------------------
# one generator


def sinusoidal_encoding(n: int, d: int, *, device=None, dtype=torch.float32) -> torch.Tensor:
    """Vaswani et al.'s positional encoding → (n, d)."""
    pos = torch.arange(n, dtype=torch.float64, device=device)[:, None]
    div = torch.exp(torch.arange(0, d, 2, dtype=torch.float64, device=device) * (-math.log(10000.0) / d))
    pe = torch.zeros(n, d, dtype=torch.float64, device=device)
    pe[:, 0::2] = torch.sin(pos * div)
    pe[:, 1::2] = torch.cos(pos * div)[:, : d // 2]
    return pe.to(dtype)


class Seq2Seq(nn.Module):
    """Transformer encoder (full self-attention) + autoregressive transformer decoder: (B, T, in) → (B, T, out)."""

    def __init__(self, in_dim: int, out_dim: int, *, d_model: int, layers: int, heads: int, ff: int,
                 dropout: float, sigmoid: bool = False):
        super().__init__()
        self.out_dim, self.sigmoid = out_dim, sigmoid
        self.src_embed = nn.Linear(in_dim, d_model)
        self.tgt_embed = nn.Linear(out_dim, d_model)
        self.encoder = nn.TransformerEncoder(
            nn.TransformerEncoderLayer(d_model, heads, ff, dropout, batch_first=True, norm_first=True),
            layers, norm=nn.LayerNorm(d_model), enable_nested_tensor=False)
        self.decoder = nn.TransformerDecoder(
            nn.TransformerDecoderLayer(d_model, heads, ff, dropout, batch_first=True, norm_first=True),
            layers, norm=nn.LayerNorm(d_model))
        self.head = nn.Linear(d_model, out_dim)

    def encode(self, src: torch.Tensor) -> torch.Tensor:
        """(B, T, in) → memory (B, T, d), full (unmasked) self-attention."""
        x = self.src_embed(src)  # (B, T, d)
        x = x + sinusoidal_encoding(x.shape[1], x.shape[2], device=x.device, dtype=x.dtype)
        return self.encoder(x)

    def decode(self, prev: torch.Tensor, memory: torch.Tensor, cond: torch.Tensor | None = None, *,
               causal: bool = True) -> torch.Tensor:
        """Decoder inputs ``prev (B, L, out)`` (start token first) → next frames (B, L, out), causally
        (``causal=False``: every input attends to every other, :meth:`parallel`'s decoding).
        ``cond (B, d)``, if given, is added to every input embedding (G_M→D's projected latent)."""
        L = prev.shape[1]
        x = self.tgt_embed(prev)  # (B, L, d)
        if cond is not None:
            x = x + cond[:, None, :]
        x = x + sinusoidal_encoding(L, x.shape[2], device=x.device, dtype=x.dtype)
        mask = torch.triu(torch.full((L, L), float("-inf"), device=x.device, dtype=x.dtype), diagonal=1) \
            if causal else None
        y = self.head(self.decoder(x, memory, tgt_mask=mask))  # (B, L, out)
        return torch.sigmoid(y) if self.sigmoid else y

    def parallel(self, memory: torch.Tensor, start: torch.Tensor, n: int, cond: torch.Tensor | None = None, *,
                 noise: float = 0.0) -> torch.Tensor:
        """A window decoded in one pass: ``start (B, out)`` then ``n - 1`` frames, each from the start pose at its
        position (plus ``cond``) over ``memory (B, T, d)`` → (B, n, out). No frame is fed back, so training and
        inference are the same computation. ``noise``: Gaussian noise of that std on the start pose the decoder
        reads (training only), as :meth:`teacher_forced`'s on its inputs."""
        given = start[:, None, :].expand(start.shape[0], n - 1, start.shape[1])  # (B, n-1, out)
        if noise > 0 and self.training:
            given = given + noise * torch.randn_like(start)[:, None, :]
        return torch.cat([start[:, None, :], self.decode(given, memory, cond, causal=False)], dim=1)

    def teacher_forced(self, src: torch.Tensor, tgt: torch.Tensor, memory: torch.Tensor | None = None, *,
                       noise: float = 0.0, cond: torch.Tensor | None = None) -> torch.Tensor:
        """Training output ``[tgt_0, ŷ_1..ŷ_{T-1}]`` (B, T, out): the start token is the first target frame,
        ``ŷ_t`` is predicted from ``tgt_0..tgt_{t-1}`` (plus Gaussian noise of std ``noise`` in training: the
        decoder learns to recover from its own small errors instead of copying its input) and the whole
        source window."""
        memory = self.encode(src) if memory is None else memory
        prev = tgt[:, :-1]
        if noise > 0 and self.training:
            prev = prev + noise * torch.randn_like(prev)
        return torch.cat([tgt[:, :1], self.decode(prev, memory, cond)], dim=1)

    def generate(self, src: torch.Tensor, start: torch.Tensor, cond: torch.Tensor | None = None,
                 given: torch.Tensor | None = None) -> torch.Tensor:
        """Autoregressive output for one window: ``start (B, out)`` then T - 1 generated frames → (B, T, out)
        (``given``: :meth:`rollout`'s).

        Incremental decoding: each layer keeps the normalised inputs of the frames decoded so far (its
        self-attention keys and values), so a new frame costs one query per layer instead of a pass over the
        whole prefix. The same numbers as :meth:`decode` on the prefix (tests/models/test_dual.py), in eval mode.
        """
        return self.rollout(self.encode(src), start, src.shape[1], cond, given)

    def rollout(self, memory: torch.Tensor, start: torch.Tensor, n: int,
                cond: torch.Tensor | None = None, given: torch.Tensor | None = None) -> torch.Tensor:
        """Free-running decoding from ``start (B, out)`` over ``memory (B, T, d)``: ``start`` then ``n - 1``
        frames, each fed back as the next input → (B, n, out). Differentiable (used in training by
        ``DualConfig.rollout_frames``); :meth:`generate` is this after encoding. ``given (B, G, out)``: frames
        ``1 … G - 1`` are those (each decoded, then replaced: the next input is the given frame, so the
        self-attention's context holds them); ``given[:, 0]`` is ``start``'s place."""
        d = memory.shape[2]
        pe = sinusoidal_encoding(n, d, device=memory.device, dtype=memory.dtype)  # (n, d)
        caches: list[torch.Tensor | None] = [None] * len(self.decoder.layers)
        frames = [start[:, None, :]]  # (B, 1, out) each
        for t in range(n - 1):
            h = self.tgt_embed(frames[-1]) + pe[t]  # (B, 1, d)
            if cond is not None:
                h = h + cond[:, None, :]
            for i, layer in enumerate(self.decoder.layers):
                hn = layer.norm1(h)
                caches[i] = hn if caches[i] is None else torch.cat([caches[i], hn], dim=1)  # (B, t + 1, d)
                h = h + layer.dropout1(layer.self_attn(hn, caches[i], caches[i], need_weights=False)[0])
                hn = layer.norm2(h)
                h = h + layer.dropout2(layer.multihead_attn(hn, memory, memory, need_weights=False)[0])
                h = h + layer._ff_block(layer.norm3(h))
            y = self.head(self.decoder.norm(h))  # (B, 1, out)
            y = torch.sigmoid(y) if self.sigmoid else y
            frames.append(given[:, t + 1 : t + 2] if given is not None and t + 1 < given.shape[1] else y)
        return torch.cat(frames, dim=1)

    @torch.no_grad()
    def rollout_cached(self, memory: torch.Tensor, start: torch.Tensor, n: int) -> torch.Tensor:
        """:meth:`rollout` for inference (eval mode, no gradient), faster: the cross-attention keys and values
        of ``memory`` are projected once per layer, and each new frame's self-attention key and value are
        projected once and appended to a per-layer cache (:meth:`rollout` re-projects the whole prefix and the
        whole memory at every frame). The same function to float rounding (tests/pipelines/test_compose.py);
        :meth:`rollout_numpy` is it in NumPy."""
        import torch.nn.functional as F

        B, _, d = memory.shape
        layers = list(self.decoder.layers)
        H = layers[0].self_attn.num_heads
        dh = d // H
        pe = sinusoidal_encoding(n, d, device=memory.device, dtype=memory.dtype)

        def heads(x: torch.Tensor) -> torch.Tensor:  # (B, L, d) -> (B, H, L, dh)
            return x.view(B, -1, H, dh).transpose(1, 2)

        cross = []
        for layer in layers:
            w, b = layer.multihead_attn.in_proj_weight, layer.multihead_attn.in_proj_bias
            cross.append((heads(F.linear(memory, w[d:2 * d], b[d:2 * d])), heads(F.linear(memory, w[2 * d:], b[2 * d:]))))
        keys = [memory.new_zeros(B, H, n, dh) for _ in layers]
        values = [memory.new_zeros(B, H, n, dh) for _ in layers]
        frames = [start[:, None, :]]
        for t in range(n - 1):
            h = self.tgt_embed(frames[-1]) + pe[t]  # (B, 1, d)
            for i, layer in enumerate(layers):
                sa = layer.self_attn
                q, k, v = F.linear(layer.norm1(h), sa.in_proj_weight, sa.in_proj_bias).split(d, dim=-1)
                keys[i][:, :, t: t + 1], values[i][:, :, t: t + 1] = heads(k), heads(v)
                a = F.scaled_dot_product_attention(heads(q), keys[i][:, :, : t + 1], values[i][:, :, : t + 1])
                h = h + sa.out_proj(a.transpose(1, 2).reshape(B, 1, d))
                ca = layer.multihead_attn
                qc = F.linear(layer.norm2(h), ca.in_proj_weight[:d], ca.in_proj_bias[:d])
                a = F.scaled_dot_product_attention(heads(qc), *cross[i])
                h = h + ca.out_proj(a.transpose(1, 2).reshape(B, 1, d))
                h = h + layer._ff_block(layer.norm3(h))
            y = self.head(self.decoder.norm(h))
            frames.append(torch.sigmoid(y) if self.sigmoid else y)
        return torch.cat(frames, dim=1)

    @torch.no_grad()
    def rollout_numpy(self, memory: torch.Tensor, start: torch.Tensor, n: int) -> torch.Tensor:
        """:meth:`rollout_cached` in NumPy float32 (inference on the CPU, eval mode): the same projections,
        caches and attention, each frame a few dozen NumPy products on (B, d) rows instead of torch calls, whose
        per-call overhead is most of the cost at G_D→M's width. The same function to float rounding
        (tests/models/test_dual.py); G_D→M's composing uses it (:meth:`DualModel.generate_music`)."""
        def a32(t: torch.Tensor) -> np.ndarray:
            return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=np.float32)

        mem = a32(memory)  # (B, T, d)
        B, T, d = mem.shape
        layers = list(self.decoder.layers)
        H = layers[0].self_attn.num_heads
        dh = d // H
        scale = np.float32(1.0 / math.sqrt(dh))
        pe = a32(sinusoidal_encoding(n, d))  # (n, d)

        def norm(mod: nn.LayerNorm):
            return a32(mod.weight), a32(mod.bias), np.float32(mod.eps)

        mean = np.full((d, 1), 1.0 / d, np.float32)  # a row's mean as a product (cheaper than ndarray.mean here)

        def layer_norm(x: np.ndarray, p) -> np.ndarray:
            c = x - x @ mean
            return c / np.sqrt((c * c) @ mean + p[2]) * p[0] + p[1]

        def attend(q: np.ndarray, k: np.ndarray, v: np.ndarray) -> np.ndarray:  # (B, H, 1, dh), (B, H, L, dh) x 2
            s = (q @ k.transpose(0, 1, 3, 2)) * scale  # (B, H, 1, L)
            s = np.exp(s - np.maximum.reduce(s, axis=-1, keepdims=True))
            return ((s / np.add.reduce(s, axis=-1, keepdims=True)) @ v).reshape(B, d)  # (B, d)

        params = []
        for layer in layers:
            sa, ca = layer.self_attn, layer.multihead_attn
            w, b = a32(ca.in_proj_weight), a32(ca.in_proj_bias)
            kc = (mem @ w[d:2 * d].T + b[d:2 * d]).reshape(B, T, H, dh).transpose(0, 2, 1, 3)  # (B, H, T, dh)
            vc = (mem @ w[2 * d:].T + b[2 * d:]).reshape(B, T, H, dh).transpose(0, 2, 1, 3)
            params.append(dict(n1=norm(layer.norm1), n2=norm(layer.norm2), n3=norm(layer.norm3),
                               qkv=(a32(sa.in_proj_weight).T.copy(), a32(sa.in_proj_bias)),
                               out=(a32(sa.out_proj.weight).T.copy(), a32(sa.out_proj.bias)),
                               qc=(w[:d].T.copy(), b[:d]), kc=kc, vc=vc,
                               outc=(a32(ca.out_proj.weight).T.copy(), a32(ca.out_proj.bias)),
                               ff1=(a32(layer.linear1.weight).T.copy(), a32(layer.linear1.bias)),
                               ff2=(a32(layer.linear2.weight).T.copy(), a32(layer.linear2.bias)),
                               keys=np.zeros((B, H, n, dh), np.float32), values=np.zeros((B, H, n, dh), np.float32)))
        emb = (a32(self.tgt_embed.weight).T.copy(), a32(self.tgt_embed.bias))
        head = (a32(self.head.weight).T.copy(), a32(self.head.bias))
        final = norm(self.decoder.norm)
        frames = [a32(start)]  # (B, out) each
        for t in range(n - 1):
            h = frames[-1] @ emb[0] + emb[1] + pe[t]  # (B, d)
            for p in params:
                qkv = layer_norm(h, p["n1"]) @ p["qkv"][0] + p["qkv"][1]  # (B, 3d)
                q, k, v = qkv[:, :d], qkv[:, d: 2 * d], qkv[:, 2 * d:]
                p["keys"][:, :, t], p["values"][:, :, t] = k.reshape(B, H, dh), v.reshape(B, H, dh)
                a = attend(q.reshape(B, H, 1, dh), p["keys"][:, :, : t + 1], p["values"][:, :, : t + 1])
                h = h + a @ p["out"][0] + p["out"][1]
                qc = layer_norm(h, p["n2"]) @ p["qc"][0] + p["qc"][1]
                h = h + attend(qc.reshape(B, H, 1, dh), p["kc"], p["vc"]) @ p["outc"][0] + p["outc"][1]
                f = np.maximum(layer_norm(h, p["n3"]) @ p["ff1"][0] + p["ff1"][1], 0.0)
                h = h + f @ p["ff2"][0] + p["ff2"][1]
            y = layer_norm(h, final) @ head[0] + head[1]
            frames.append(1.0 / (1.0 + np.exp(-y)) if self.sigmoid else y)
        return torch.from_numpy(np.stack(frames, axis=1)).to(memory.dtype)

    def generate_full(self, src: torch.Tensor, start: torch.Tensor, cond: torch.Tensor | None = None) -> torch.Tensor:
        """:meth:`generate` by re-decoding the whole prefix at every step (the reference for its tests)."""
        memory = self.encode(src)  # (B, T, d)
        out = start[:, None, :]  # (B, 1, out)
        for _ in range(src.shape[1] - 1):
            nxt = self.decode(out, memory, cond)[:, -1:]  # (B, 1, out)
            out = torch.cat([out, nxt], dim=1)
        return out


# --------------------------------------------------------------------------------------------------
# the model


class DualModel(nn.Module):
    """G_M→D (music (B, T, 53) → dance (B, T, P)) and G_D→M (dance → chroma + beat (B, T, 13)).

    Examples
    --------
    >>> cfg = DualConfig(music_dim=17, music_raw_from=4, pose_dim=15, window=8, m2d_d_model=16, m2d_heads=2,
    ...                  m2d_ff=32, d2m_d_model=8, d2m_heads=2, d2m_ff=16, m2d_layers=1, d2m_layers=1)
    >>> model = DualModel(cfg)
    >>> music, dance = torch.randn(4, 8, 17), torch.randn(4, 8, 15)
    >>> loss, parts = model(music, dance)
    >>> sorted(parts)
    ['dance_cycle', 'dance_rec', 'gw', 'music_cycle', 'music_rec']
    >>> model.generate_dance(music[:1, :20], start=dance[:1, 0]).shape
    torch.Size([1, 8, 15])
    """

    family: ClassVar[str] = "dual"

    def __init__(self, config: DualConfig):
        super().__init__()
        self.config = c = config
        self.m2d = Seq2Seq(c.music_dim, c.pose_dim, d_model=c.m2d_d_model, layers=c.m2d_layers, heads=c.m2d_heads,
                           ff=c.m2d_ff, dropout=c.dropout)
        self.d2m = Seq2Seq(c.pose_dim, c.music_out_dim, d_model=c.d2m_d_model, layers=c.d2m_layers,
                           heads=c.d2m_heads, ff=c.d2m_ff, dropout=c.dropout, sigmoid=True)
        if c.latent_dim > 0:
            # q(z | dance window): the window's frames embedded, averaged over time, → (mu, log variance)
            self.m2d_posterior = nn.Sequential(nn.Linear(c.pose_dim, c.m2d_d_model), nn.GELU(),
                                               nn.Linear(c.m2d_d_model, 2 * c.latent_dim))
            self.m2d_latent = nn.Linear(c.latent_dim, c.m2d_d_model)  # z → the decoder's input space
        # start poses of training windows (a ring buffer, saved with the weights), sampled at inference
        self.register_buffer("pose_pool", torch.zeros(c.pool_size, c.pose_dim))
        self.register_buffer("pool_count", torch.zeros((), dtype=torch.long))

    # ---- losses -----------------------------------------------------------------------------------

    def music_from_composed(self, composed: torch.Tensor) -> torch.Tensor:
        """G_M→D's input for composed music (B, T, 13): MFCC blocks at their mean (0), chroma + beat composed."""
        pad = composed.new_zeros(composed.shape[:-1] + (self.config.music_raw_from,))
        return torch.cat([pad, composed], dim=-1)  # (B, T, music_dim)

    def forward(self, music: torch.Tensor, dance: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """All losses of one batch of windows, routed to the generators as the paper prescribes.

        Parameters
        ----------
        music : (B, T, music_dim) features, columns ``[music_raw_from:]`` raw chroma + beat (the music target)
        dance : (B, T, pose_dim) rot6d, translation normalised, 6D raw

        Returns
        -------
        loss : the weighted sum of the enabled losses
        parts : each enabled loss (``dance_rec``, ``music_rec``, ``gw``, ``dance_cycle``, ``music_cycle``)
        """
        c = self.config
        self._check(music, dance)
        target_music = music[..., c.music_raw_from:]  # (B, T, 13)
        parts: dict[str, torch.Tensor] = {}
        if c.generators in ("both", "m2d"):
            memory_x = self.m2d.encode(music)  # (B, T, d_x)
            cond = None
            if c.latent_dim > 0:
                cond, parts["kl"] = self._posterior(dance)  # (B, d_x), scalar
            dance_in = self._self_fed(dance, memory_x, cond) if c.self_feed > 0 and self.training else dance
            dance_hat = self._m2d_predict(music, dance_in, memory_x, cond)  # (B, T, P)
            parts["dance_rec"] = dance_loss(dance_hat, dance, raw_from=c.dance_raw_from)
            if c.velocity_weight > 0:
                parts["dance_vel"] = dance_difference_loss(dance_hat, dance, order=1)
            if c.accel_weight > 0:
                parts["dance_acc"] = dance_difference_loss(dance_hat, dance, order=2)
            if c.rollout_frames > 0 and c.rollout_weight > 0 and self.training:
                # the closed loop of inference: frames fed back, scored on their first and second differences
                roll = self.m2d.rollout(memory_x, dance[:, 0], c.rollout_frames + 1, cond)  # (B, K + 1, P)
                truth = dance[:, : c.rollout_frames + 1]
                parts["dance_roll"] = dance_difference_loss(roll, truth, order=1) + \
                    dance_difference_loss(roll, truth, order=2)
        if c.generators in ("both", "d2m"):
            memory_y = self.d2m.encode(dance)  # (B, T, d_y)
            music_hat = self.d2m.teacher_forced(dance, target_music, memory_y)  # (B, T, 13)
            parts["music_rec"] = music_loss(music_hat, target_music, beat_pos_weight=c.beat_pos_weight)
        if c.gw:  # reaches Enc_M→D only
            z_x, z_y = memory_x.mean(1), memory_y.mean(1).detach()  # (B, d_x), (B, d_y)
            parts["gw"] = entropic_gromov_wasserstein(
                z_x, z_y, epsilon=c.gw_epsilon, sinkhorn_iters=c.gw_sinkhorn_iters,
                projection_iters=c.gw_projection_iters, normalize=c.gw_normalize, marginals=c.gw_marginals)
        if c.cycle:
            # dance cycle G_M→D(G_D→M(y)) updates G_M→D; music cycle G_D→M(G_M→D(x)) updates G_D→M
            dance_cyc = self._m2d_predict(self.music_from_composed(music_hat.detach()), dance, None, cond)
            parts["dance_cycle"] = dance_loss(dance_cyc, dance, raw_from=c.dance_raw_from)
            music_cyc = self.d2m.teacher_forced(dance_hat.detach(), target_music)
            parts["music_cycle"] = music_loss(music_cyc, target_music, beat_pos_weight=c.beat_pos_weight)
        weights = {"gw": c.gw_weight, "dance_cycle": c.cycle_weight, "music_cycle": c.cycle_weight,
                   "dance_vel": c.velocity_weight, "dance_acc": c.accel_weight, "dance_roll": c.rollout_weight,
                   "kl": c.kl_weight}
        loss = sum(weights.get(k, 1.0) * v for k, v in parts.items())
        return loss, parts

    def _m2d_predict(self, music: torch.Tensor, dance: torch.Tensor, memory: torch.Tensor | None,
                     cond: torch.Tensor | None) -> torch.Tensor:
        """G_M→D's training output for ``dance (B, T, P)`` over ``music`` (its encoding ``memory`` if given):
        teacher-forced, or in one pass from the window's first frame (``m2d_decoder="parallel"``)."""
        c = self.config
        if c.m2d_decoder == "parallel":
            memory = self.m2d.encode(music) if memory is None else memory
            return self.m2d.parallel(memory, dance[:, 0], dance.shape[1], cond, noise=c.decoder_noise)
        return self.m2d.teacher_forced(music, dance, memory, noise=c.decoder_noise, cond=cond)

    def _posterior(self, dance: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The latent of each window, sampled from q(z | dance (B, T, P)) by reparameterisation, projected to the
        decoder's width → (B, d_x), and the KL to N(0, I) (free bits: each dimension's batch-mean KL below
        ``kl_free_bits`` nats costs nothing, so the decoder is not pushed to ignore z). ``posterior_position``: each
        frame's hidden features get its position in the window (sinusoidal) before the average over time."""
        c = self.config
        first, act, last = self.m2d_posterior
        h = first(dance)  # (B, T, d); without positions a bag of frames: the same z for them in any order
        if c.posterior_position:  # each frame's features with its place in the window: z can say when
            h = h + sinusoidal_encoding(h.shape[1], h.shape[2], device=h.device, dtype=h.dtype)
        mu, logvar = last(act(h)).mean(1).chunk(2, dim=-1)  # (B, Z) each
        logvar = logvar.clamp(-8.0, 8.0)
        z = mu + torch.exp(0.5 * logvar) * torch.randn_like(mu) if self.training else mu
        kl = 0.5 * (mu.pow(2) + logvar.exp() - 1.0 - logvar).mean(0)  # (Z,) nats
        return self.m2d_latent(z), kl.clamp(min=c.kl_free_bits).sum()

    @torch.no_grad()
    def _self_fed(self, dance: torch.Tensor, memory_x: torch.Tensor, cond: torch.Tensor | None = None) -> torch.Tensor:
        """Scheduled sampling in one extra pass (not the paper): G_M→D's teacher-forced prediction of ``dance``
        (B, T, P), detached, replaces each frame t ≥ 1 of the decoder input with probability ``self_feed``, so the
        decoder also learns from inputs that carry its own errors. Frame 0 (the start token) stays true."""
        pred = self.m2d.decode(dance[:, :-1], memory_x, cond)  # (B, T-1, P): ŷ_1..ŷ_{T-1}
        use = torch.rand(dance.shape[0], dance.shape[1] - 1, 1, device=dance.device) < self.config.self_feed
        return torch.cat([dance[:, :1], torch.where(use, pred, dance[:, 1:])], dim=1)

    @torch.no_grad()
    def remember_start_poses(self, dance: torch.Tensor) -> None:
        """Add the first frames of training windows ``dance (B, T, P)`` to the start-pose pool (a ring buffer)."""
        n = self.pose_pool.shape[0]
        for pose in dance[:, 0]:
            self.pose_pool[int(self.pool_count) % n] = pose
            self.pool_count += 1

    def sample_start_pose(self, generator: torch.Generator | None = None) -> torch.Tensor:
        """A start pose (P,) drawn from the pool with ``generator`` (the rest pose at the mean translation if the
        pool is empty)."""
        filled = min(int(self.pool_count), self.pose_pool.shape[0])
        if filled == 0:
            pose = torch.zeros(self.config.pose_dim, device=self.pose_pool.device)
            pose[self.config.dance_raw_from:] = torch.tensor(IDENTITY_6D).repeat(
                (self.config.pose_dim - self.config.dance_raw_from) // 6)
            return pose
        k = int(torch.randint(filled, (1,), generator=generator))
        return self.pose_pool[k].clone()

    # ---- inference ----------------------------------------------------------------------------------

    @torch.no_grad()
    def generate_dance(self, music: torch.Tensor, *, start: torch.Tensor,
                       generator: torch.Generator | None = None, prefix: torch.Tensor | None = None) -> torch.Tensor:
        """Dance for music of any length: ``music (B, n, music_dim)``, ``start (B, P)`` → (B, n, P).

        With a latent (``latent_dim > 0``) each window's z is drawn from N(0, I) with ``generator`` (one draw
        per window and batch row, in order), so each seed dances its own choices through the whole song.
        ``prefix (B, N, P)``: the dance's first N frames (``prefix[:, 0]`` in ``start``'s place), fed to the
        decoder as its previous frames (:meth:`Seq2Seq.rollout`'s ``given``), the dance continuing from the last."""
        return self._generate(self.m2d, music, start, generator=generator, latent=self.config.latent_dim > 0,
                              prefix=prefix)

    @torch.no_grad()
    def generate_music(self, dance: torch.Tensor, *, start: torch.Tensor) -> torch.Tensor:
        """Chroma + beat for a dance of any length: ``dance (B, n, P)``, ``start (B, 13)`` → (B, n, 13)."""
        return self._generate(self.d2m, dance, start, cached=True)

    def _generate(self, net: Seq2Seq, src: torch.Tensor, start: torch.Tensor, *, cached: bool = False,
                  generator: torch.Generator | None = None, latent: bool = False,
                  prefix: torch.Tensor | None = None) -> torch.Tensor:
        """Windows of T frames overlapping by one; each starts from the last generated frame of the previous.
        ``cached``: decode with :meth:`Seq2Seq.rollout_numpy` (G_D→M) instead of :meth:`Seq2Seq.generate`.

        Runs on one torch thread (restored after): the incremental decoding's attention rounds differently
        with 2 threads than with 1 (1e-6 of a unit per window on the embedded model), and one thread is as fast
        for its one-frame products (and much faster on a busy CPU), so the dance does not depend on the
        thread count."""
        was_training = self.training
        threads = torch.get_num_threads()
        self.eval()
        torch.set_num_threads(1)
        try:
            B, n, _ = src.shape
            T = self.config.window
            if n == 0:
                return src.new_zeros(B, 0, net.out_dim)
            if prefix is not None:
                if cached or prefix.ndim != 3 or prefix.shape[0] != B or prefix.shape[2] != net.out_dim:
                    raise ParameterError(f"a prefix must be ({B}, N, {net.out_dim}) for the dance decoder, got "
                                         f"{tuple(prefix.shape)}")
                start = prefix[:, 0]
            out, s, prev = [start[:, None, :]], 0, start
            parallel = net is self.m2d and self.config.m2d_decoder == "parallel"
            while s + 1 < n:
                chunk = src[:, s: s + T]  # (B, ≤T, in)
                cond = None
                if latent:
                    z = torch.randn(B, self.config.latent_dim, generator=generator)  # (B, Z) from the prior
                    cond = self.m2d_latent(z.to(src.device, src.dtype))  # (B, d)
                given = prefix[:, s : s + T] if prefix is not None and s + 1 < prefix.shape[1] else None
                if parallel and given is not None:
                    raise ParameterError("the parallel decoder of G_M→D cannot continue a prefix frame by frame")
                y = (net.parallel(net.encode(chunk), prev, chunk.shape[1], cond) if parallel
                     else net.rollout_numpy(net.encode(chunk), prev, chunk.shape[1]) if cached
                     else net.generate(chunk, prev, cond) if given is None
                     else net.generate(chunk, prev, cond, given))  # (B, ≤T, out)
                out.append(y[:, 1:])
                prev, s = y[:, -1], s + chunk.shape[1] - 1
            return torch.cat(out, dim=1)
        finally:
            torch.set_num_threads(threads)
            self.train(was_training)

    def _check(self, music: torch.Tensor, dance: torch.Tensor) -> None:
        c = self.config
        if music.ndim != 3 or music.shape[2] != c.music_dim:
            raise ParameterError(f"music must have shape (B, T, {c.music_dim}), got {tuple(music.shape)}")
        if dance.ndim != 3 or dance.shape[0] != music.shape[0] or dance.shape[1] != music.shape[1] \
                or dance.shape[2] != c.pose_dim:
            raise ParameterError(f"dance must have shape {tuple(music.shape[:2]) + (c.pose_dim,)}, got "
                                 f"{tuple(dance.shape)}")

    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)
