"""Per-family dataset builders: ``build(data, config, stats) -> (train_set, val_set)``.

A family names its builder in :mod:`dancekit.registry` (``dataset="dancekit.training.datasets:..."``).
``data`` is a :class:`~dancekit.data.PreparedData`, ``config`` the run's
:class:`~dancekit.training.TrainConfig`, ``stats`` the training split's :class:`~dancekit.checkpoints.NormStats`.
"""

from __future__ import annotations

from dancekit.checkpoints.stats import NormStats
from dancekit.data import PreparedData, WindowDataset
from dancekit.training.config import TrainConfig


def music_dance_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                        preset: str) -> tuple[WindowDataset, WindowDataset]:
    """Paired (music, dance) windows of ``config.seq_len`` frames (:class:`~dancekit.data.WindowDataset`):
    the training split with random offsets and genre balance as configured, the validation split without."""
    common = dict(preset=preset, window=config.seq_len, stride=config.stride, stats=stats,
                  representation=config.representation, genres=config.genres)
    train_set = WindowDataset(data, "train", random_offset=config.random_offset, seed=config.seed,
                              balance_genres=config.balance_genres, **common)
    val_set = WindowDataset(data, "val", **common)
    return train_set, val_set
