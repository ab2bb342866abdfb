"""Distance of a generated dance to its ground truth.

The dual-learning paper (§4.3) calls its main dance metric "Fréchet distance" but defines
it as the average 3D joint distance of the generated sequence from the ground truth. It is
*not* the Fréchet (inception) distance between feature distributions (see
:mod:`dancekit.metrics.fid`); to avoid the confusion it is named :func:`mean_joint_distance`
here and reported as "FD (dual-learning, mean joint distance)".
"""

from __future__ import annotations

import numpy as np

from dancekit.errors import ParameterError

__all__ = ["mean_joint_distance"]


def mean_joint_distance(pred: np.ndarray, ref: np.ndarray, *, crop: bool = True) -> float:
    """Mean Euclidean distance between corresponding joints, over frames and joints.

    Parameters
    ----------
    pred, ref : (T, J, 3) joint positions in the same units (the result is in those units)
    crop : compare the first ``min(T_pred, T_ref)`` frames when the lengths differ
        (otherwise a length mismatch raises)

    Raises
    ------
    ParameterError
        On shape mismatch (joints or coordinates), or lengths that differ with ``crop=False``.

    Examples
    --------
    >>> x = np.zeros((4, 2, 3))
    >>> mean_joint_distance(x, x + [3.0, 4.0, 0.0])
    5.0
    """
    a = np.asarray(pred, np.float64)
    b = np.asarray(ref, np.float64)
    if a.ndim != 3 or b.ndim != 3 or a.shape[1:] != b.shape[1:]:
        raise ParameterError(f"mean_joint_distance needs two (T, J, D) arrays with the same J, D: {a.shape}, {b.shape}")
    if len(a) != len(b):
        if not crop:
            raise ParameterError(f"sequences have {len(a)} and {len(b)} frames")
    n = min(len(a), len(b))
    if n == 0:
        raise ParameterError("mean_joint_distance: empty sequence")
    return float(np.linalg.norm(a[:n] - b[:n], axis=-1).mean())
