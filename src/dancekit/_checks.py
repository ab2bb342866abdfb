"""Argument checks shared by every layer (no dependency beyond :mod:`dancekit.errors`)."""

from __future__ import annotations

import math

from dancekit.errors import ParameterError


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
