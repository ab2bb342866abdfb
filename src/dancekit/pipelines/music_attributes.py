"""Music attribute inference: a song → the probability of each dance genre (inference only).

    >>> pipe = MusicAttributePipeline.from_pretrained("runs/music_attributes/model")   # doctest: +SKIP
    >>> pipe("song.ogg")                                                                # doctest: +SKIP
    {'waltz': 0.71, 'rumba': 0.22, 'chacha': 0.05, 'tango': 0.02}

The checkpoint folder (``dancekit train music_attributes``) carries the classifier, the feature preset,
fps and hop length it was trained with, the class names (``genres``) and the normalisation statistics.
A composite dance model may declare one as its ``genre_reader`` component: the Dance Revolution pipeline
then reads the genre of a song from its music and dances it with the matching genre model.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from dancekit.checkpoints import load_pretrained, resolve_model
from dancekit.errors import CheckpointError
from dancekit.models.music_attributes import MusicAttributeClassifier


class MusicAttributePipeline:
    """Classify the dance genre a song calls for with a trained :class:`MusicAttributeClassifier`.

    Parameters
    ----------
    model : the trained classifier
    meta : the checkpoint's ``config.json`` (needs ``fps`` and ``genres``, the class names in order;
        ``preset`` and ``hop_length`` default to ``music2dance`` and 512)
    arrays : the normalisation statistics (``music_mean``, ``music_std``)
    """

    def __init__(self, model: MusicAttributeClassifier, *, meta: dict[str, Any], arrays: dict[str, np.ndarray],
                 folder: str = "?"):
        if not isinstance(model, MusicAttributeClassifier):
            raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a music attribute classifier")
        for key in ("fps", "genres"):
            if key not in meta:
                raise CheckpointError(f"checkpoint {folder}: config.json has no {key!r} entry")
        missing = [k for k in ("music_mean", "music_std") if k not in arrays]
        if missing:
            raise CheckpointError(f"checkpoint {folder}: stats.npz lacks {missing}")
        self.model = model.eval()
        self.meta = meta
        self.fps = float(meta["fps"])
        self.preset = str(meta.get("preset", "music2dance"))
        self.hop_length = int(meta.get("hop_length", 512))
        self.genres = tuple(str(g) for g in meta["genres"])
        self.music_mean = np.asarray(arrays["music_mean"], np.float32)
        self.music_std = np.asarray(arrays["music_std"], np.float32)
        if len(self.genres) != model.config.n_classes:
            raise CheckpointError(f"checkpoint {folder}: {len(self.genres)} genres for a classifier of "
                                  f"{model.config.n_classes} classes")
        if len(self.music_mean) != model.config.music_dim:
            raise CheckpointError(f"checkpoint {folder}: statistics of {len(self.music_mean)} columns for "
                                  f"music_dim {model.config.music_dim}")

    @classmethod
    def from_pretrained(cls, folder: str | os.PathLike, *, device: str = "cpu") -> MusicAttributePipeline:
        """Load a checkpoint folder written by ``dancekit train music_attributes``.

        Raises
        ------
        CheckpointError
            For a missing or corrupt folder, or one that holds another model family.
        """
        folder = resolve_model(folder)
        model, meta, arrays = load_pretrained(folder, device=device)
        return cls(model, meta=meta, arrays=arrays, folder=str(Path(folder)))

    def __call__(self, audio_path: str | os.PathLike, *, start: float | None = None,
                 end: float | None = None) -> dict[str, float]:
        """Probability of each genre (in the checkpoint's order, summing to 1) for the song or its
        excerpt ``[start, end)`` seconds.

        Raises
        ------
        AudioError
            For a missing, unreadable or too short song.
        """
        from dancekit.features import extract_file

        fs = extract_file(audio_path, fps=self.fps, preset=self.preset, start=start, end=end,
                          hop_length=self.hop_length)
        return self.classify_features(fs.features, source=str(audio_path))

    def classify_features(self, features: np.ndarray, *, source: str = "the music") -> dict[str, float]:
        """Probability of each genre for a song's ``features`` (T, D): the checkpoint's preset at its fps,
        not normalised (e.g. ``PreparedData.features(name, pipe.preset)["features"]``)."""
        feats = np.asarray(features, np.float32)
        if feats.ndim != 2 or feats.shape[1] != self.model.config.music_dim:
            raise CheckpointError(f"the {self.preset!r} features of {source} have shape {feats.shape}, but "
                                  f"the classifier expects {self.model.config.music_dim} columns")
        probs = self.model.predict_song((feats - self.music_mean) / self.music_std)  # (n_classes,)
        return {g: float(p) for g, p in zip(self.genres, probs)}
