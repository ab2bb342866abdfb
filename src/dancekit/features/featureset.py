"""The :class:`FeatureSet` container and its ``.npz`` file format."""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, ParameterError

__all__ = ["FeatureSet", "parse_names"]


def parse_names(names: tuple[str, ...] | list[str]) -> list[tuple[str, int]]:
    """Split block labels ``"mfcc:20"`` into ``[("mfcc", 20), ...]``."""
    out = []
    for label in names:
        block, _, dim = str(label).partition(":")
        if not dim.isdigit():
            raise ParameterError(f"feature block label must look like 'name:dim', got {label!r}")
        out.append((block, int(dim)))
    return out


@dataclass(frozen=True, eq=False)
class FeatureSet:
    """Music features of one song, frame-aligned to a motion frame rate.

    Attributes
    ----------
    features : np.ndarray, float32, shape (T, D)
        Row ``i`` describes the audio around ``i / fps`` seconds (motion frame ``i``).
    names : tuple of str
        One label ``"block:dim"`` per column block, in column order; the dims
        add up to ``D`` (e.g. ``("mfcc:20", "mfcc_delta:20", ...)``).
    beat_times : np.ndarray, float64, shape (n_beats,)
        Beat times in seconds from the start of the analysed audio.
    fps : float
        Frame rate of ``features`` (frames per second).
    preset : str
        ``"revolution"``, ``"music2dance"`` or ``"dual"``.
    tempo : float
        Global tempo estimate in BPM (0.0 if no beat was found).
    hop_length : int
        Hop in samples at the feature sample rate ``fps * hop_length``.
    downbeat_times : np.ndarray or None
        Downbeat times in seconds (``music2dance`` only).
    beat_strength : float
        How strongly the audio pulses at a danceable tempo, 0 … 1
        (:func:`~dancekit.features.beat_strength`; below
        :data:`~dancekit.features.MUSIC_BEAT_STRENGTH` it does not look like music); NaN if unknown.
    from_cache : bool
        True when :func:`~dancekit.features.extract_file` read this from its cache.
    """

    features: np.ndarray
    names: tuple[str, ...]
    beat_times: np.ndarray
    fps: float
    preset: str
    tempo: float
    hop_length: int = 512
    downbeat_times: np.ndarray | None = None
    beat_strength: float = float("nan")
    from_cache: bool = field(default=False, compare=False)

    @property
    def num_frames(self) -> int:
        return int(self.features.shape[0])

    @property
    def dim(self) -> int:
        return int(self.features.shape[1])

    def columns(self, block: str) -> slice:
        """Column slice of a block, by its name without the dimension (e.g. ``"chroma_cqt"``)."""
        a = 0
        for name, d in parse_names(self.names):
            if name == block:
                return slice(a, a + d)
            a += d
        known = [n for n, _ in parse_names(self.names)]
        raise ParameterError(f"no feature block {block!r} in preset {self.preset!r}; blocks: {known}")

    def block(self, block: str) -> np.ndarray:
        """The ``(T, d)`` columns of one block, e.g. ``fs.block("chroma_cqt")``."""
        return self.features[:, self.columns(block)]

    def to_dict(self) -> dict[str, np.ndarray]:
        """Arrays as written to ``.npz`` (strings as unicode arrays: no pickle needed to read)."""
        d = {
            "features": np.ascontiguousarray(self.features, dtype=np.float32),
            "names": np.array(self.names, dtype=str),
            "beat_times": np.asarray(self.beat_times, dtype=np.float64),
            "fps": np.array(float(self.fps)),
            "preset": np.array(self.preset),
            "tempo": np.array(float(self.tempo)),
            "hop_length": np.array(int(self.hop_length)),
            "beat_strength": np.array(float(self.beat_strength)),
        }
        if self.downbeat_times is not None:
            d["downbeat_times"] = np.asarray(self.downbeat_times, dtype=np.float64)
        return d

    def save(self, path: str | os.PathLike) -> Path:
        """Write an uncompressed ``.npz`` atomically (keys: see :meth:`to_dict`)."""
        path = Path(path)
        with atomic_path(path, suffix=".npz") as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **self.to_dict())
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> FeatureSet:
        """Read a file written by :meth:`save`.

        Raises
        ------
        DancekitError
            If the file is missing, not an npz, lacks a key or is inconsistent.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                feats = z["features"]
                names = tuple(str(n) for n in z["names"])
                fs = cls(
                    features=feats,
                    names=names,
                    beat_times=z["beat_times"],
                    fps=float(z["fps"]),
                    preset=str(z["preset"]),
                    tempo=float(z["tempo"]) if "tempo" in z else 0.0,
                    hop_length=int(z["hop_length"]) if "hop_length" in z else 512,
                    downbeat_times=z["downbeat_times"] if "downbeat_times" in z else None,
                    beat_strength=float(z["beat_strength"]) if "beat_strength" in z else float("nan"),
                )
            if (
                feats.ndim != 2
                or feats.dtype != np.float32
                or sum(d for _, d in parse_names(names)) != feats.shape[1]
            ):
                raise ValueError(f"inconsistent: features {feats.shape} {feats.dtype}, names {names}")
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise DancekitError(f"cannot read feature file {str(path)!r}: {exc}") from None
        return fs
