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

FRONTENDS = ("conv", "fc")


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
    frontend: str = "conv"  # conv (the paper's model) | fc (its FC+Bi-LSTM baseline)

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
        for i, out in enumerate(c.channels):
            if c.frontend == "fc":  # a per-frame linear layer, as a kernel-1 convolution
                convs.append(nn.Conv1d(width, out, 1))
            else:
                stride = 2 if i == len(c.channels) - 1 else 1
                convs.append(nn.Conv1d(width, out, c.kernel, stride=stride))
            width = out
        self.convs = nn.ModuleList(convs)
        self.lstm = nn.LSTM(width, c.lstm_hidden, batch_first=True, bidirectional=True)
        self.head = nn.Linear(2 * c.lstm_hidden, c.n_classes)

    def min_frames(self) -> int:
        """Shortest input (frames) that leaves at least one step after the convolutions."""
        n = 1
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
        h = music.transpose(1, 2)  # (B, D, n)
        for conv in self.convs:
            h = F.dropout(F.relu(conv(h)), c.dropout, self.training)  # (B, C_i, n_i)
        h, _ = self.lstm(h.transpose(1, 2))  # (B, n', 2 * hidden)
        return self.head(h.mean(dim=1))  # (B, n_classes)

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
