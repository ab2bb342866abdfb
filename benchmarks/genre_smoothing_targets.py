"""Per genre, the jitter-to-energy ratio of the real training dances (the smoothing stage's measure,
:func:`dancekit.motion.footlock.smoothing_window`): the median per genre is what a checkpoint's
``"smoothing": {"genre_targets": ...}`` holds (docs/MUSIC2DANCE.md, "Genre steering with the stages").

    PYTHONPATH=src python benchmarks/genre_smoothing_targets.py [data/tang2018] [split]

Prints each dance's ratio and the JSON object of the medians (3 decimals).
"""

from __future__ import annotations

import json
import sys

import numpy as np

from dancekit.data import PreparedData
from dancekit.motion.footlock import _jitter_ratio


def main() -> None:
    data = PreparedData(sys.argv[1] if len(sys.argv) > 1 else "data/tang2018")
    split = sys.argv[2] if len(sys.argv) > 2 else "train"
    ratios: dict[str, list[float]] = {}
    for name in data.names(split):
        m = data.motion(name)
        r = _jitter_ratio(np.asarray(m.to_positions()), m.skeleton, m.fps)
        ratios.setdefault(data.genre(name), []).append(r)
        print(f"{name:12s} {data.genre(name):7s} {r:.3f}")
    for g, v in ratios.items():
        print(f"{g:7s} n {len(v):2d} min {min(v):.3f} median {np.median(v):.3f} max {max(v):.3f}")
    print(json.dumps({"genre_targets": {g: round(float(np.median(v)), 3) for g, v in ratios.items()}}))


if __name__ == "__main__":
    main()
