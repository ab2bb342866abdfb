"""Per genre, the real training dances' jitter (m/s: speed removed by a 5-frame average,
:func:`dancekit.metrics.stability.jitter`, the measure of the per-song jitter guard): the median per genre is
the ``"sampling": {"genre_jitter": ...}`` table of the genre draw's jitter cap (issue 15, branch ``variety5``).

    PYTHONPATH=src python benchmarks/genre_jitter_table.py [data/tang2018] [split]

Prints each dance's jitter, per genre n / min / median / max, and the JSON object of the medians (3 decimals).
"""

from __future__ import annotations

import json
import sys

import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics import stability


def main() -> None:
    data = PreparedData(sys.argv[1] if len(sys.argv) > 1 else "data/tang2018")
    split = sys.argv[2] if len(sys.argv) > 2 else "train"
    values: dict[str, list[float]] = {}
    for name in data.names(split):
        m = data.motion(name)
        j = stability.jitter(np.asarray(m.to_positions(), np.float64), fps=m.fps, skeleton=m.skeleton)["speed_residual"]
        values.setdefault(data.genre(name), []).append(float(j))
        print(f"{name:12s} {data.genre(name):7s} {j:.4f}")
    for g, v in values.items():
        print(f"{g:7s} n {len(v):2d} min {min(v):.3f} median {np.median(v):.3f} max {max(v):.3f}")
    print(json.dumps({"genre_jitter": {g: round(float(np.median(v)), 3) for g, v in values.items()}}))


if __name__ == "__main__":
    main()
