"""Does ``--genre`` steer? Dance every song of a split as every genre a model offers, and read it back.

For each song of the split and each genre of the model (``pipe.genres``: a genre-conditioned model's
genres, or the genre models in its folder), ``seeds`` dances (seeds 0, 1, ...) are generated for the same
slice of the song as in the dataset and classified by the style classifier (``dancekit evaluate``'s). The
report gives the share of dances read back as the requested genre (``read_back``), the confusion counts
(requested → read), the classifier's mean probability of the requested genre, and per genre the largest
stillness share and the mean smoothed energy (m/s) of the dances (does it still dance?).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancekit.errors import ParameterError
from dancekit.metrics.stability import smoothed_energy, stillness_share
from dancekit.metrics.style import dance_genre

__all__ = ["steering"]


def steering(pipe: Any, data: Any, style: Any, *, split: str, seeds: int = 1, progress: bool = True) -> dict:
    """Read-back scores of ``pipe`` (a dance pipeline with ``genres``) on the songs of ``split``.

    Parameters
    ----------
    pipe : a dance pipeline offering genres (``pipe.genres``)
    data : a :class:`~dancekit.data.PreparedData`
    style : a :class:`~dancekit.pipelines.StylePipeline`
    split : the songs
    seeds : dances per song and genre

    Raises
    ------
    ParameterError
        If the model offers no genre.
    """
    from tqdm import tqdm

    if not pipe.genres:
        raise ParameterError("the model offers no genre (neither conditioned nor with genre models)")
    matrix = {g: dict.fromkeys(style.genres, 0) for g in pipe.genres}
    prob: dict[str, list[float]] = {g: [] for g in pipe.genres}
    still: dict[str, list[float]] = {g: [] for g in pipe.genres}
    energy: dict[str, list[float]] = {g: [] for g in pipe.genres}
    per_song: dict[str, dict[str, str]] = {}
    jobs = [(n, g, k) for n in data.names(split) for g in pipe.genres for k in range(seeds)]
    batch = getattr(pipe, "dances", None)  # a pipeline that dances a song's seeds of one genre at once
    done: dict[tuple[str, str, int], Any] = {}
    for name, genre, k in tqdm(jobs, desc="steering", unit="dance", disable=not progress):
        ref = data.audio(name)
        if batch is not None and (name, genre, k) not in done:  # the song's seeds of each genre at once
            done = {}
            for g in pipe.genres:
                ks = [s for n, gg, s in jobs if n == name and gg == g]
                rows = batch(ref.path, seeds=ks, genre=g, start=ref.start, end=ref.end)
                done.update({(name, g, s): r.motion for s, r in zip(ks, rows)})
        m = done[(name, genre, k)] if batch is not None else pipe(ref.path, seed=k, start=ref.start, end=ref.end,
                                                                   genre=genre).motion
        pos = m.to_positions()
        still[genre].append(stillness_share(pos, fps=m.fps, skeleton=m.skeleton))
        energy[genre].append(smoothed_energy(pos, fps=m.fps, skeleton=m.skeleton))
        _, logp = style.embed(pos, fps=m.fps, skeleton=m.skeleton)
        p = np.exp(logp).mean(axis=0)
        read = style.genres[dance_genre(logp)]
        matrix[genre][read] += 1
        prob[genre].append(float(p[style.genres.index(genre)]))
        per_song.setdefault(name, {})[genre if seeds == 1 else f"{genre}__{k}"] = read
    n = len(jobs)
    hits = sum(matrix[g][g] for g in pipe.genres)
    return {
        "split": split, "seeds": seeds, "n": n, "read_back": hits / n,
        "read_back_per_genre": {g: matrix[g][g] / sum(matrix[g].values()) for g in pipe.genres},
        "mean_prob_requested": {g: float(np.mean(v)) for g, v in prob.items()},
        "stillness_max": {g: float(max(v)) for g, v in still.items()},
        "smoothed_energy": {g: float(np.mean(v)) for g, v in energy.items()},
        "matrix": matrix, "per_song": per_song,
    }
