"""The Dance Revolution style metrics (Table 2) on the features of a style classifier.

The style classifier (:mod:`dancekit.models.style`; inference :class:`dancekit.pipelines.StylePipeline`)
recognises the genre of a dance from motion alone. Its penultimate activations of consecutive windows
(4 s for the shipped classifier) are the feature space of these metrics; here they are plain arrays:

* **FID** (:func:`style_fid`) — Fréchet distance between the window features of the generated dances
  and of the real dances (classifier features are used as they are, not z-scored);
* **ACC** — share of generated dances classified as the genre of their music (a dance's genre:
  :func:`dance_genre`, the argmax of the mean log-probability over its windows);
* **Diversity** (:func:`style_diversity`) — mean feature distance over random pairs of generated dances
  for *different* music (Lee et al. 2019; Dance Revolution samples 500 pairs);
* **Multimodality** (:func:`multimodality`) — mean feature distance among the dances generated for the
  *same* music (5 per song in the paper), averaged over songs.

A dance's feature vector is the mean of its window features. :func:`classification_scores` measures the
classifier itself (accuracy and balanced accuracy, per window and per dance).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dancekit.errors import ParameterError
from dancekit.metrics.fid import average_pairwise_distance, frechet_distance

__all__ = [
    "balanced_accuracy",
    "classification_scores",
    "dance_genre",
    "multimodality",
    "style_diversity",
    "style_fid",
]


def balanced_accuracy(y_true: Sequence[int], y_pred: Sequence[int]) -> float:
    """Mean over the classes present in ``y_true`` of the per-class recall (NaN without labels)."""
    t, p = np.asarray(y_true), np.asarray(y_pred)
    if len(t) == 0:
        return float("nan")
    return float(np.mean([np.mean(p[t == c] == c) for c in np.unique(t)]))


def dance_genre(log_probs: np.ndarray) -> int:
    """Genre index of a whole dance from its window log-probabilities ``(K, G)``: argmax of their mean."""
    lp = np.asarray(log_probs, np.float64)
    if lp.ndim != 2 or len(lp) == 0:
        raise ParameterError(f"window log-probabilities must have shape (K >= 1, G), got {lp.shape}")
    return int(np.argmax(lp.mean(axis=0)))


def classification_scores(log_probs: Sequence[np.ndarray], labels: Sequence[int], *,
                          genres: Sequence[str]) -> dict:
    """Accuracy and balanced accuracy of a classifier on labelled dances, per window and per dance.

    Parameters
    ----------
    log_probs : per dance, its window log-probabilities ``(K_i, G)``
    labels : per dance, the index of its true genre in ``genres``
    genres : the classifier's genre names

    Returns
    -------
    dict: ``window_accuracy``, ``window_balanced_accuracy``, ``dance_accuracy``,
    ``dance_balanced_accuracy`` (NaN without dances), ``n_windows``, ``n_dances`` and
    ``dance_predictions`` (``[true genre, predicted genre]`` per dance).
    """
    if len(log_probs) != len(labels):
        raise ParameterError(f"{len(log_probs)} dances of log-probabilities but {len(labels)} labels")
    win_true, win_pred, dance_true, dance_pred = [], [], [], []
    for lp, label in zip(log_probs, labels):
        pred = np.asarray(lp).argmax(axis=1)
        win_true += [int(label)] * len(pred)
        win_pred += pred.tolist()
        dance_true.append(int(label))
        dance_pred.append(dance_genre(lp))
    wt, wp = np.asarray(win_true), np.asarray(win_pred)
    return {
        "window_accuracy": float(np.mean(wt == wp)) if len(wt) else float("nan"),
        "window_balanced_accuracy": balanced_accuracy(wt, wp),
        "dance_accuracy": float(np.mean(np.asarray(dance_true) == np.asarray(dance_pred))) if dance_true else float("nan"),
        "dance_balanced_accuracy": balanced_accuracy(dance_true, dance_pred),
        "n_windows": int(len(wt)),
        "n_dances": int(len(dance_true)),
        "dance_predictions": [[genres[t], genres[p]] for t, p in zip(dance_true, dance_pred)],
    }


def style_diversity(features: np.ndarray, music: Sequence[str], *, pairs: int = 500, seed: int = 0) -> float:
    """Mean distance over random pairs of dance features ``(N, F)`` for different music.

    Up to ``pairs`` distinct pairs are drawn (all of them when there are fewer), seeded.
    """
    f = np.asarray(features, np.float64)
    music = list(music)
    if len(music) != len(f):
        raise ParameterError(f"{len(f)} feature vectors but {len(music)} music names")
    cand = [(i, j) for i in range(len(f)) for j in range(i + 1, len(f)) if music[i] != music[j]]
    if not cand:
        return float("nan")
    rng = np.random.default_rng(seed)
    if len(cand) > pairs:
        cand = [cand[k] for k in rng.choice(len(cand), size=pairs, replace=False)]
    return float(np.mean([np.linalg.norm(f[i] - f[j]) for i, j in cand]))


def multimodality(features: np.ndarray, music: Sequence[str]) -> float:
    """Mean pairwise feature distance among dances for the same music, averaged over songs with ≥ 2 dances."""
    f = np.asarray(features, np.float64)
    music = list(music)
    if len(music) != len(f):
        raise ParameterError(f"{len(f)} feature vectors but {len(music)} music names")
    per_song = []
    for song in sorted(set(music)):
        idx = [i for i, m in enumerate(music) if m == song]
        if len(idx) >= 2:
            per_song.append(average_pairwise_distance(f[idx]))
    return float(np.mean(per_song)) if per_song else float("nan")


def style_fid(pred_windows: np.ndarray, ref_windows: np.ndarray) -> float:
    """FID between two sets of window features ``(N, F)`` and ``(M, F)``."""
    return float(frechet_distance(pred_windows, ref_windows))
