"""Motion analysis that several layers need (pipelines, data preparation, metrics): NumPy in, NumPy out.

Arrays are world joint positions ``(T, J, 3)`` in the skeleton's units at ``fps`` frames per second.
"""

from __future__ import annotations

import numpy as np

from dancekit.motion.skeleton import Skeleton


def floor_curve(
    positions: np.ndarray, skeleton: Skeleton, *, fps: float, window_s: float = 3.0, percentile: float = 5.0
) -> np.ndarray:
    """Floor height at every frame ``(T,)``, in skeleton units.

    The ``percentile`` of the lowest foot joint's height in a ``window_s`` window around each frame,
    smoothed with a 1-second moving average. A dancer's feet touch the floor most of the time, so
    jumps do not lift the curve; a drifting capture floor is followed.
    """
    from scipy.ndimage import percentile_filter, uniform_filter1d

    up = skeleton.up_index
    feet = [skeleton.index(f) for f in skeleton.feet] or list(range(skeleton.num_joints))
    lowest = np.asarray(positions, np.float64)[:, feet, up].min(axis=1)
    size = max(1, int(round(window_s * fps)))
    floor = percentile_filter(lowest, percentile, size=size, mode="nearest")
    return uniform_filter1d(floor, size=max(1, int(round(fps))), mode="nearest")

