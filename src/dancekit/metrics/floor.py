"""How a dance meets the floor: the floor numbers of docs/BENCHMARKS.md in one report.

NumPy in, NumPy out. The measures themselves are :mod:`dancekit.motion.floor`'s (the foot lock and the
pipeline's re-grounding act on them, and the layer table lets metrics import motion, not the reverse); this
module gathers them into the report the benchmarks and evaluations read.
"""

from __future__ import annotations

import numpy as np

from dancekit.motion.floor import floor_gap_cm, planted_share
from dancekit.motion.skeleton import Skeleton

__all__ = ["floor_contact"]


def floor_contact(positions: np.ndarray, *, skeleton: Skeleton, fps: float, near_cm: float = 2.0) -> dict[str, float]:
    """The floor report of a dance.

    Parameters
    ----------
    positions : (T, J, 3) world positions in skeleton units at ``fps`` frames per second
    skeleton, fps : the skeleton (up axis, units, legs) and the frame rate
    near_cm : the height over the local floor (cm) within which a frame counts as touching it

    Returns
    -------
    dict
        ``float_cm``: the median over frames of the lowest joint's height over the local floor (cm,
        :func:`dancekit.motion.floor.floor_float_cm`); ``near_floor_share``: the share of frames within
        ``near_cm`` of it; ``planted_share``: the share of foot-frames planted
        (:func:`dancekit.motion.floor.planted_share`; NaN for a skeleton without legs).
    """
    gap = floor_gap_cm(positions, skeleton=skeleton, fps=fps)  # (T,) cm
    return {"float_cm": float(np.median(gap)), "near_floor_share": float(np.mean(gap <= near_cm)),
            "planted_share": planted_share(positions, skeleton=skeleton, fps=fps)}
