"""Style classifier inference: a dance → the probability of each genre and its window features.

    >>> pipe = StylePipeline.from_pretrained("style")            # the embedded classifier   # doctest: +SKIP
    >>> result = pipe(motion)                                                                 # doctest: +SKIP
    >>> result.genre, result.genre_probs, result.features.shape                               # doctest: +SKIP
    ('waltz', {'waltz': 0.93, ...}, (7, 32))

The checkpoint folder (``dancekit train style``, or the embedded ``dancekit/assets/models/style/``)
carries the classifier (:mod:`dancekit.models.style`), the skeleton it was trained on and the input
statistics (``stats.npz``: ``input_mean``, ``input_std``). The window features are what the Dance
Revolution style metrics (:mod:`dancekit.metrics.style`) compare.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from dancekit._checks import check_fps, check_positions
from dancekit.checkpoints import load_pretrained, resolve_model
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.style import StyleClassifier, style_input
from dancekit.motion import Motion, Skeleton
from dancekit.motion.analysis import resample_positions

__all__ = ["DEFAULT_STYLE_MODEL", "StylePipeline", "StyleResult"]

#: The name of the embedded style classifier (``dancekit/assets/models/style/``).
DEFAULT_STYLE_MODEL = "style"


@dataclass
class StyleResult:
    """What the style classifier reads in one dance.

    Attributes
    ----------
    genre : the genre of the whole dance (argmax of the mean window log-probability)
    genre_probs : genre → probability (the normalised geometric mean of the window probabilities)
    features : window features ``(K, F)`` (consecutive windows)
    log_probs : window log-probabilities ``(K, G)``
    """

    genre: str
    genre_probs: dict[str, float] = field(default_factory=dict)
    features: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    log_probs: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def dance_features(self) -> np.ndarray:
        """The dance's feature vector ``(F,)``: the mean of its window features."""
        return self.features.mean(axis=0)


class StylePipeline:
    """A trained style classifier with its input statistics, skeleton and frame rate (inference only).

    Parameters
    ----------
    model : the trained :class:`~dancekit.models.style.StyleClassifier`
    skeleton : the skeleton it was trained on (dances must have its joints)
    mean, std : the input statistics ``(6J + 4,)``
    meta : the checkpoint's ``config.json`` (recorded in reports)
    folder : where it was loaded from
    """

    def __init__(self, model: StyleClassifier, *, skeleton: Skeleton, mean: np.ndarray, std: np.ndarray,
                 meta: dict[str, Any] | None = None, folder: str = "?"):
        if not isinstance(model, StyleClassifier):
            raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a style classifier")
        self.model = model.eval()
        self.config = model.config
        self.skeleton = skeleton
        self.mean = np.asarray(mean, np.float32)
        self.std = np.asarray(std, np.float32)
        self.meta = dict(meta or {})
        self.folder = str(folder)
        if self.mean.shape != (self.config.in_dim,) or self.std.shape != (self.config.in_dim,):
            raise CheckpointError(f"checkpoint {folder}: style classifier statistics must have "
                                  f"{self.config.in_dim} values")

    @classmethod
    def from_pretrained(cls, name_or_folder: str | os.PathLike = DEFAULT_STYLE_MODEL, *,
                        device: str = "cpu") -> StylePipeline:
        """Load a style classifier: a checkpoint folder or a model name (default: the embedded one).

        Raises
        ------
        CheckpointError
            If the folder is missing, incomplete or not a style classifier.
        ParameterError
            For an unknown model name.
        """
        folder = resolve_model(name_or_folder)
        model, meta, stats = load_pretrained(folder, device=device)
        if meta.get("model") != "style":
            raise CheckpointError(f"{folder} is a {meta.get('model')!r} checkpoint, not a style classifier")
        for key in ("input_mean", "input_std"):
            if key not in stats:
                raise CheckpointError(f"{folder}/stats.npz has no {key!r}")
        if "skeleton" not in meta:
            raise CheckpointError(f"{folder}/config.json has no skeleton")
        return cls(model, skeleton=Skeleton.from_dict(meta["skeleton"]), mean=stats["input_mean"],
                   std=stats["input_std"], meta=meta, folder=str(Path(folder)))

    @property
    def genres(self) -> list[str]:
        return list(self.config.genres)

    @property
    def fps(self) -> float:
        return float(self.config.fps)

    @property
    def window(self) -> int:
        """Frames per window at the classifier's fps."""
        return int(self.config.window)

    def check_skeleton(self, skeleton: Skeleton) -> None:
        """Raise :class:`ParameterError` unless ``skeleton`` has the classifier's joints."""
        if tuple(skeleton.joint_names) != tuple(self.skeleton.joint_names):
            raise ParameterError(
                f"the style classifier was trained on skeleton {self.skeleton.name!r} "
                f"({self.skeleton.num_joints} joints); this dance uses {skeleton.name!r} ({skeleton.num_joints})"
            )

    def windows(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None,
                stride: int | None = None) -> np.ndarray:
        """Normalised consecutive windows ``(K, L, D)`` of one dance ``(T, J, 3)``.

        The dance is resampled linearly to the classifier's fps; windows are ``window`` frames long and
        start every ``stride`` frames (default: ``window``, i.e. non-overlapping); a dance shorter than
        one window (but at least 1 s long) is a single shorter window.
        """
        skeleton = skeleton or self.skeleton
        self.check_skeleton(skeleton)
        fps = check_fps(fps)
        p = resample_positions(check_positions(positions, skeleton, min_frames=2), orig_fps=fps, target_fps=self.fps)
        x = (style_input(p, fps=self.fps, skeleton=skeleton) - self.mean) / self.std
        L = self.window
        if len(x) < L:
            if len(x) < self.fps:
                raise ParameterError(f"dance too short for the style classifier: {len(x) / self.fps:.2f} s < 1 s")
            return x[None]
        step = int(stride or L)
        return np.stack([x[s : s + L] for s in range(0, len(x) - L + 1, step)])

    @torch.no_grad()
    def embed(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None,
              stride: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(features (K, F), log_probs (K, G))`` float64 of the consecutive windows of one dance."""
        w = torch.from_numpy(np.ascontiguousarray(self.windows(positions, fps=fps, skeleton=skeleton,
                                                               stride=stride)))
        feats, logp = [], []
        for chunk in torch.split(w, 256):
            f = self.model.features(chunk)  # (B, F)
            feats.append(f)
            logp.append(F.log_softmax(self.model.head(f), dim=-1))  # (B, G)
        return torch.cat(feats).numpy().astype(np.float64), torch.cat(logp).numpy().astype(np.float64)

    def predict(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None) -> int:
        """Genre index of a whole dance: argmax of the mean window log-probability."""
        _, logp = self.embed(positions, fps=fps, skeleton=skeleton)
        return int(np.argmax(logp.mean(axis=0)))

    def __call__(self, motion: Motion, *, stride: int | None = None) -> StyleResult:
        """The genre of a dance, the probability of each genre and its window features."""
        feats, logp = self.embed(motion.to_positions(), fps=motion.fps, skeleton=motion.skeleton, stride=stride)
        mean = logp.mean(axis=0)
        probs = np.exp(mean - mean.max())
        probs /= probs.sum()
        return StyleResult(genre=self.genres[int(np.argmax(mean))],
                           genre_probs={g: float(p) for g, p in zip(self.genres, probs)},
                           features=feats, log_probs=logp)
