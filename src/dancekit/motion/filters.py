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
:func:`lowpass_kernel`         a windowed-sinc FIR low-pass: ``scipy.signal.firwin(numtaps, cutoff,
                               window=..., fs=fps)``, equal to 1e-12
:func:`fir_lowpass`            that kernel applied along an axis, zero-phase (the kernel is symmetric),
                               the ends padded by odd reflection (``scipy.signal.filtfilt``'s "odd")
=============================  ==============================================================

Windows follow scipy's placement (origin 0): a window of ``size`` samples around sample ``i`` covers
``i - size // 2 … i + (size - 1) // 2``. Every function returns a new float64 array of the input's
shape; the rank filters work through the samples in pieces of :data:`PIECE`, so a long song needs no
``(T, size)`` array. Checked against scipy in ``tests/motion/test_filters.py``.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from dancekit.errors import ParameterError

__all__ = ["PIECE", "fir_lowpass", "gaussian_filter1d", "lowpass_kernel", "lowpass_taps", "maximum_filter1d",
           "minimum_filter1d", "percentile_filter1d", "uniform_filter1d"]

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


def lowpass_taps(cutoff_hz: float, *, fps: float) -> int:
    """The default length (odd, samples) of :func:`lowpass_kernel`: a Hamming window's transition band is
    about ``3.3 fps / numtaps`` Hz wide, so this makes it as wide as the cut-off (for a 3-Hz cut-off at
    25 fps, 29 taps, 1.16 s: the band from ~1.5 Hz passes within 0.2 %, from ~4.5 Hz up is removed to 0.3 %)."""
    n = int(np.ceil(3.3 * float(fps) / float(cutoff_hz)))
    return n + 1 - n % 2


def lowpass_kernel(cutoff_hz: float, *, fps: float, numtaps: int | None = None,
                   window: str | tuple[str, float] = "hamming") -> np.ndarray:
    """A windowed-sinc low-pass FIR kernel ``(numtaps,)`` float64, symmetric, summing to 1 (unit gain at 0 Hz).

    ``h[n] = c sinc(c (n - (N - 1) / 2)) w[n]`` with ``c = cutoff_hz / (fps / 2)`` and ``w`` the window
    (``"hamming"``, ``"hann"``, ``"blackman"`` or ``("kaiser", beta)``, the symmetric NumPy windows), then
    scaled to sum 1: ``scipy.signal.firwin(numtaps, cutoff_hz, window=window, fs=fps)``. ``numtaps`` odd,
    default :func:`lowpass_taps`. ``cutoff_hz`` in Hz, strictly between 0 and the Nyquist frequency.
    """
    fps = float(fps)
    if not 0.0 < float(cutoff_hz) < fps / 2:
        raise ParameterError(f"a low-pass cut-off must be between 0 and {fps / 2:g} Hz at {fps:g} fps, "
                             f"got {cutoff_hz}")
    n = lowpass_taps(cutoff_hz, fps=fps) if numtaps is None else int(numtaps)
    if n < 1 or n % 2 == 0:
        raise ParameterError(f"a zero-phase low-pass needs an odd number of taps, got {n}")
    c = float(cutoff_hz) / (fps / 2)
    m = np.arange(n) - (n - 1) / 2
    if isinstance(window, tuple) and len(window) == 2 and window[0] == "kaiser":
        w = np.kaiser(n, float(window[1]))
    elif window in ("hamming", "hann", "blackman"):
        w = {"hamming": np.hamming, "hann": np.hanning, "blackman": np.blackman}[window](n)
    else:
        raise ParameterError(f"unknown window {window!r}: hamming, hann, blackman or ('kaiser', beta)")
    h = c * np.sinc(c * m) * w
    return h / h.sum()


def fir_lowpass(x: np.ndarray, kernel: np.ndarray, *, axis: int = 0) -> np.ndarray:
    """``x`` filtered along ``axis`` by a symmetric (zero-phase) FIR ``kernel`` of odd length: ``out[i] =
    Σ_k h[k] x[i + k - N // 2]``, the samples beyond each end taken by odd reflection about the end sample
    (``2 x[0] - x[k]``: a straight line is kept up to the ends, as ``scipy.signal.filtfilt`` pads). A signal
    shorter than the kernel is returned unfiltered. float64, the input's shape."""
    h = np.asarray(kernel, np.float64)
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    half = len(h) // 2
    if len(h) % 2 == 0:
        raise ParameterError(f"a zero-phase FIR kernel has an odd length, got {len(h)}")
    if len(x) <= half or len(x) < len(h):
        return np.moveaxis(x.copy(), 0, axis)
    ext = np.concatenate([2 * x[:1] - x[half:0:-1], x, 2 * x[-1:] - x[-2:-half - 2:-1]]) if half else x
    n = len(x)
    out = h[0] * ext[:n]
    for k in range(1, len(h)):
        out += h[k] * ext[k:k + n]
    return np.moveaxis(out, 0, axis)


#: Frames per piece in the chunked smoothing helpers (:func:`chunks`, :func:`savgol_rows`,
#: :func:`jitter_ratio`): the filters are local, so a long song is done piece by piece with a margin.
CHUNK = 4096


def chunks(n: int, size: int | None = None) -> list[tuple[int, int]]:
    """``[0, n)`` cut into ``ceil(n / size)`` pieces of nearly equal length (each at least ``size / 2``
    frames when there are several; ``size`` default :data:`CHUNK`)."""
    size = CHUNK if size is None else int(size)
    k = max(1, -(-n // size))
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def savgol_rows(p: np.ndarray, window: int, order: int, a: int, b: int) -> np.ndarray:
    """Frames ``[a, b)`` of ``savgol(p, window, order)``, from frames ``[a - window // 2, b + window // 2)``
    of ``p`` only: the same numbers (each output frame is the same weighted sum of the same input frames;
    only the song's own first and last ``window // 2`` frames take the edge polynomials). float64."""
    T, half = len(p), window // 2
    if window <= order or window > T:
        return np.array(p[a:b], dtype=np.float64)
    lo, hi = max(a - half, 0), min(b + half, T)
    if hi - lo < window:  # a piece shorter than the window near both ends: widen it (rare: T < 2 * CHUNK)
        lo, hi = max(0, min(lo, T - window)), min(T, max(hi, window))
    q = savgol(p[lo:hi], window, order) if (lo, hi) != (0, T) else savgol(p, window, order)
    # inside the piece, rows away from the piece's own ends are exact; the piece's ends are exact only
    # where they are the song's ends
    return q[a - lo: b - lo]


def savgol(p: np.ndarray, window: int, order: int) -> np.ndarray:
    """Savitzky-Golay smoothing along axis 0: ``scipy.signal.savgol_filter(p, window, order, axis=0,
    mode="interp")`` in NumPy (``scipy.signal`` imports ``scipy.stats``, a second of a ``dancekit dance``
    process): each frame the value at its centre of the degree-``order`` least-squares polynomial through
    the ``window`` frames around it; the first and last ``window // 2`` frames take the polynomial fitted to
    the first / last window. Equal to scipy's to float rounding (``tests/motion/test_footlock.py``). float64 out."""
    p = np.asarray(p)
    if window <= order or window > len(p):
        return p.copy()
    x = np.asarray(p, dtype=np.float64)
    T, half = len(x), window // 2
    t = np.arange(window, dtype=np.float64)
    V = (t[:, None] - half) ** np.arange(order + 1)[None, :]  # (window, order + 1), centred on the middle frame
    fit = V @ np.linalg.pinv(V)  # (window, window): the fitted values of a window from its samples
    out = np.zeros_like(x)
    for k, c in enumerate(fit[half]):
        out[half:T - half] += c * x[k:T - 2 * half + k]
    out[:half] = np.tensordot(fit[:half], x[:window], axes=1)
    out[T - half:] = np.tensordot(fit[window - half:], x[T - window:], axes=1)
    return out


def lowpass_rows(p: np.ndarray, kernel: np.ndarray, a: int, b: int) -> np.ndarray:
    """Frames ``[a, b)`` of :func:`fir_lowpass` ``(p, kernel)`` (a zero-phase FIR along
    axis 0), from frames ``[a - N // 2, b + N // 2)`` of ``p`` only (beyond the song's ends the same odd
    reflection about the end frame): the same numbers, bit for bit, so a long song is filtered piece by piece
    (:func:`chunks`). A dance shorter than the kernel comes back unfiltered. float64."""
    h = np.asarray(kernel, np.float64)
    T, half = len(p), len(h) // 2
    if T < len(h) or T <= half:
        return np.array(p[a:b], dtype=np.float64)
    idx = np.arange(a - half, b + half)
    lo, hi = max(a - half, 0), min(b + half, T)
    x = np.asarray(p[lo:hi], np.float64)
    parts = []
    if idx[0] < 0:  # before the first frame: 2 p[0] - p[-i]
        parts.append(2 * np.asarray(p[:1], np.float64) - np.asarray(p[-idx[idx < 0]], np.float64))
    parts.append(x)
    if idx[-1] >= T:  # after the last frame: 2 p[T-1] - p[2 (T-1) - i]
        parts.append(2 * np.asarray(p[T - 1:], np.float64)
                     - np.asarray(p[2 * (T - 1) - idx[idx >= T]], np.float64))
    ext = np.concatenate(parts) if len(parts) > 1 else x
    n = b - a
    out = h[0] * ext[:n]
    for k in range(1, len(h)):
        out += h[k] * ext[k:k + n]
    return out
