"""Argument checks shared by every layer (no dependency beyond :mod:`dancekit.errors` and NumPy)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dancekit.errors import ParameterError


def reduce_seed(seed: int) -> int:
    """A seed of any size (negative or beyond 64 bits) as one torch and NumPy accept, in ``[0, 2**63)``.

    Seeds already in ``[0, 2**63)`` are returned unchanged (so existing seeds give the same dances); any
    other integer maps to the first 63 bits of the SHA-256 of its decimal digits (distinct seeds stay
    distinct with overwhelming probability).

    Examples
    --------
    >>> reduce_seed(7), reduce_seed(2**64) == reduce_seed(2**64), 0 <= reduce_seed(-1) < 2**63
    (7, True, True)
    """
    import hashlib

    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ParameterError(f"seed must be an integer, got {seed!r}")
    seed = int(seed)
    if 0 <= seed < 2**63:
        return seed
    return int.from_bytes(hashlib.sha256(str(seed).encode()).digest()[:8], "big") >> 1


def check_times(times: Any, name: str) -> np.ndarray:
    """Event times (seconds, any shape) as a sorted float64 vector; ``ParameterError`` naming ``name`` when
    one is NaN or inf."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if not np.isfinite(t).all():
        raise ParameterError(f"{name} contain NaN or inf")
    return np.sort(t)


def check_fps(fps: float, *, name: str = "fps") -> float:
    """``fps`` (frames per second) as a positive finite float, else :class:`ParameterError`.

    Numbers of any kind (NumPy scalars and 0-d arrays included) are accepted; booleans and strings
    are refused rather than coerced.
    """
    problem = f"{name} must be a positive number of frames per second, got {fps!r}"
    if isinstance(fps, (bool, str, bytes)):
        raise ParameterError(problem)
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise ParameterError(problem) from None
    if not math.isfinite(value) or value <= 0:
        raise ParameterError(problem)
    return value


def check_positions(positions: Any, skeleton: Any = None, *, min_frames: int = 2,
                    name: str = "positions") -> np.ndarray:
    """World joint positions ``(T, J, 3)`` as a float64 array, else :class:`ParameterError`.

    Raises
    ------
    ParameterError
        If the array is not 3-D with 3 coordinates, has fewer than ``min_frames`` frames, does not
        match ``skeleton.num_joints`` (when a skeleton is given) or holds NaN / inf.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ParameterError(f"{name} must have shape (T, J, 3), got {p.shape}")
    if skeleton is not None and p.shape[1] != skeleton.num_joints:
        raise ParameterError(
            f"{name} has {p.shape[1]} joints but skeleton {skeleton.name!r} has {skeleton.num_joints}"
        )
    if p.shape[0] < min_frames:
        raise ParameterError(f"{name} has {p.shape[0]} frames; this needs at least {min_frames}")
    if not np.isfinite(p).all():
        raise ParameterError(f"{name} contains NaN or inf values")
    return p
