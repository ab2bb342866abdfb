"""Per genre, the median of one measure over the real training dances: the per-genre tables the embedded
checkpoints' stage entries hold (issue 15).

    PYTHONPATH=src python benchmarks/genre_tables.py jitter [--data data/tang2018] [--split train]
    PYTHONPATH=src python benchmarks/genre_tables.py smoothing
    PYTHONPATH=src python benchmarks/genre_tables.py energy

Measures (each the number its stage compares a generated dance with):

* ``jitter``: the speed (m/s) a 5-frame average removes (:func:`dancekit.metrics.stability.jitter`, the per-song
  jitter guard's measure): the ``"sampling": {"genre_jitter": ...}`` table of the genre draw's jitter cap (and
  of music2dance's ``"jitter_cap"`` entry);
* ``smoothing``: the jitter-to-energy ratio of the smoothing stage
  (:func:`dancekit.motion.footlock.smoothing_window`): the ``"smoothing": {"genre_targets": ...}`` table
  (docs/STAGES.md, "Per genre");
* ``energy``: the smoothed energy (m/s, :func:`dancekit.metrics.smoothed_energy`): the ``"energy":
  {"genre_energy": ...}`` table of the energy stage.

Prints each dance's value, per genre n / min / median / max, and the JSON entry of the medians (3 decimals).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable

import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics import smoothed_energy, stability
from dancekit.motion import Motion


def _jitter(m: Motion) -> float:
    p = np.asarray(m.to_positions(), np.float64)
    return float(stability.jitter(p, fps=m.fps, skeleton=m.skeleton)["speed_residual"])


def _smoothing(m: Motion) -> float:
    from dancekit.motion.jitter import jitter_ratio as _jitter_ratio

    return float(_jitter_ratio(np.asarray(m.to_positions()), m.skeleton, m.fps))


def _energy(m: Motion) -> float:
    return float(smoothed_energy(np.asarray(m.to_positions(), np.float64), fps=m.fps, skeleton=m.skeleton))


#: measure name -> (the function of one real dance, the key of the checkpoint entry's table)
MEASURES: dict[str, tuple[Callable[[Motion], float], str]] = {
    "jitter": (_jitter, "genre_jitter"), "smoothing": (_smoothing, "genre_targets"), "energy": (_energy, "genre_energy")}


def genre_values(data: PreparedData, measure: str, split: str = "train") -> dict[str, list[float]]:
    """Per genre, ``measure`` of each real dance of ``split``, in the split's order."""
    fn = MEASURES[measure][0]
    out: dict[str, list[float]] = {}
    for name in data.names(split):
        out.setdefault(data.genre(name), []).append(fn(data.motion(name)))
    return out


def genre_table(data: PreparedData, measure: str, split: str = "train") -> dict[str, float]:
    """Per genre, the median of ``measure`` over the real dances of ``split``, rounded to 3 decimals."""
    return {g: round(float(np.median(v)), 3) for g, v in genre_values(data, measure, split).items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("measure", choices=sorted(MEASURES))
    ap.add_argument("--data", default="data/tang2018")
    ap.add_argument("--split", default="train")
    args = ap.parse_args()
    data = PreparedData(args.data)
    fn, key = MEASURES[args.measure]
    values: dict[str, list[float]] = {}
    for name in data.names(args.split):
        v = fn(data.motion(name))
        values.setdefault(data.genre(name), []).append(v)
        print(f"{name:12s} {data.genre(name):7s} {v:.4f}")
    for g, v in values.items():
        print(f"{g:7s} n {len(v):2d} min {min(v):.3f} median {np.median(v):.3f} max {max(v):.3f}")
    print(json.dumps({key: {g: round(float(np.median(v)), 3) for g, v in values.items()}}))


if __name__ == "__main__":
    main()
