"""Style (genre) classifier: which genre is this dance? From motion alone.

One file, one model: :class:`StyleClassifierConfig` (a dataclass saved with the weights) and
:class:`StyleClassifier` (an ``nn.Module(config)``), plus its input representation :func:`style_input`.
Its penultimate activations are the feature space of the Dance Revolution style metrics
(:mod:`dancekit.metrics.style`); inference: :class:`dancekit.pipelines.StylePipeline`; training: the
generic loop, family ``"style"`` (``dancekit train style --data DIR --out RUN``).

Input representation (per frame, at the classifier's fps)
    Every joint relative to the pelvis, rotated about the up axis into the body's heading frame
    (:func:`dancekit.motion.analysis.heading_axes`: x = the body's left, from the hip and shoulder
    lines; y = up; z = forward), in metres (3J); their velocities in m/s (3J); the root velocity in the
    heading frame (m/s, 3) and the yaw rate (rad/s, 1): ``6J + 4`` values (142 for tang2018),
    standardised with the training statistics (``stats.npz``: ``input_mean``, ``input_std``).

Network
    Three 1-D convolutions over time (kernel 5; the last two with stride 2), GELU, a mean over time, a
    linear layer to ``feature_dim`` (the features), dropout and a linear layer to the genres. Trained on
    windows of ``window`` frames (4 s) cut every 0.5 s from the training dances and their mirror images,
    with a class-weighted cross-entropy (weights inversely proportional to each genre's window count:
    tang2018 has 26 waltzes and one tango).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancekit._checks import check_fps, check_positions
from dancekit.errors import ParameterError
from dancekit.motion.analysis import heading_rotation
from dancekit.motion.skeleton import Skeleton

__all__ = ["StyleClassifier", "StyleClassifierConfig", "input_dim", "style_input"]

#: Version tag of :func:`style_input`, recorded in checkpoints (``config.json`` ``"input"``).
INPUT_VERSION = "style_input v1 (6J+4)"


def input_dim(skeleton: Skeleton) -> int:
    """Columns of :func:`style_input` for ``skeleton``: ``6J + 4``."""
    return 6 * skeleton.num_joints + 4


def style_input(positions: np.ndarray, *, fps: float, skeleton: Skeleton) -> np.ndarray:
    """Per-frame classifier input ``(T, 6J + 4)`` float32 of world positions ``(T, J, 3)`` (unnormalised;
    see the module docstring). The pelvis is the ``pelvis`` role, else the skeleton's root."""
    fps = check_fps(fps)
    p = check_positions(positions, skeleton, min_frames=2) * skeleton.unit_scale  # (T, J, 3) metres
    R = heading_rotation(p, skeleton)  # (T, 3, 3): world -> body rows (left, up, forward)
    lateral, ups = R[:, 0], R[:, 1]
    r = skeleton.index("pelvis") if skeleton.has("pelvis") else skeleton.root
    root = p[:, r]
    local = np.einsum("tij,tkj->tki", R, p - root[:, None, :])  # (T, J, 3)
    local_v = np.gradient(local, axis=0) * fps
    root_v = np.einsum("tij,tj->ti", R, np.gradient(root, axis=0) * fps)
    # yaw rate: signed angle between consecutive lateral axes about up
    lat_next = np.gradient(lateral, axis=0)
    yaw = np.sum(np.cross(lateral, lat_next) * ups, axis=-1) * fps
    T = len(p)
    out = np.concatenate([local.reshape(T, -1), local_v.reshape(T, -1), root_v, yaw[:, None]], axis=1)
    return out.astype(np.float32)


@dataclass
class StyleClassifierConfig:
    """Hyper-parameters of :class:`StyleClassifier` (saved in ``config.json``)."""

    in_dim: int  # D = 6J + 4
    genres: list[str]
    window: int = 100  # frames per window (4 s at 25 fps)
    fps: float = 25.0
    channels: int = 64
    feature_dim: int = 32
    kernel_size: int = 5
    dropout: float = 0.2
    class_weights: list[float] | None = None  # per genre, for the training loss

    def __post_init__(self) -> None:
        if self.in_dim < 1 or self.channels < 1 or self.feature_dim < 1 or self.window < 8:
            raise ParameterError(f"bad StyleClassifierConfig sizes: {self}")
        if len(self.genres) < 2:
            raise ParameterError(f"a style classifier needs at least 2 genres, got {self.genres}")
        if self.class_weights is not None and len(self.class_weights) != len(self.genres):
            raise ParameterError("class_weights must have one weight per genre")


class StyleClassifier(nn.Module):
    """1-D convolutional genre classifier over windows ``(B, L, D)`` of normalised inputs."""

    family: ClassVar[str] = "style"

    def __init__(self, config: StyleClassifierConfig):
        super().__init__()
        self.config = config
        c, k = config.channels, config.kernel_size
        self.convs = nn.ModuleList(
            [
                nn.Conv1d(config.in_dim, c, k, padding=k // 2),
                nn.Conv1d(c, c, k, stride=2, padding=k // 2),
                nn.Conv1d(c, c, k, stride=2, padding=k // 2),
            ]
        )
        self.proj = nn.Linear(c, config.feature_dim)
        self.drop = nn.Dropout(config.dropout)
        self.head = nn.Linear(config.feature_dim, len(config.genres))
        weights = config.class_weights or [1.0] * len(config.genres)
        self.register_buffer("class_weights", torch.tensor(weights, dtype=torch.float32), persistent=False)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Penultimate features ``(B, feature_dim)`` of windows ``x (B, L, D)``."""
        h = x.transpose(1, 2)  # (B, D, L)
        for conv in self.convs:
            h = F.gelu(conv(h))  # (B, C, L')
        h = h.mean(dim=2)  # (B, C)
        return F.gelu(self.proj(h))  # (B, F)

    def forward(
        self, x: torch.Tensor, targets: torch.Tensor | None = None
    ) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """Logits ``(B, G)``; with ``targets (B,)`` also the class-weighted cross-entropy."""
        logits = self.head(self.drop(self.features(x)))  # (B, G)
        if targets is None:
            return logits
        return logits, F.cross_entropy(logits, targets, weight=self.class_weights)
