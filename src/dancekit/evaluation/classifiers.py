"""How well do the classifiers classify? Accuracy on the real dances (style) and songs (music attributes).

``dancekit score-classifier CHECKPOINT... --data DIR`` runs :func:`score_classifier` for either family:

- a **style classifier** (family ``style``, motion → genre): accuracy and balanced accuracy per window and
  per whole dance on every split (:func:`style_classifier_scores`);
- a **music attribute classifier** (family ``music_attributes``, music → genre): per-song accuracy of each
  split and every prediction (:func:`music_attribute_scores`; a song's genre is the mean log-probability
  of its windows of the prepared features of the classifier's preset).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from dancekit.errors import CheckpointError, ParameterError
from dancekit.metrics.style import classification_scores

__all__ = ["SPLITS", "music_attribute_scores", "score_classifier", "style_classifier_scores", "style_split_scores"]

SPLITS = ("train", "val", "test")


def style_classifier_scores(style: Any, dances: Sequence[tuple[np.ndarray, int]], *, fps: float) -> dict:
    """Accuracy and balanced accuracy of a :class:`~dancekit.pipelines.StylePipeline` on labelled dances
    ``(positions (T, J, 3), genre index)`` at ``fps``, per window and per dance
    (:func:`dancekit.metrics.style.classification_scores`)."""
    log_probs = [style.embed(positions, fps=fps)[1] for positions, _ in dances]
    return classification_scores(log_probs, [label for _, label in dances], genres=style.genres)


def style_split_scores(style: Any, data: Any, *, splits: Sequence[str] = SPLITS) -> dict:
    """:func:`style_classifier_scores` on the real dances of every split of a prepared dataset (None for an
    empty split), plus the test dances' names (``test_names``)."""
    unknown = sorted({data.genre(n) for n in data.names()} - set(style.genres))
    if unknown:
        raise ParameterError(f"the style classifier knows the genres {style.genres}, not {unknown}")
    report: dict[str, Any] = {}
    for split in splits:
        dances = [(data.motion(n).to_positions(), style.genres.index(data.genre(n))) for n in data.names(split)]
        report[split] = style_classifier_scores(style, dances, fps=data.fps) if dances else None
    report["test_names"] = data.names("test")
    return report


def music_attribute_scores(pipe: Any, data: Any, *, splits: Sequence[str] = SPLITS) -> dict:
    """Per-song accuracy of a :class:`~dancekit.pipelines.MusicAttributePipeline` on every split:
    ``{split: {"accuracy", "predictions": {song: genre}}}``."""
    report: dict[str, Any] = {}
    for split in splits:
        pred = {}
        for name in data.names(split):
            probs = pipe.classify_features(data.features(name, pipe.preset)["features"], source=name)
            pred[name] = max(probs, key=probs.get)
        acc = float(np.mean([data.genre(n) == g for n, g in pred.items()])) if pred else float("nan")
        report[split] = {"accuracy": acc, "predictions": pred}
    return report


def score_classifier(checkpoint: str | os.PathLike, data: Any, *, splits: Sequence[str] = SPLITS) -> dict:
    """Scores of a classifier checkpoint (a folder or model name) on a prepared dataset, by its family.

    Raises
    ------
    CheckpointError
        For a checkpoint that is not a style or music attribute classifier.
    """
    from dancekit.checkpoints import resolve_model
    from dancekit.checkpoints.hub import read_meta

    folder = resolve_model(checkpoint)
    family = read_meta(folder)["model"]
    if family == "style":
        from dancekit.pipelines.style import StylePipeline

        scores = style_split_scores(StylePipeline.from_pretrained(folder), data, splits=splits)
    elif family == "music_attributes":
        from dancekit.pipelines.music_attributes import MusicAttributePipeline

        scores = music_attribute_scores(MusicAttributePipeline.from_pretrained(folder), data, splits=splits)
    else:
        raise CheckpointError(f"{folder} holds a {family!r} model, not a classifier (style or music_attributes)")
    return {"checkpoint": str(checkpoint), "family": family, **scores}
