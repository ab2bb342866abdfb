"""Music attribute classifier of Music2Dance (§4.3): which dance type does a piece of music call for?

One file, one model: :class:`MusicAttributeConfig` (a dataclass saved with the weights) and
:class:`MusicAttributeClassifier` (an ``nn.Module(config)``).

Architecture (paper §4.3, Fig. 5)
    Normalised music features ``(B, n, D)`` of a long window (30 s in the paper: "the music attribute is
    not determined by a short music clip") → three temporal convolutions (kernel 2, channels 16-24-32,
    the third with stride 2, ReLU, dropout 0.1) → one bidirectional LSTM → mean over time → one fully
    connected layer → logits over the dance types ``(B, n_classes)``. Trained with cross-entropy.
    The paper's features are the ``music2dance`` preset (onset, beat, downbeat, chroma; D = 15) and its
    classes are two music attributes; here the classes are the dataset's dance genres (tang2018: waltz,
    rumba, cha-cha, tango).

The paper's baseline (Table 1, "FC+Bi-LSTM") is ``frontend="fc"``: the temporal convolutions replaced by
per-frame fully connected layers of the same widths (no temporal context before the BiLSTM, no stride).

Rhythm periodicity (``rhythm_bins > 0``, not in the paper): the autocorrelation of one input column (the
onset strength of the ``music2dance`` preset) over the window, read at ``rhythm_bins`` log-spaced lags from
``rhythm_min_lag`` to ``rhythm_max_lag`` frames (:func:`log_lag_autocorrelation`), joins the BiLSTM's mean
before the fully connected layer. It carries the tempo and the metre (a waltz's onsets repeat every 3 beats,
a rumba's every 4), the strongest cues to a ballroom dance type; it has no weights, so the trunk (the
convolutions and the BiLSTM) keeps the paper's layout and Music2Dance's F_map can still start from it.
``frontend="none"`` drops the trunk: the fully connected layer reads the rhythm periodicity alone (a linear
classifier of it, with nothing to learn a song's chords by; F_map cannot start from such a classifier).

A whole song is classified by :meth:`MusicAttributeClassifier.predict_song`: the mean log-probability of
its windows (hop half a window); a song shorter than a window is classified in one piece.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancekit.errors import ParameterError

FRONTENDS = ("conv", "fc", "none")


@dataclass
class MusicAttributeConfig:
    """Hyper-parameters of :class:`MusicAttributeClassifier` (saved as ``config.json`` with the weights)."""

    music_dim: int = 15  # D, features per frame (the `music2dance` preset)
    n_classes: int = 4  # dance types (tang2018 genres)
    channels: tuple[int, ...] = (16, 24, 32)  # temporal convolutions; the last one has stride 2
    kernel: int = 2
    lstm_hidden: int = 32  # per direction
    dropout: float = 0.1
    window: int = 750  # frames per classified window (30 s at 25 fps)
    frontend: str = "conv"  # conv (the paper's model) | fc (its FC+Bi-LSTM baseline) | none (rhythm only)
    rhythm_bins: int = 0  # log-spaced lags of the onset autocorrelation fed to the head (0: the paper's model)
    rhythm_min_lag: float = 6.0  # frames, shortest lag read (0.24 s at 25 fps)
    rhythm_max_lag: float = 100.0  # frames, longest lag read (4 s at 25 fps)
    rhythm_column: int = 0  # input column whose periodicity is read (the music2dance preset's onset strength)

    def __post_init__(self) -> None:
        self.channels = tuple(int(c) for c in self.channels)
        for name in ("music_dim", "n_classes", "kernel", "lstm_hidden", "window"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ParameterError(f"MusicAttributeConfig.{name} must be a positive integer, got {value!r}")
        if self.n_classes < 2:
            raise ParameterError(f"MusicAttributeConfig.n_classes must be at least 2, got {self.n_classes}")
        if not self.channels or min(self.channels) < 1:
            raise ParameterError(f"MusicAttributeConfig.channels must be positive integers, got {self.channels}")
        if self.frontend not in FRONTENDS:
            raise ParameterError(f"MusicAttributeConfig.frontend must be one of {FRONTENDS}, got {self.frontend!r}")
        if not 0.0 <= self.dropout < 1.0:
            raise ParameterError(f"MusicAttributeConfig.dropout must be in [0, 1), got {self.dropout}")
        if isinstance(self.rhythm_bins, bool) or not isinstance(self.rhythm_bins, int) or self.rhythm_bins < 0:
            raise ParameterError(f"MusicAttributeConfig.rhythm_bins must be an integer >= 0, got {self.rhythm_bins!r}")
        if not 1.0 <= float(self.rhythm_min_lag) < float(self.rhythm_max_lag):
            raise ParameterError(f"MusicAttributeConfig needs 1 <= rhythm_min_lag < rhythm_max_lag (frames), got "
                                 f"{self.rhythm_min_lag!r}, {self.rhythm_max_lag!r}")
        if self.frontend == "none" and not self.rhythm_bins:
            raise ParameterError("MusicAttributeConfig: frontend 'none' needs rhythm_bins > 0 (the head would read nothing)")
        if not 0 <= int(self.rhythm_column) < self.music_dim:
            raise ParameterError(f"MusicAttributeConfig.rhythm_column must be a column 0..{self.music_dim - 1}, got "
                                 f"{self.rhythm_column!r}")


def rhythm_lags(config: MusicAttributeConfig) -> torch.Tensor:
    """The ``rhythm_bins`` lags (frames, float) read by the rhythm periodicity: log-spaced from
    ``rhythm_min_lag`` to ``rhythm_max_lag`` inclusive."""
    c = config
    return torch.logspace(float(np.log10(c.rhythm_min_lag)), float(np.log10(c.rhythm_max_lag)), c.rhythm_bins,
                          dtype=torch.float64).float()


def log_lag_autocorrelation(x: torch.Tensor, lags: torch.Tensor) -> torch.Tensor:
    """Normalised autocorrelation of each row of ``x`` (B, n) at fractional ``lags`` (K,) frames → (B, K).

    Each row is centred; its unbiased autocorrelation ``r(k) = sum_t x_t x_{t+k} / (n - k)`` (by FFT) is divided
    by ``r(0)`` (so 1 at lag 0 and the same for any affine rescaling of the row) and read at each lag by linear
    interpolation between whole lags; a lag the row is too short for (``>= n - 1``) reads 0, as does a
    constant row."""
    if x.dim() != 2 or lags.dim() != 1:
        raise ParameterError(f"need x (B, n) and lags (K,), got {tuple(x.shape)} and {tuple(lags.shape)}")
    B, n = x.shape
    xc = x - x.mean(dim=1, keepdim=True)
    f = torch.fft.rfft(xc, 2 * n, dim=1)
    r = torch.fft.irfft(f * f.conj(), 2 * n, dim=1)[:, :n] / torch.arange(n, 0, -1, dtype=x.dtype, device=x.device)
    r = r / torch.clamp(r[:, :1], min=1e-12)  # (B, n)
    lags = lags.to(x.device, x.dtype)
    lo = torch.clamp(lags.floor().long(), 0, max(n - 2, 0))
    frac = (lags - lo.to(x.dtype)).clamp(0.0, 1.0)
    hi = torch.clamp(lo + 1, max=n - 1)
    out = r[:, lo] * (1 - frac) + r[:, hi] * frac  # (B, K)
    out = torch.where((lags < n - 1)[None, :], out, torch.zeros_like(out))
    flat = (xc.abs().amax(dim=1, keepdim=True) <= 1e-12)
    return torch.where(flat, torch.zeros_like(out), out)


class MusicAttributeClassifier(nn.Module):
    """Music features (B, n, D) → dance-type logits (B, n_classes).

    Examples
    --------
    >>> model = MusicAttributeClassifier(MusicAttributeConfig(music_dim=15, n_classes=4, window=50))
    >>> model(torch.randn(2, 50, 15)).shape
    torch.Size([2, 4])
    """

    family: ClassVar[str] = "music_attributes"

    def __init__(self, config: MusicAttributeConfig):
        super().__init__()
        self.config = c = config
        convs, width = [], c.music_dim
        for i, out in enumerate(c.channels if c.frontend != "none" else ()):
            if c.frontend == "fc":  # a per-frame linear layer, as a kernel-1 convolution
                convs.append(nn.Conv1d(width, out, 1))
            else:
                stride = 2 if i == len(c.channels) - 1 else 1
                convs.append(nn.Conv1d(width, out, c.kernel, stride=stride))
            width = out
        self.convs = nn.ModuleList(convs)
        trunk = 0 if c.frontend == "none" else 2 * c.lstm_hidden
        self.lstm = nn.LSTM(width, c.lstm_hidden, batch_first=True, bidirectional=True) if trunk else None
        self.head = nn.Linear(trunk + c.rhythm_bins, c.n_classes)
        self.register_buffer("lags", rhythm_lags(c), persistent=False)  # (rhythm_bins,) frames

    def min_frames(self) -> int:
        """Shortest input (frames) that leaves at least one step after the convolutions."""
        n = 1 if self.lstm is not None else 2  # the rhythm periodicity alone: any two frames
        for conv in reversed(self.convs):
            n = (n - 1) * conv.stride[0] + conv.kernel_size[0]
        return n

    def forward(self, music: torch.Tensor) -> torch.Tensor:
        """``music`` (B, n, D) normalised features, n >= :meth:`min_frames` → logits (B, n_classes)."""
        c = self.config
        if music.dim() != 3 or music.shape[-1] != c.music_dim:
            raise ParameterError(f"music must be (B, n, {c.music_dim}), got {tuple(music.shape)}")
        if music.shape[1] < self.min_frames():
            raise ParameterError(f"music needs at least {self.min_frames()} frames, got {music.shape[1]}")
        parts = []
        if self.lstm is not None:
            h = music.transpose(1, 2)  # (B, D, n)
            for conv in self.convs:
                h = F.dropout(F.relu(conv(h)), c.dropout, self.training)  # (B, C_i, n_i)
            h, _ = self.lstm(h.transpose(1, 2))  # (B, n', 2 * hidden)
            parts.append(h.mean(dim=1))  # (B, 2 * hidden)
        if c.rhythm_bins:
            parts.append(log_lag_autocorrelation(music[:, :, c.rhythm_column], self.lags))  # (B, rhythm_bins)
        return self.head(torch.cat(parts, dim=-1))  # (B, n_classes)

    @torch.no_grad()
    def predict_song(self, music: np.ndarray | torch.Tensor) -> np.ndarray:
        """Class probabilities (n_classes,) of a whole song: ``music`` (n, D) normalised features.

        The song is cut into windows of ``config.window`` frames (hop ``window // 2``, the last window
        flush with the end); the result is the softmax of the windows' mean log-probability.
        """
        x = torch.as_tensor(np.asarray(music, dtype=np.float32))
        if x.dim() != 2:
            raise ParameterError(f"music must be (n, D), got {tuple(x.shape)}")
        w, n = self.config.window, x.shape[0]
        if n < self.min_frames():
            raise ParameterError(f"music needs at least {self.min_frames()} frames, got {n}")
        if n <= w:
            windows = x[None]
        else:
            starts = list(range(0, n - w + 1, max(1, w // 2)))
            if starts[-1] != n - w:
                starts.append(n - w)
            windows = torch.stack([x[s : s + w] for s in starts])  # (W, w, D)
        was_training = self.training
        self.eval()
        try:
            logp = F.log_softmax(self(windows), dim=-1).mean(0)  # (n_classes,)
        finally:
            self.train(was_training)
        return torch.softmax(logp, dim=0).numpy().astype(np.float64)
