"""Music2Dance (Zhuang et al. 2020, §4.4): a WaveNet that dances, conditioned on mapped music and the dance type.

One file, one model: :class:`Music2DanceConfig` (a dataclass saved with the weights) and
:class:`Music2DanceModel` (an ``nn.Module(config)``); :func:`gmm_nll` and :func:`gmm_sample` are its
output distribution.

Architecture (paper §4.4.2–4.4.3, supplement §1.2.1)
    * Music feature mapping ``h_m = F_map(x_m)`` (:class:`MusicFeatureMap`): the trunk of the music attribute
      classifier (:mod:`dancekit.models.music_attributes`: three temporal convolutions, the third with
      stride 2, and a BiLSTM, without its last layer). Its stride-2 output is repeated twice along time
      (nearest-neighbour upsampling), so ``h_m`` has one vector per motion frame. Its weights can come from
      a trained classifier (``fmap_checkpoint``, loaded by the training objective) and be frozen
      (``fmap_frozen``) or fine-tuned. ``music_condition="raw"`` is the paper's ablation (§5.2): the
      normalised music features themselves are the local condition.
    * WaveNet generator (``generator="wavenet"``): the input motion ``x_{t-1}`` (dropout ``input_dropout`` in
      training) → a 1x1 convolution to ``channels`` → ``n_layers`` residual blocks, block ``l`` a causal
      convolution (kernel ``kernel``, dilation ``2^(l mod (max_dilation_exp + 1))``: 1, 2, 4, 8, 16, 1, ...)
      plus the local condition (a 1x1 projection of ``h_m``) plus the global condition (a projection of the
      dance-type embedding), a gated activation ``tanh(f) * sigmoid(g)``, a 1x1 residual and a 1x1 skip
      output → ReLU → 1x1 → ReLU → 1x1 → the output parameters. Xavier-normal initialisation.
    * Output (Eq. 7–8): a diagonal Gaussian mixture of ``n_mixtures`` components over the motion vector
      without its last ``contact_dim`` columns (rotations, root and end effectors), ``ω`` by softmax, the
      variance ``Σ = exp(σ̂)``, and foot-contact logits for the last ``contact_dim`` columns.
    * Loss (Eq. 9–11): ``L_gmm + λ · BCE`` with λ = ``contact_weight`` (0.1), divided by the number of
      mixture dimensions D (the same optimum and balance as the paper's; the scale suits the generic
      trainer's gradient clipping).
    * The paper's baseline (``generator="lstm"``): the mapped music merged with the motion as the input of
      an LSTM (Fragkiadaki et al.; Martinez et al.), the same output head.

Generation (:meth:`Music2DanceModel.generate`) is incremental: each WaveNet layer keeps a queue of its last
``dilation · (kernel - 1)`` inputs, so a new frame costs O(layers), not O(receptive field), and equals the
full-sequence evaluation (``tests/models/test_music2dance.py``). The frame loop runs in NumPy
(:class:`NumpyWaveNet`: the same products, a small NumPy operation costs about a microsecond where a torch
call costs several, and a frame is some 250 of them); :meth:`Music2DanceModel.step` is the torch reference.

The motion vector is the ``rotations_rootdelta`` representation (:mod:`dancekit.motion.root_delta`) with
its columns normalised, except the contact flags, which stay 0/1 (the dataset builder and the pipeline
see to that). Dance types: ``genre`` indices ``0..n_genres-1``; ``-1`` (or ``None``) is "no type", a
learned embedding of its own.
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

GENERATORS = ("wavenet", "lstm")
MUSIC_CONDITIONS = ("fmap", "raw")


@dataclass
class Music2DanceConfig:
    """Hyper-parameters of :class:`Music2DanceModel` (saved as ``config.json`` with the weights).

    The defaults are the paper's WaveNet (20 blocks, 32 channels, dilations up to 2^4: a receptive field of
    125 frames, 5 s at 25 fps), which is small enough to train on 2 CPU cores.
    """

    music_dim: int = 15  # D_m, the `music2dance` preset (onset, beat, downbeat, chroma)
    pose_dim: int = 155  # P, rotations_rootdelta of tang2018 (its last contact_dim columns are contacts)
    n_genres: int = 4  # dance types (global condition); 0: none
    contact_dim: int = 2
    generator: str = "wavenet"  # wavenet | lstm (the paper's baseline)
    n_layers: int = 20  # residual blocks
    channels: int = 32  # residual channels
    skip_channels: int = 64
    kernel: int = 2
    max_dilation_exp: int = 4  # dilations cycle 1, 2, ..., 2^max_dilation_exp
    n_mixtures: int = 1  # N (the paper: 1)
    genre_dim: int = 16
    music_condition: str = "fmap"  # fmap (F_map, §4.4.2) | raw (the ablation: features as the local condition)
    fmap_channels: tuple[int, ...] = (16, 24, 32)  # the music attribute classifier's trunk
    fmap_kernel: int = 2
    fmap_lstm_hidden: int = 32
    fmap_dropout: float = 0.1
    fmap_checkpoint: str = ""  # a music_attributes checkpoint whose trunk initialises F_map ("" : random)
    fmap_frozen: bool = False  # keep F_map fixed (from fmap_checkpoint) or fine-tune it
    lstm_hidden: int = 256  # generator="lstm"
    lstm_layers: int = 2
    input_dropout: float = 0.4  # dropout on the input motion (supplement §1.2.1)
    input_noise: float = 0.05  # Gaussian noise (std, normalised units) on the input motion in training
    target_noise: float = 0.02  # ... and on the targets
    contact_weight: float = 0.1  # λ of Eq. 11
    min_log_var: float = -9.0  # floor of σ̂ (log variance), for stability
    phase: int = 1  # training phase: 1 ground-truth inputs; 2 the model's first-pass predictions as inputs
    cluster_balance: bool = True  # weight training windows by their motion cluster (supplement §1.2.2)

    def __post_init__(self) -> None:
        self.fmap_channels = tuple(int(c) for c in self.fmap_channels)
        for name in ("music_dim", "pose_dim", "n_layers", "channels", "skip_channels", "kernel", "n_mixtures",
                     "genre_dim", "fmap_kernel", "fmap_lstm_hidden", "lstm_hidden", "lstm_layers"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ParameterError(f"Music2DanceConfig.{name} must be a positive integer, got {value!r}")
        if self.n_genres < 0 or self.max_dilation_exp < 0 or not 0 <= self.contact_dim < self.pose_dim:
            raise ParameterError("Music2DanceConfig: n_genres and max_dilation_exp must be >= 0 and "
                                 f"0 <= contact_dim < pose_dim, got {self.n_genres}, {self.max_dilation_exp}, "
                                 f"{self.contact_dim}, {self.pose_dim}")
        if self.generator not in GENERATORS:
            raise ParameterError(f"Music2DanceConfig.generator must be one of {GENERATORS}, got {self.generator!r}")
        if self.music_condition not in MUSIC_CONDITIONS:
            raise ParameterError(f"Music2DanceConfig.music_condition must be one of {MUSIC_CONDITIONS}, "
                                 f"got {self.music_condition!r}")
        if len(self.fmap_channels) != 3 or min(self.fmap_channels) < 1:
            raise ParameterError(f"Music2DanceConfig.fmap_channels must be 3 positive integers, got {self.fmap_channels}")
        for name in ("input_dropout", "fmap_dropout"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ParameterError(f"Music2DanceConfig.{name} must be in [0, 1), got {getattr(self, name)}")
        if min(self.input_noise, self.target_noise, self.contact_weight) < 0:
            raise ParameterError("Music2DanceConfig.input_noise, target_noise and contact_weight must be >= 0")
        if self.phase not in (1, 2):
            raise ParameterError(f"Music2DanceConfig.phase must be 1 or 2, got {self.phase!r}")

    @property
    def gmm_dim(self) -> int:
        """D: the columns the mixture models (all but the contacts)."""
        return self.pose_dim - self.contact_dim

    @property
    def out_dim(self) -> int:
        return self.n_mixtures * (1 + 2 * self.gmm_dim) + self.contact_dim

    @property
    def dilations(self) -> tuple[int, ...]:
        return tuple(2 ** (i % (self.max_dilation_exp + 1)) for i in range(self.n_layers))

    @property
    def receptive_field(self) -> int:
        """Frames of input motion an output frame sees (the WaveNet's)."""
        return 1 + (self.kernel - 1) * sum(self.dilations)


# ---------------------------------------------------------------------------------------------- the GMM

def split_params(params: torch.Tensor, config: Music2DanceConfig):
    """Head output ``(..., out_dim)`` → ``logit_w (..., N)``, ``mu (..., N, D)``, ``log_var (..., N, D)``,
    ``contact_logits (..., contact_dim)``."""
    N, D = config.n_mixtures, config.gmm_dim
    lead = params.shape[:-1]
    logit_w = params[..., :N]
    mu = params[..., N : N + N * D].reshape(*lead, N, D)
    log_var = params[..., N + N * D : N + 2 * N * D].reshape(*lead, N, D).clamp_min(config.min_log_var)
    return logit_w, mu, log_var, params[..., N + 2 * N * D :]


def gmm_nll(logit_w: torch.Tensor, mu: torch.Tensor, log_var: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Negative log-likelihood ``(...)`` of ``x (..., D)`` under the diagonal mixture (Eq. 7–9).

    ``logit_w (..., N)``: ω = softmax(logit_w); ``mu, log_var (..., N, D)``: means and log variances (Σ = exp).
    """
    log_w = F.log_softmax(logit_w, dim=-1)  # (..., N)
    z = (x.unsqueeze(-2) - mu) ** 2 * torch.exp(-log_var)  # (..., N, D)
    log_comp = -0.5 * (z + log_var + math.log(2 * math.pi)).sum(-1)  # (..., N)
    return -torch.logsumexp(log_w + log_comp, dim=-1)


def standard_normal(shape: tuple[int, ...], *, generator: torch.Generator | list[torch.Generator] | None = None,
                    dtype: torch.dtype = torch.float32, device: torch.device | str = "cpu") -> torch.Tensor:
    """``N(0, 1)`` noise of ``shape``; with a list of generators, row ``b`` (of the leading dimension) from
    ``generator[b]``, as a batch of that row alone would draw it."""
    if isinstance(generator, (list, tuple)):
        return torch.cat([torch.randn((1, *shape[1:]), generator=g, dtype=dtype, device=device) for g in generator])
    return torch.randn(shape, generator=generator, dtype=dtype, device=device)


def gmm_sample(logit_w: torch.Tensor, mu: torch.Tensor, log_var: torch.Tensor, *, temperature: float = 1.0,
               generator: torch.Generator | list[torch.Generator] | None = None,
               noise: torch.Tensor | None = None) -> torch.Tensor:
    """A sample ``(..., D)`` of the mixture (Eq. 12). ``temperature`` scales the variances and sharpens ω
    (logits / temperature); 0 gives the mean of the most likely component.

    ``generator``: one for all, or a list of one per row of the leading dimension (``(B, ...)`` inputs): row
    ``b`` then draws from ``generator[b]`` exactly what a batch of that row alone draws from it, so a batch
    of seeds equals the seeds one by one. ``noise (..., D)``: the standard normal draw to use (e.g. noise
    correlated over frames, :meth:`Music2DanceModel.generate`) instead of a fresh one.
    """
    if temperature <= 0:
        k = logit_w.argmax(-1)
        return torch.gather(mu, -2, k[..., None, None].expand(*k.shape, 1, mu.shape[-1]))[..., 0, :]
    if isinstance(generator, (list, tuple)):
        if len(generator) != logit_w.shape[0]:
            raise ParameterError(f"{len(generator)} generators for a batch of {logit_w.shape[0]}")
        return torch.cat([gmm_sample(logit_w[b : b + 1], mu[b : b + 1], log_var[b : b + 1], temperature=temperature,
                                     generator=g, noise=None if noise is None else noise[b : b + 1])
                          for b, g in enumerate(generator)])
    N = logit_w.shape[-1]
    if N == 1:  # one component: nothing to choose (no draw, as with a choice among one)
        k = torch.zeros(logit_w.shape[:-1], dtype=torch.long, device=logit_w.device)
    else:
        probs = F.softmax(logit_w / temperature, dim=-1)
        k = torch.multinomial(probs.reshape(-1, N), 1, generator=generator).reshape(probs.shape[:-1])  # (...)
    idx = k[..., None, None].expand(*k.shape, 1, mu.shape[-1])
    m = torch.gather(mu, -2, idx)[..., 0, :]
    std = torch.exp(0.5 * torch.gather(log_var, -2, idx)[..., 0, :]) * math.sqrt(temperature)
    eps = torch.randn(m.shape, generator=generator, dtype=m.dtype, device=m.device) if noise is None else noise
    return m + std * eps


# ---------------------------------------------------------------------------------------------- F_map

class MusicFeatureMap(nn.Module):
    """F_map (§4.4.2): the music attribute classifier's trunk, music ``(B, T, D_m)`` → ``h_m (B, T, 2·hidden)``.

    Parameter names are the classifier's (``convs.*``, ``lstm.*``), so :meth:`load_classifier` takes a
    :class:`~dancekit.models.music_attributes.MusicAttributeClassifier` state dict (its ``head`` is dropped).
    The input is padded at the end (replicated) so that the stride-2 output covers every frame; it is then
    repeated twice along time and cut to T.
    """

    def __init__(self, config: Music2DanceConfig):
        super().__init__()
        c = config
        self.kernel, self.dropout = c.fmap_kernel, c.fmap_dropout
        widths = (c.music_dim,) + c.fmap_channels
        self.convs = nn.ModuleList(nn.Conv1d(widths[i], widths[i + 1], c.fmap_kernel, stride=2 if i == 2 else 1)
                                   for i in range(3))
        self.lstm = nn.LSTM(widths[-1], c.fmap_lstm_hidden, batch_first=True, bidirectional=True)
        self.out_dim = 2 * c.fmap_lstm_hidden

    def forward(self, music: torch.Tensor) -> torch.Tensor:
        T = music.shape[1]
        h = F.pad(music.transpose(1, 2), (0, 3 * self.kernel), mode="replicate")  # (B, D_m, T + 3k)
        for conv in self.convs:
            h = F.dropout(F.relu(conv(h)), self.dropout, self.training)  # (B, C_i, n_i)
        h, _ = self.lstm(h.transpose(1, 2))  # (B, n', 2H), n' >= ceil(T / 2)
        return h.repeat_interleave(2, dim=1)[:, :T]  # (B, T, 2H)

    def load_classifier(self, state: dict[str, torch.Tensor]) -> None:
        """Copy the trunk of a music attribute classifier's state dict (strict on the trunk's keys)."""
        trunk = {k: v for k, v in state.items() if not k.startswith("head.")}
        self.load_state_dict(trunk, strict=True)


# ---------------------------------------------------------------------------------------------- the model

class Music2DanceModel(nn.Module):
    """Music ``(B, T, D_m)`` + previous motion ``(B, T, P)`` + dance type ``(B,)`` → mixture parameters per frame.

    Examples
    --------
    >>> cfg = Music2DanceConfig(music_dim=15, pose_dim=20, n_layers=4, channels=8, skip_channels=8)
    >>> model = Music2DanceModel(cfg)
    >>> model(torch.randn(2, 30, 15), torch.randn(2, 30, 20), torch.tensor([0, -1])).shape  # (B, T, out_dim)
    torch.Size([2, 30, 39])
    """

    family: ClassVar[str] = "music2dance"

    def __init__(self, config: Music2DanceConfig):
        super().__init__()
        self.config = c = config
        C, L = c.channels, c.n_layers
        if c.music_condition == "fmap":
            self.fmap = MusicFeatureMap(c)
            cond_dim = self.fmap.out_dim
        else:
            self.fmap = None
            cond_dim = c.music_dim
        self.genre_embedding = nn.Embedding(c.n_genres + 1, c.genre_dim)  # index n_genres: no dance type
        self.register_buffer("fmap_loaded", torch.zeros((), dtype=torch.uint8))
        if c.generator == "wavenet":
            self.input_proj = nn.Conv1d(c.pose_dim, C, 1)
            self.dilated = nn.ModuleList(nn.Conv1d(C, 2 * C, c.kernel, dilation=d) for d in c.dilations)
            self.local_proj = nn.Linear(cond_dim, L * 2 * C)  # every block's local-condition 1x1, at once
            self.global_proj = nn.Linear(c.genre_dim, L * 2 * C, bias=False)
            self.res = nn.ModuleList(nn.Conv1d(C, C, 1) for _ in range(L))
            self.skip = nn.ModuleList(nn.Conv1d(C, c.skip_channels, 1) for _ in range(L))
            self.out1 = nn.Conv1d(c.skip_channels, c.skip_channels, 1)
            self.out2 = nn.Conv1d(c.skip_channels, c.out_dim, 1)
        else:
            self.lstm_in = nn.Linear(c.pose_dim + cond_dim + c.genre_dim, c.lstm_hidden)
            self.lstm = nn.LSTM(c.lstm_hidden, c.lstm_hidden, num_layers=c.lstm_layers, batch_first=True)
            self.head = nn.Linear(c.lstm_hidden, c.out_dim)
        for m in self.modules():
            if isinstance(m, nn.Conv1d | nn.Linear):
                nn.init.xavier_normal_(m.weight)
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
        if c.fmap_frozen and self.fmap is not None:
            self.fmap.requires_grad_(False)

    def train(self, mode: bool = True) -> Music2DanceModel:
        super().train(mode)
        if self.config.fmap_frozen and self.fmap is not None:
            self.fmap.eval()  # a frozen F_map has no dropout either
        return self

    # ---------------------------------------------------------------- conditions
    def music_condition(self, music: torch.Tensor, *, window: int | None = None) -> torch.Tensor:
        """``h_m (B, T, H)``: F_map of the music, or the music itself (``music_condition="raw"``).

        ``window``: compute F_map on windows of this many frames (hop ``window // 2``, each frame taken from
        the window where it is farthest from the edges), as in training on windows, instead of running its
        BiLSTM over the whole song (None, or a song no longer than a window).
        """
        c = self.config
        if music.dim() != 3 or music.shape[-1] != c.music_dim:
            raise ParameterError(f"music must be (B, T, {c.music_dim}), got {tuple(music.shape)}")
        if self.fmap is None:
            return music
        T = music.shape[1]
        if window is None or T <= window:
            return self.fmap(music)
        if window < 4:
            raise ParameterError(f"the F_map window must be at least 4 frames, got {window}")
        hop, q = window // 2, window // 4
        starts = list(range(0, T - window + 1, hop))
        if starts[-1] != T - window:
            starts.append(T - window)
        out = music.new_zeros(music.shape[0], T, self.fmap.out_dim)
        for k, s in enumerate(starts):
            h = self.fmap(music[:, s : s + window])  # (B, window, H)
            lo = s if k == 0 else s + q
            hi = s + window if k == len(starts) - 1 else s + window - q
            out[:, lo:hi] = h[:, lo - s : hi - s]
        return out

    def genre_vector(self, genre: torch.Tensor | None, batch: int, device: torch.device) -> torch.Tensor:
        """The dance-type embedding ``(B, genre_dim)``; ``None`` or ``-1``: the "no type" embedding."""
        n = self.config.n_genres
        if genre is None:
            genre = torch.full((batch,), -1, dtype=torch.long, device=device)
        genre = torch.as_tensor(genre, device=device).long().reshape(-1).expand(batch)
        if bool(((genre < -1) | (genre >= n)).any()):
            raise ParameterError(f"genre indices must be in [-1, {n - 1}], got {genre.tolist()}")
        return self.genre_embedding(torch.where(genre < 0, torch.full_like(genre, n), genre))

    def guided_genre_vector(self, genre: torch.Tensor | None, batch: int, device: torch.device, *,
                            genre_scale: float = 1.0) -> torch.Tensor:
        """The dance-type vector ``(B, genre_dim)`` with guidance ``α = genre_scale``: ``g_∅ + α (g - g_∅)``
        (``g_∅`` the learned "no type" embedding, which training's genre dropout fits), so every gated
        layer's dance-type term ``W_g g`` (linear, no bias) becomes ``W_g g_∅ + α W_g (g - g_∅)``. α = 1: the
        model as trained; α > 1 pushes the dance further towards its type; rows without a type are unchanged."""
        g = self.genre_vector(genre, batch, device)
        if genre_scale == 1.0:
            return g
        if not math.isfinite(genre_scale) or genre_scale < 0:
            raise ParameterError(f"genre_scale must be a finite number >= 0, got {genre_scale!r}")
        g0 = self.genre_vector(None, batch, device)
        return g0 + genre_scale * (g - g0)

    def _conditions(self, music: torch.Tensor, genre: torch.Tensor | None, *,
                    window: int | None = None, genre_scale: float = 1.0) -> tuple[torch.Tensor, torch.Tensor]:
        """WaveNet: per-block condition ``(B, T, L, 2C)``; LSTM: (music condition, genre vector).
        ``genre_scale``: see :meth:`guided_genre_vector`."""
        h_m = self.music_condition(music, window=window)  # (B, T, H)
        g = self.guided_genre_vector(genre, music.shape[0], music.device, genre_scale=genre_scale)  # (B, G)
        if self.config.generator != "wavenet":
            return h_m, g
        B, T = music.shape[:2]
        L, C2 = self.config.n_layers, 2 * self.config.channels
        cond = self.local_proj(h_m) + self.global_proj(g)[:, None]  # (B, T, L * 2C)
        return cond.reshape(B, T, L, C2), g

    # ---------------------------------------------------------------- full sequence
    def forward(self, music: torch.Tensor, prev: torch.Tensor, genre: torch.Tensor | None = None) -> torch.Tensor:
        """Output parameters ``(B, T, out_dim)`` for frames ``t`` given ``prev[:, t]`` = the motion of frame
        ``t - 1`` (:func:`shift_right` of the dance) and everything before it: causal in ``prev``."""
        c = self.config
        if prev.dim() != 3 or prev.shape[-1] != c.pose_dim or prev.shape[:2] != music.shape[:2]:
            raise ParameterError(f"prev must be (B, T, {c.pose_dim}) like music's (B, T), got {tuple(prev.shape)}")
        prev = F.dropout(prev, c.input_dropout, self.training)
        cond, g = self._conditions(music, genre)
        if c.generator == "lstm":
            B, T = prev.shape[:2]
            h, _ = self.lstm(self.lstm_in(torch.cat([prev, cond, g[:, None].expand(B, T, -1)], -1)))
            return self.head(h)  # (B, T, out_dim)
        x = self.input_proj(prev.transpose(1, 2))  # (B, C, T)
        skips = 0.0
        # the blocks' conditions as views: unbind's gradient is one stack, where indexing cond[:, :, i] in each
        # block would allocate, zero and add a gradient of the whole (B, T, L, 2C) per block
        conds = cond.unbind(2)
        for i, (conv, d) in enumerate(zip(self.dilated, c.dilations)):
            h = conv(F.pad(x, ((c.kernel - 1) * d, 0))) + conds[i].transpose(1, 2)  # (B, 2C, T) causal
            z = torch.tanh(h[:, : c.channels]) * torch.sigmoid(h[:, c.channels :])  # (B, C, T) gated
            skips = skips + self.skip[i](z)  # (B, S, T)
            x = x + self.res[i](z)
        out = self.out2(F.relu(self.out1(F.relu(skips))))  # (B, out_dim, T)
        return out.transpose(1, 2)

    def loss(self, params: torch.Tensor, target: torch.Tensor,
             weights: torch.Tensor | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """``(L_gmm + λ · BCE) / D`` (Eq. 11) of ``params (B, T, out_dim)`` against ``target (B, T, P)``
        (its last ``contact_dim`` columns 0/1), averaged over frames; ``weights (B,)``: per-window weights
        (the motion clusters' balance; mean 1 over the data)."""
        c = self.config
        logit_w, mu, log_var, contact_logits = split_params(params, c)
        nll = gmm_nll(logit_w, mu, log_var, target[..., : c.gmm_dim]).mean(-1)  # (B,)
        if c.contact_dim:
            bce = F.binary_cross_entropy_with_logits(contact_logits, target[..., c.gmm_dim :],
                                                     reduction="none").mean((-1, -2))  # (B,)
        else:
            bce = torch.zeros_like(nll)
        per_window = (nll + c.contact_weight * bce) / c.gmm_dim
        loss = (per_window * weights.to(per_window)).mean() if weights is not None else per_window.mean()
        acc = ((contact_logits > 0).float() == target[..., c.gmm_dim :]).float().mean().item() if c.contact_dim else 1.0
        return loss, {"nll_per_dim": float(nll.mean().detach()) / c.gmm_dim, "bce": float(bce.mean().detach()),
                      "contact_acc": acc}

    def predict(self, params: torch.Tensor, *, temperature: float = 1.0,
                generator: torch.Generator | list[torch.Generator] | None = None,
                noise: torch.Tensor | None = None) -> torch.Tensor:
        """A motion frame ``(..., P)`` from output parameters: a mixture sample (``noise``: see
        :func:`gmm_sample`) and thresholded contacts."""
        logit_w, mu, log_var, contact_logits = split_params(params, self.config)
        x = gmm_sample(logit_w, mu, log_var, temperature=temperature, generator=generator, noise=noise)
        return torch.cat([x, (contact_logits > 0).to(x.dtype)], dim=-1)

    # ---------------------------------------------------------------- incremental
    def init_state(self, batch: int, *, device: torch.device | None = None, dtype: torch.dtype | None = None) -> list:
        """Per-layer queues of past block inputs (zeros: the causal padding), or the LSTM's state (None)."""
        c = self.config
        if c.generator == "lstm":
            return [None]
        p = next(self.parameters())
        device, dtype = device or p.device, dtype or p.dtype
        return [[torch.zeros(batch, c.channels, device=device, dtype=dtype) for _ in range((c.kernel - 1) * d)]
                for d in c.dilations]

    def _step_weights(self) -> dict[str, list[torch.Tensor] | torch.Tensor]:
        """The WaveNet's weights arranged for :meth:`step`: per block the taps of the dilated convolution as
        one ``(k·C, 2C)`` matrix (oldest tap first), the residual 1x1 ``(C, C)``; the skip 1x1s of all blocks
        stacked ``(L·C, S)`` with their biases summed (the skip sum is one product of the concatenated
        gated outputs)."""
        c = self.config
        return {
            "in_w": self.input_proj.weight[:, :, 0].T, "in_b": self.input_proj.bias,
            "conv_w": [conv.weight.permute(2, 1, 0).reshape(c.kernel * c.channels, 2 * c.channels)
                       for conv in self.dilated],
            "conv_b": [conv.bias for conv in self.dilated],
            "res_w": [r.weight[:, :, 0].T for r in self.res], "res_b": [r.bias for r in self.res],
            "skip_w": torch.cat([s.weight[:, :, 0].T for s in self.skip]),
            "skip_b": torch.stack([s.bias for s in self.skip]).sum(0),
        }

    def step(self, cond_t: torch.Tensor, g: torch.Tensor, prev_t: torch.Tensor, state: list,
             weights: dict | None = None) -> torch.Tensor:
        """One frame: ``cond_t`` the frame's condition (WaveNet ``(B, L, 2C)``, LSTM ``(B, H)``), ``g`` the
        genre vector, ``prev_t (B, P)`` the previous motion frame → parameters ``(B, out_dim)``; ``state``
        (from :meth:`init_state`) is updated in place; ``weights``: :meth:`_step_weights` (computed when
        None; pass them when stepping many frames). O(layers) per frame."""
        c = self.config
        if c.generator == "lstm":
            h, state[0] = self.lstm(self.lstm_in(torch.cat([prev_t, cond_t, g], -1))[:, None], state[0])
            return self.head(h[:, 0])
        w = self._step_weights() if weights is None else weights
        C = c.channels
        x = torch.addmm(w["in_b"], prev_t, w["in_w"])  # (B, C)
        zs = []
        for i, d in enumerate(c.dilations):
            queue = state[i]  # inputs at t - (k-1)d, ..., t - 1
            taps = torch.cat([queue[j * d] for j in range(c.kernel - 1)] + [x], -1)  # (B, k·C) t-(k-1)d ... t
            h = torch.addmm(cond_t[:, i] + w["conv_b"][i], taps, w["conv_w"][i])  # (B, 2C)
            queue.pop(0)
            queue.append(x)
            z = torch.tanh(h[:, :C]) * torch.sigmoid(h[:, C:])  # (B, C)
            zs.append(z)
            x = x + torch.addmm(w["res_b"][i], z, w["res_w"][i])
        skips = torch.addmm(w["skip_b"], torch.cat(zs, -1), w["skip_w"])  # (B, S)
        h = F.relu(F.linear(F.relu(skips), self.out1.weight[:, :, 0], self.out1.bias))
        return F.linear(h, self.out2.weight[:, :, 0], self.out2.bias)

    @torch.no_grad()
    def forward_incremental(self, music: torch.Tensor, prev: torch.Tensor,
                            genre: torch.Tensor | None = None) -> torch.Tensor:
        """:meth:`forward` computed frame by frame with :meth:`step` (eval mode; for tests and analysis)."""
        cond, g = self._conditions(music, genre)
        state = self.init_state(prev.shape[0], device=prev.device, dtype=prev.dtype)
        w = self._step_weights() if self.config.generator == "wavenet" else None
        return torch.stack([self.step(cond[:, t], g, prev[:, t], state, w) for t in range(prev.shape[1])], dim=1)

    @torch.no_grad()
    def generate(self, music: torch.Tensor, genre: torch.Tensor | None = None, *, temperature: float = 1.0,
                 generator: torch.Generator | list[torch.Generator] | None = None, first: torch.Tensor | None = None,
                 progress: bool = False, fmap_window: int | None = None,
                 noise_correlation: float = 0.0, genre_scale: float = 1.0, reference: bool = False,
                 prefix: torch.Tensor | None = None) -> torch.Tensor:
        """A dance ``(B, T, P)`` for ``music (B, T, D_m)``, frame by frame, sampling the mixture.

        ``prefix (1 or B, N, P)``: the dance's first N frames, given: each is sampled as usual (the same random
        draws) and then replaced by the given frame, which is the next frame's input (teacher forcing: the
        WaveNet's receptive field holds the prefix), so the dance continues from the prefix's last frame.

        ``noise_correlation`` ρ in [0, 1): the standard normal draw of each frame is ``ε_t = ρ ε_{t-1} +
        √(1-ρ²) η_t`` (η fresh; still N(0, 1) at every frame) instead of independent draws (ρ = 0, the
        paper's): the deviations from the mixture means then vary slowly, a dance instead of a tremor.

        ``first (B, P)``: the input of frame 0 (default zeros: the mean pose, no contacts); ``fmap_window``:
        see :meth:`music_condition` (the pipeline passes the training window); ``generator``: one, or one
        per row (a batch of seeds: each row is generated on its own, as a batch of one, so that row k is bit for
        bit the dance of its seed alone whatever the batch: the batched products round differently for every
        batch size); ``genre_scale``:
        guidance of the dance type (:meth:`guided_genre_vector`; 1: as trained). Call in eval mode.

        The WaveNet's frames are computed by :class:`NumpyWaveNet` (on the CPU, in the model's float
        dtype; the same dance as the torch :meth:`step` to float rounding, from the same random draws);
        ``reference=True``, a reduced-precision copy (``fast_step``, :mod:`dancekit.models.precision`), the
        LSTM baseline or another device run the torch loop.
        """
        from tqdm import tqdm

        if isinstance(generator, (list, tuple)) and len(generator) > 1:  # one generator per row: each row alone
            if len(generator) != music.shape[0]:
                raise ParameterError(f"{len(generator)} generators for a batch of {music.shape[0]}")
            genres = None if genre is None else torch.as_tensor(genre).reshape(-1)
            return torch.cat([
                self.generate(music[k : k + 1], None if genres is None else genres[k : k + 1] if len(genres) > 1
                              else genres, temperature=temperature, generator=[gen],
                              first=None if first is None else first[k : k + 1], progress=progress,
                              fmap_window=fmap_window, noise_correlation=noise_correlation, genre_scale=genre_scale,
                              reference=reference,
                              prefix=None if prefix is None else prefix[k : k + 1] if len(prefix) > 1 else prefix)
                for k, gen in enumerate(generator)])
        B, T = music.shape[:2]
        cond, g = self._conditions(music, genre, window=fmap_window, genre_scale=genre_scale)
        if not 0.0 <= noise_correlation < 1.0:
            raise ParameterError(f"noise_correlation must be in [0, 1), got {noise_correlation!r}")
        x = first if first is not None else music.new_zeros(B, self.config.pose_dim)
        if prefix is not None:
            if prefix.ndim != 3 or prefix.shape[0] not in (1, B) or prefix.shape[2] != self.config.pose_dim:
                raise ParameterError(f"prefix must be (1 or {B}, N, {self.config.pose_dim}), got {tuple(prefix.shape)}")
            prefix = prefix.to(music.dtype).expand(B, -1, -1)
        rho, eps = float(noise_correlation), None
        fast_step = getattr(self, "fast_step", None)  # reduced precision: models/precision.py
        p = next(self.parameters())
        if (not reference and fast_step is None and self.config.generator == "wavenet" and p.device.type == "cpu"
                and music.dtype == p.dtype and p.dtype in (torch.float32, torch.float64)):
            out = NumpyWaveNet(self).generate(cond, x, temperature=temperature, generator=generator,
                                              noise_correlation=rho, progress=progress, prefix=prefix)
            return torch.from_numpy(out)
        state = self.init_state(B, device=music.device, dtype=music.dtype)
        w = self._step_weights() if self.config.generator == "wavenet" else None
        step = fast_step or self.step
        frames = []
        for t in tqdm(range(T), disable=not progress, desc="dance", unit="frame"):
            if rho > 0 and temperature > 0:
                eta = standard_normal((B, self.config.gmm_dim), generator=generator, dtype=music.dtype,
                                      device=music.device)
                eps = eta if eps is None else rho * eps + math.sqrt(1 - rho * rho) * eta
            x = self.predict(step(cond[:, t], g, x, state, w), temperature=temperature, generator=generator,
                             noise=eps)
            if prefix is not None and t < prefix.shape[1]:
                x = prefix[:, t]
            frames.append(x)
        return torch.stack(frames, dim=1)


class NumpyWaveNet:
    """The WaveNet's generation loop (:meth:`Music2DanceModel.generate`) in NumPy, for inference on the CPU.

    The same products as :meth:`Music2DanceModel.step` (per block the taps of the dilated convolution as one
    ``(k·C, 2C)`` matrix, the residual 1x1, the skip 1x1s of all blocks as one product; the weights in the
    model's float dtype), with fewer and cheaper operations per frame (a NumPy call costs about a microsecond,
    a torch call several; a frame is some 200 of them):

    * taps without queues: block ``l`` (dilation ``d``) keeps ``(k-1)·d + 1`` tap buffers ``(B, k·C)`` used in
      turn; its input at frame ``t`` is written into the buffer of frame ``t`` (last slot) and into those of
      frames ``t + d, ..., t + (k-1)·d`` (earlier slots), so each frame's taps lie ready for one product;
    * the gate ``tanh(f) · σ(g)`` as one ``tanh`` over both halves: ``σ(g) = (1 + tanh(g/2)) / 2``, with the
      ``g`` half of the weights and conditions and the ``1/2`` of the gated output moved into the residual and
      skip weights (scalings by powers of two: exact);
    * the dilated convolution's bias added to the precomputed conditions once per chunk of frames; the last
      block's residual (unused) not computed.

    The output equals the torch step's to float rounding (``tests/models/test_music2dance_numpy.py``).

    Sampling draws the same random numbers from the same generators in the same order as
    :func:`gmm_sample` frame by frame: with one mixture component (or temperature 0) no draw depends on the
    model's output, so a chunk's standard normal draws (and their correlation over frames) are made ahead,
    one torch call per frame as the torch loop makes them; with several components the choice of a
    component depends on the output, and each frame samples with :meth:`Music2DanceModel.predict`.
    """

    #: frames whose conditions and noise are prepared at once (memory O(chunk), not O(song))
    CHUNK = 512

    def __init__(self, model: Music2DanceModel):
        c = self.config = model.config
        if c.generator != "wavenet":
            raise ParameterError("NumpyWaveNet runs the WaveNet generator only")
        self.model = model
        dtype = next(model.parameters()).dtype
        self.dtype = np.float32 if dtype == torch.float32 else np.float64
        self.model_dtype = dtype
        C = c.channels

        def a(t: torch.Tensor, scale: float = 1.0) -> np.ndarray:
            return np.array(t.detach().cpu().numpy(), dtype=self.dtype, order="C") * self.dtype(scale)

        w = model._step_weights()
        self.half = np.ones(2 * C, dtype=self.dtype)
        self.half[C:] = 0.5  # σ(g) = (1 + tanh(g / 2)) / 2
        self.in_w, self.in_b = a(w["in_w"]), a(w["in_b"])
        self.conv_w = [a(cw) * self.half for cw in w["conv_w"]]  # (k·C, 2C), oldest tap first
        self.conv_b = np.stack([a(b) for b in w["conv_b"]])  # (L, 2C)
        # the loop's gated output is 2·tanh(f)·σ(g) = tanh(f)·(1 + tanh(g/2)): its 1/2 goes into the 1x1s
        self.res_w, self.res_b = [a(r, 0.5) for r in w["res_w"]], [a(b) for b in w["res_b"]]
        self.skip_w, self.skip_b = a(w["skip_w"], 0.5), a(w["skip_b"])
        self.out1_w, self.out1_b = a(model.out1.weight[:, :, 0].T), a(model.out1.bias)
        self.out2_w, self.out2_b = a(model.out2.weight[:, :, 0].T), a(model.out2.bias)

    def _tap_buffers(self, B: int) -> list[list[tuple[np.ndarray, np.ndarray, list[np.ndarray]]]]:
        """Per block, per frame modulo ``(k-1)·d + 1``: (the taps ``(B, k·C)``, the view of the frame's own
        input in them, the views where later frames read it)."""
        c = self.config
        C, k = c.channels, c.kernel
        out = []
        for d in c.dilations:
            R = (k - 1) * d + 1
            bufs = [np.zeros((B, k * C), self.dtype) for _ in range(R)]
            out.append([(bufs[u], bufs[u][:, (k - 1) * C :],
                         [bufs[(u + m * d) % R][:, (k - 1 - m) * C : (k - m) * C] for m in range(1, k)])
                        for u in range(R)])
        return out

    def generate(self, cond: torch.Tensor, first: torch.Tensor, *, temperature: float = 1.0,
                 generator: torch.Generator | list[torch.Generator] | None = None, noise_correlation: float = 0.0,
                 progress: bool = False, prefix: torch.Tensor | None = None) -> np.ndarray:
        """The dance ``(B, T, P)`` (the model's dtype) for the per-block conditions ``cond (B, T, L, 2C)``
        (:meth:`Music2DanceModel._conditions`) from the input ``first (B, P)`` of frame 0; sampling (and a given
        ``prefix (B, N, P)``) as :meth:`Music2DanceModel.generate`."""
        from tqdm import tqdm

        c = self.config
        B, T, L = cond.shape[0], cond.shape[1], c.n_layers
        C, N, D, P = c.channels, c.n_mixtures, c.gmm_dim, c.pose_dim
        dt = self.dtype
        rho = float(noise_correlation)
        ahead = temperature <= 0 or N == 1  # the draws do not depend on the outputs: made per chunk
        sqrt_t = math.sqrt(temperature) if temperature > 0 else 0.0
        taps = self._tap_buffers(B)
        periods = [len(v) for v in taps]
        layers = list(zip(range(L), taps, periods, self.conv_w, self.res_w, self.res_b))
        zs = np.zeros((B, L * C), dt)  # the gated outputs of all blocks (times 2), for the one skip product
        z_views = [zs[:, i * C : (i + 1) * C] for i in range(L)]
        y = np.zeros((T, B, P), dt)
        prev = np.array(first.detach().cpu().numpy(), dtype=dt)
        given = None if prefix is None else np.array(prefix.detach().cpu().numpy(), dtype=dt)  # (B, N, P)
        eps_t = None  # the correlated noise of the last frame (torch, as the torch loop computes it)
        bar = tqdm(total=T, disable=not progress, desc="dance", unit="frame")
        for t0 in range(0, T, self.CHUNK):
            t1 = min(T, t0 + self.CHUNK)
            condb = (cond[:, t0:t1].detach().cpu().numpy().astype(dt) + self.conv_b) * self.half  # (B, t1-t0, L, 2C)
            noise = None
            if ahead and temperature > 0:
                noise = np.empty((t1 - t0, B, D), dt)
                for j in range(t1 - t0):
                    eta = standard_normal((B, D), generator=generator, dtype=self.model_dtype)
                    if rho > 0:
                        eps_t = eta if eps_t is None else rho * eps_t + math.sqrt(1 - rho * rho) * eta
                        noise[j] = eps_t.numpy()
                    else:
                        noise[j] = eta.numpy()
            for t in range(t0, t1):
                cb = condb[:, t - t0]  # (B, L, 2C)
                x_in = r = None  # the previous block's input and residual 1x1 output
                for i, tap, R, conv_w, res_w, res_b in layers:
                    tb, x, later = tap[t % R]
                    if x_in is None:  # the input 1x1 of the previous frame
                        np.matmul(prev, self.in_w, out=x)
                        x += self.in_b
                    else:  # the residual: the previous block's input plus its 1x1 output
                        np.add(x_in, r, out=x)
                    for view in later:
                        view[...] = x
                    h = tb @ conv_w
                    h += cb[:, i]
                    np.tanh(h, out=h)
                    gate = h[:, C:]
                    gate += 1.0
                    z = np.multiply(h[:, :C], gate, out=z_views[i])
                    if i < L - 1:
                        r = z @ res_w
                        r += res_b
                        x_in = x
                s = zs @ self.skip_w
                s += self.skip_b
                np.maximum(s, 0, out=s)
                o = s @ self.out1_w
                o += self.out1_b
                np.maximum(o, 0, out=o)
                params = o @ self.out2_w
                params += self.out2_b
                frame = y[t]
                if ahead:
                    if N == 1:
                        mu = params[:, 1 : 1 + D]
                    else:  # temperature 0: the mean of the most likely component
                        mus = params[:, N : N + N * D].reshape(B, N, D)
                        mu = mus[np.arange(B), params[:, :N].argmax(-1)]
                    if temperature > 0:  # m + exp(log_var / 2) · √t · ε, log_var clamped as split_params does
                        std = params[:, 1 + D : 1 + 2 * D]
                        np.maximum(std, c.min_log_var, out=std)
                        std *= 0.5
                        np.exp(std, out=std)
                        std *= sqrt_t
                        std *= noise[t - t0]
                        np.add(mu, std, out=frame[:, :D])
                    else:
                        frame[:, :D] = mu
                    frame[:, D:] = params[:, N + 2 * N * D :] > 0
                else:  # several components, sampled: the torch sampling frame by frame, draws in its order
                    if rho > 0:
                        eta = standard_normal((B, D), generator=generator, dtype=self.model_dtype)
                        eps_t = eta if eps_t is None else rho * eps_t + math.sqrt(1 - rho * rho) * eta
                    frame[:] = self.model.predict(torch.from_numpy(params), temperature=temperature,
                                                  generator=generator, noise=eps_t).numpy()
                if given is not None and t < given.shape[1]:
                    frame[:] = given[:, t]
                prev = frame
            bar.update(t1 - t0)
        bar.close()
        return np.ascontiguousarray(y.transpose(1, 0, 2))


def shift_right(x: torch.Tensor, first: torch.Tensor | None = None) -> torch.Tensor:
    """The autoregressive input ``(B, T, P)``: frame ``t`` holds ``x[:, t - 1]``, frame 0 ``first`` (zeros)."""
    head = x.new_zeros(x.shape[0], 1, x.shape[2]) if first is None else first[:, None]
    return torch.cat([head, x[:, :-1]], dim=1)
