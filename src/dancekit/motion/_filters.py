"""The 1-D filters the dance stages use, in NumPy: ``scipy.ndimage``'s results without its import.

``import scipy.ndimage`` costs a fresh process ~0.5 s (it loads scipy's array-API back ends and
``scipy.sparse``), a tenth of a ``dancekit dance`` of a one-minute song; the stages only need five
one-dimensional filters, all with ``mode="nearest"`` (the edge sample repeated), so they are here:

=============================  ==============================================================
:func:`gaussian_filter1d`      ``scipy.ndimage.gaussian_filter1d(x, sigma, axis, mode="nearest")``
                               (truncate 4: radius ``int(4 sigma + 0.5)``), equal to 1e-12
:func:`uniform_filter1d`       ``scipy.ndimage.uniform_filter1d(x, size, axis, mode="nearest")``,
                               equal to 1e-12 (each window summed afresh; scipy keeps a running sum)
:func:`minimum_filter1d`       ``scipy.ndimage.minimum_filter1d(x, size, mode="nearest")``, bit-equal
:func:`maximum_filter1d`       ``scipy.ndimage.maximum_filter1d(x, size, mode="nearest")``, bit-equal
:func:`percentile_filter1d`    ``scipy.ndimage.percentile_filter(x, percentile, size, mode="nearest")``
                               of a 1-D ``x``, bit-equal
=============================  ==============================================================

Windows follow scipy's placement (origin 0): a window of ``size`` samples around sample ``i`` covers
``i - size // 2 … i + (size - 1) // 2``. Every function returns a new float64 array of the input's
shape; the rank filters work through the samples in pieces of :data:`PIECE`, so a long song needs no
``(T, size)`` array. Checked against scipy in ``tests/test_filters.py``.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from dancekit.errors import ParameterError

__all__ = ["PIECE", "gaussian_filter1d", "maximum_filter1d", "minimum_filter1d", "percentile_filter1d",
           "uniform_filter1d"]

#: Samples per piece of the rank filters (their window views are ``(PIECE, size)``).
PIECE = 8192


def _padded(x: np.ndarray, size: int, axis: int) -> tuple[np.ndarray, int]:
    """``x`` (float64, the filtered axis first) with ``size // 2`` edge copies before and ``(size - 1) // 2``
    after, and the axis it came from."""
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    before, after = size // 2, (size - 1) // 2
    pad = [(before, after)] + [(0, 0)] * (x.ndim - 1)
    return np.pad(x, pad, mode="edge"), before


def _check_size(size: int) -> int:
    size = int(size)
    if size < 1:
        raise ParameterError(f"filter size must be >= 1, got {size}")
    return size


def _correlate(x: np.ndarray, weights: np.ndarray, axis: int) -> np.ndarray:
    """``x`` correlated with ``weights`` along ``axis`` (edge mode): ``out[i] = Σ_k w[k] x[i + k - len // 2]``."""
    size = len(weights)
    xp, _ = _padded(x, size, axis)
    n = len(xp) - size + 1
    out = weights[0] * xp[:n]
    for k in range(1, size):
        out += weights[k] * xp[k:k + n]
    return np.moveaxis(out, 0, axis)


def gaussian_filter1d(x: np.ndarray, sigma: float, *, axis: int = -1) -> np.ndarray:
    """Gaussian smoothing of ``x`` along ``axis``: standard deviation ``sigma`` samples, the kernel
    truncated at ``int(4 sigma + 0.5)`` samples each side and normalised to sum 1 (scipy's), edge mode.
    ``sigma <= 0``: a float64 copy."""
    sigma = float(sigma)
    if sigma <= 0:
        return np.array(x, dtype=np.float64)
    radius = int(4.0 * sigma + 0.5)
    k = np.arange(-radius, radius + 1)
    w = np.exp(-0.5 / (sigma * sigma) * k**2)
    return _correlate(x, w / w.sum(), axis)


def uniform_filter1d(x: np.ndarray, size: int, *, axis: int = -1) -> np.ndarray:
    """Mean of ``size`` consecutive samples along ``axis`` (edge mode), scipy's window placement."""
    size = _check_size(size)
    xp, _ = _padded(x, size, axis)
    n = len(xp) - size + 1
    out = xp[:n].copy()
    for k in range(1, size):
        out += xp[k:k + n]
    return np.moveaxis(out / size, 0, axis)


def _rank(x: np.ndarray, size: int, rank: int) -> np.ndarray:
    """The ``rank``-th smallest (0-based) of the ``size`` samples around every sample of a 1-D ``x``."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ParameterError(f"the rank filters take a 1-D array, got shape {x.shape}")
    xp, _ = _padded(x, size, 0)
    out = np.empty(len(x))
    for a in range(0, len(x), PIECE):
        b = min(a + PIECE, len(x))
        win = sliding_window_view(xp[a:b + size - 1], size)  # (b - a, size), a view
        if rank == 0:
            out[a:b] = win.min(axis=1)
        elif rank == size - 1:
            out[a:b] = win.max(axis=1)
        else:
            out[a:b] = np.partition(win, rank, axis=1)[:, rank]
    return out


def minimum_filter1d(x: np.ndarray, size: int) -> np.ndarray:
    """Running minimum of a 1-D ``x`` over ``size`` samples (edge mode), scipy's window placement."""
    return _rank(x, _check_size(size), 0)


def maximum_filter1d(x: np.ndarray, size: int) -> np.ndarray:
    """Running maximum of a 1-D ``x`` over ``size`` samples (edge mode), scipy's window placement."""
    size = _check_size(size)
    return _rank(x, size, size - 1)


def percentile_filter1d(x: np.ndarray, percentile: float, size: int) -> np.ndarray:
    """The ``percentile`` (0-100; negative counts from 100) of the ``size`` samples around every sample of a
    1-D ``x`` (edge mode): the sample of rank ``int(size * percentile / 100)`` in the sorted window, no
    interpolation, as ``scipy.ndimage.percentile_filter``."""
    size = _check_size(size)
    percentile = float(percentile)
    if percentile < 0.0:
        percentile += 100.0
    rank = int(float(size) * percentile / 100.0)
    if rank < 0:
        rank += size
    if not 0 <= rank < size:
        raise ParameterError(f"percentile {percentile} out of range for a window of {size} samples")
    return _rank(x, size, rank)
