"""Per-family dataset builders: ``build(data, config, stats) -> (train_set, val_set)``.

A family names its builder in :mod:`dancekit.registry` (``dataset="dancekit.training.datasets:..."``).
``data`` is a :class:`~dancekit.data.PreparedData`, ``config`` the run's
:class:`~dancekit.training.TrainConfig`, ``stats`` the training split's :class:`~dancekit.checkpoints.NormStats`.
"""

from __future__ import annotations

from dancekit.checkpoints.stats import NormStats
from dancekit.data import PreparedData, WindowDataset
from dancekit.training.loop import TrainConfig


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


def raw_columns(*, preset: str, representation: str) -> tuple[int, int]:
    """(first raw music column, first raw dance column) of the dual-learning model: the ``dual`` preset's chroma +
    beat blocks and ``rot6d``'s 6D rotations stay as they are (the generators output them and the losses compare
    them raw); the MFCC blocks and the root translation are normalised."""
    from dancekit.errors import ParameterError
    from dancekit.features import PRESETS
    from dancekit.motion.representations import ROT6D_TRANSLATION

    if preset != "dual" or representation != "rot6d":
        raise ParameterError(f"the dual-learning model needs preset 'dual' and representation 'rot6d', got "
                             f"{preset!r} and {representation!r} (--set representation=rot6d)")
    names = [name for name, _ in PRESETS[preset]]
    music_raw_from = sum(d for name, d in PRESETS[preset][: names.index("chroma_harmonic")])
    return music_raw_from, ROT6D_TRANSLATION


def partial_stats(stats: NormStats, *, music_raw_from: int, dance_raw_from: int) -> NormStats:
    """``stats`` with mean 0 and std 1 from ``music_raw_from`` / ``dance_raw_from`` on (those columns stay raw)."""
    import numpy as np

    def keep(mean, std, start):
        mean, std = np.array(mean, np.float32), np.array(std, np.float32)
        mean[start:], std[start:] = 0.0, 1.0
        return mean, std

    music_mean, music_std = keep(stats.music_mean, stats.music_std, music_raw_from)
    dance_mean, dance_std = keep(stats.dance_mean, stats.dance_std, dance_raw_from)
    return NormStats(music_mean=music_mean, music_std=music_std, dance_mean=dance_mean, dance_std=dance_std)


def dual_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                 preset: str) -> tuple[WindowDataset, WindowDataset]:
    """(music, dance) windows for the dual-learning model (:mod:`dancekit.models.dual`): the ``dual`` preset and
    ``rot6d``, normalised except the chroma + beat and the 6D columns (:func:`raw_columns`). The datasets carry
    ``music_raw_from`` and ``dance_raw_from`` for the model configuration (the family's data fields)."""
    music_raw_from, dance_raw_from = raw_columns(preset=preset, representation=config.representation)
    stats = partial_stats(stats, music_raw_from=music_raw_from, dance_raw_from=dance_raw_from)
    sets = music_dance_windows(data, config, stats, preset=preset)
    for ds in sets:
        ds.music_raw_from, ds.dance_raw_from = music_raw_from, dance_raw_from
    return sets
