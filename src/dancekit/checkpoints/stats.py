"""Normalisation statistics as plain arrays (never pickled objects)."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import CheckpointError

#: Rows (frames) normalised at a time by :meth:`NormStats.normalize_music`.
_ROWS = 4096

@dataclass
class NormStats:
    """Per-column mean and standard deviation of the music features and the dance features.

    ``normalize_*`` maps to zero mean / unit variance; ``denormalize_*`` inverts it.
    Standard deviations are floored at ``min_std`` so constant columns (e.g. a
    beat one-hot that never fires) stay finite.
    """

    music_mean: np.ndarray  # (D,)
    music_std: np.ndarray  # (D,)
    dance_mean: np.ndarray  # (P,)
    dance_std: np.ndarray  # (P,)

    @classmethod
    def compute(cls, music: list[np.ndarray], dance: list[np.ndarray], *, min_std: float = 1e-3) -> NormStats:
        """Statistics over all frames of a list of ``(T_i, D)`` music and ``(T_i, P)`` dance arrays."""
        m = np.concatenate([np.asarray(a, np.float64) for a in music], axis=0)
        d = np.concatenate([np.asarray(a, np.float64) for a in dance], axis=0)
        return cls(
            music_mean=m.mean(0).astype(np.float32),
            music_std=np.maximum(m.std(0), min_std).astype(np.float32),
            dance_mean=d.mean(0).astype(np.float32),
            dance_std=np.maximum(d.std(0), min_std).astype(np.float32),
        )

    def normalize_music(self, x: np.ndarray) -> np.ndarray:
        """``((x - music_mean) / music_std)`` as float32, ``x (..., music_dim)``; a song's features ``(T, D)``
        are done a few thousand frames at a time (the same numbers, without two float64 copies of an hour of
        features)."""
        x = np.asarray(x)
        if x.ndim < 2:
            return ((x - self.music_mean) / self.music_std).astype(np.float32)
        out = np.empty(np.broadcast_shapes(x.shape, np.shape(self.music_mean)), np.float32)
        for a in range(0, len(out), _ROWS):
            out[a: a + _ROWS] = (x[a: a + _ROWS] - self.music_mean) / self.music_std
        return out

    def normalize_dance(self, x: np.ndarray) -> np.ndarray:
        return ((x - self.dance_mean) / self.dance_std).astype(np.float32)

    def denormalize_dance(self, x: np.ndarray) -> np.ndarray:
        return (x * self.dance_std + self.dance_mean).astype(np.float32)

    def save(self, path: str | os.PathLike) -> None:
        with atomic_path(path) as tmp:
            np.savez(tmp, **self.as_arrays())

    def as_arrays(self) -> dict[str, np.ndarray]:
        return {
            "music_mean": self.music_mean,
            "music_std": self.music_std,
            "dance_mean": self.dance_mean,
            "dance_std": self.dance_std,
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], *, source: str = "?") -> NormStats:
        """The statistics in a checkpoint's ``stats.npz`` arrays (copied as float32).

        Raises
        ------
        CheckpointError
            Naming ``source`` and the missing arrays when one of the four is absent.
        """
        keys = ("music_mean", "music_std", "dance_mean", "dance_std")
        missing = [k for k in keys if k not in arrays]
        if missing:
            raise CheckpointError(f"checkpoint {source}: stats.npz lacks {missing}")
        return cls(**{k: np.array(arrays[k], np.float32) for k in keys})

    @classmethod
    def load(cls, path: str | os.PathLike) -> NormStats:
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls(**{k: np.asarray(z[k], np.float32) for k in ("music_mean", "music_std", "dance_mean", "dance_std")})
        except (OSError, KeyError, ValueError) as exc:
            raise CheckpointError(f"cannot read normalisation statistics {path}: {exc}") from exc
