"""Per-family dataset builders: ``build(data, config, stats) -> (train_set, val_set)``.

A family names its builder in :mod:`dancekit.registry` (``dataset="dancekit.training.datasets:..."``).
``data`` is a :class:`~dancekit.data.PreparedData`, ``config`` the run's
:class:`~dancekit.training.TrainConfig`, ``stats`` the training split's :class:`~dancekit.checkpoints.NormStats`.
"""

from __future__ import annotations

import numpy as np
import torch

from dancekit.checkpoints.stats import NormStats
from dancekit.data import PreparedData, WindowDataset
from dancekit.errors import ParameterError
from dancekit.motion import Motion, Skeleton
from dancekit.training.config import TrainConfig


def music_dance_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                        preset: str) -> tuple[WindowDataset, WindowDataset]:
    """Paired (music, dance) windows of ``config.seq_len`` frames (:class:`~dancekit.data.WindowDataset`):
    the training split with random offsets, genre balance and augmentations (mirror, heading, tempo) as
    configured, the validation split without."""
    common = dict(preset=preset, window=config.seq_len, stride=config.stride, stats=stats,
                  representation=config.representation, genres=config.genres)
    train_set = WindowDataset(data, "train", random_offset=config.random_offset, seed=config.seed,
                              balance_genres=config.balance_genres, mirror=config.augment_mirror,
                              heading=config.augment_heading, tempo=config.augment_tempo, **common)
    val_set = WindowDataset(data, "val", **common)
    return train_set, val_set


def refuse_augmentations(config: TrainConfig, what: str) -> None:
    """Raise :class:`ParameterError` if ``config`` asks for an augmentation (``augment_mirror``,
    ``augment_heading``, ``augment_tempo``) that the windows of ``what`` do not apply, rather than train
    without it."""
    asked = [f"{k}={v!r}" for k in ("augment_mirror", "augment_heading", "augment_tempo")
             if (v := getattr(config, k))]
    if asked:
        raise ParameterError(f"{what} does not apply {', '.join(asked)} (the augmentations work on positions3d and "
                             "rot6d windows: revolution, dual, music_attributes)")


# --------------------------------------------------------------------------------- style classifier windows


class StyleWindows(torch.utils.data.Dataset):
    """Windows of a style classifier: items ``{"x": (L, D) float32 normalised style inputs, "y": int64}``.

    Built by :func:`style_window_sets`. Attributes the model configuration takes from the data
    (registry ``data_fields``): ``in_dim``, ``genres``, ``fps``, ``class_weights``; the input statistics
    the checkpoint saves: ``stats`` (``input_mean``, ``input_std``).
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, *, genres: list[str], fps: float,
                 stats: dict[str, np.ndarray], class_weights: list[float] | None = None):
        self.x = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))  # (N, L, D)
        self.y = torch.from_numpy(np.asarray(y, dtype=np.int64))  # (N,)
        self.in_dim = int(self.x.shape[-1]) if self.x.ndim == 3 else len(stats["input_mean"])
        self.genres = list(genres)
        self.fps = float(fps)
        self.stats = stats
        self.class_weights = class_weights
        self.class_counts = np.bincount(self.y.numpy(), minlength=len(self.genres)).astype(int).tolist()

    def __len__(self) -> int:
        return len(self.y)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"x": self.x[i], "y": self.y[i]}


def style_window_sets(
    train: list[tuple[np.ndarray, int]],
    val: list[tuple[np.ndarray, int]],
    *,
    skeleton: Skeleton,
    fps: float,
    genres: list[str],
    window: int,
    stride: int,
    mirror: bool = True,
) -> tuple[StyleWindows, StyleWindows]:
    """Training and validation windows of a style classifier from labelled dances.

    Parameters
    ----------
    train, val : ``(positions (T, J, 3), genre index)`` dances at ``fps`` on ``skeleton``
    genres : genre names (the labels index them)
    window, stride : window length and the step between window starts, frames
    mirror : add the mirror image of every training dance (:meth:`~dancekit.motion.Motion.mirror`)

    The input statistics (``stats``) are the mean and standard deviation (floored at 1e-3) over every
    frame of every training window; the class weights are inversely proportional to each genre's
    training window count (0 for a genre without windows).
    """
    from dancekit.models.style import style_input

    def windows(dances: list[tuple[np.ndarray, int]], *, augment: bool) -> tuple[list[np.ndarray], list[int]]:
        xs, ys = [], []
        for positions, label in dances:
            if not 0 <= int(label) < len(genres):
                raise ParameterError(f"genre index {label} out of range for genres {genres}")
            variants = [positions]
            if augment:
                variants.append(Motion(skeleton=skeleton, fps=fps, positions=positions).mirror().positions)
            for v in variants:
                x = style_input(v, fps=fps, skeleton=skeleton)
                for s in range(0, len(x) - window + 1, stride):
                    xs.append(x[s : s + window])
                    ys.append(int(label))
        return xs, ys

    xs, ys = windows(train, augment=mirror)
    if not xs:
        raise ParameterError(f"no training dance is at least {window} frames ({window / fps:g} s) long")
    x = np.stack(xs)  # (N, L, D)
    y = np.asarray(ys)
    flat = x.reshape(-1, x.shape[-1]).astype(np.float64)
    mean = flat.mean(0).astype(np.float32)
    std = np.maximum(flat.std(0), 1e-3).astype(np.float32)
    counts = np.bincount(y, minlength=len(genres)).astype(np.float64)
    weights = np.where(counts > 0, counts.sum() / (np.count_nonzero(counts) * np.maximum(counts, 1)), 0.0)
    stats = {"input_mean": mean, "input_std": std}
    common = dict(genres=list(genres), fps=fps, stats=stats, class_weights=[float(w) for w in weights])
    train_set = StyleWindows((x - mean) / std, y, **common)
    vx, vy = windows(val, augment=False)
    val_x = (np.stack(vx) - mean) / std if vx else np.zeros((0, window, x.shape[-1]), np.float32)
    return train_set, StyleWindows(val_x, np.asarray(vy, np.int64), **common)


def style_windows(data: PreparedData, config: TrainConfig, stats: NormStats | None = None, *,
                  preset: str | None = None) -> tuple[StyleWindows, StyleWindows]:
    """Style classifier windows of a prepared dataset (:func:`style_window_sets`): ``config.seq_len``
    frames every ``config.stride`` frames (default ``seq_len // 8``) of the training dances and their mirror
    images, and of the validation dances. Reads motion only (``stats`` and ``preset`` are unused: the
    classifier's input statistics are the training set's ``stats``)."""
    refuse_augmentations(config, "the style classifier's windows (always with their mirror images)")

    def labelled(split: str) -> list[tuple[np.ndarray, int]]:
        return [(data.motion(n).to_positions(), data.genre_index(n)) for n in data.names(split)]

    return style_window_sets(labelled("train"), labelled("val"), skeleton=data.skeleton, fps=data.fps,
                             genres=list(data.genres), window=config.seq_len,
                             stride=config.stride or max(1, config.seq_len // 8))


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
