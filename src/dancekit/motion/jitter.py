"""Jitter measures of a dance, and the filter settings chosen from them.

NumPy in, NumPy out. Arrays are world joint positions ``(T, J, 3)`` in the skeleton's units at ``fps`` frames
per second. The measures are those of :mod:`dancekit.metrics.stability` (jitter: the body-relative speed a
5-frame moving average removes), computed here without importing the metrics (motion sits below metrics in
docs/ARCHITECTURE.md's layer table), over pieces of :data:`~dancekit.motion.filters.CHUNK` frames so a long
song needs no whole-song float64 copies.

=============================  ====================================================================
function                       what
=============================  ====================================================================
:func:`jitter_speed`           the jitter in m/s (``"speed_residual"`` of the metrics)
:func:`jitter_ratio`           the jitter over the smoothed speed (jitter-to-energy ratio), of the
                               dance or of its Savitzky-Golay / low-pass filtered version
:func:`smoothing_window`       the shortest Savitzky-Golay window bringing the ratio to a target
:func:`lowpass_cutoff`         the highest low-pass cut-off bringing the ratio to a target
:func:`jitter_cutoff`          the highest low-pass cut-off bringing the jitter under a cap (m/s)
:func:`smooth_positions`       a Savitzky-Golay filter, its window given or chosen by the ratio
=============================  ====================================================================
"""

from __future__ import annotations

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.filters import chunks, lowpass_rows, savgol, savgol_rows
from dancekit.motion.skeleton import Skeleton

__all__ = ["CAP_CUTOFFS_HZ", "CUTOFFS_HZ", "jitter_cutoff", "jitter_ratio", "jitter_speed", "lowpass_cutoff",
           "smooth_positions", "smoothing_window"]


#: The cut-offs (Hz, highest first) :func:`lowpass_cutoff` tries: the 5-frame average of the jitter measure
#: removes half of a 3-Hz motion and all of 5 and 10 Hz at 25 fps; dance motion is mostly below 2 Hz.
CUTOFFS_HZ = (8.0, 6.0, 5.0, 4.5, 4.0, 3.5, 3.0, 2.5)


def _check(positions: np.ndarray, name: str) -> np.ndarray:
    p = np.array(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"{name} needs (T, J, 3) positions, got shape {np.shape(positions)}")
    return p


def smoothing_window(positions: np.ndarray, *, skeleton: Skeleton, fps: float, target: float,
                     windows: tuple[int, ...] = (5, 7, 9, 11, 13, 15, 17, 21), order: int = 3) -> int:
    """The shortest Savitzky-Golay window (frames, odd) of ``windows`` whose output has a jitter ratio
    (speed removed by a 5-frame average over the smoothed speed, :func:`dancekit.metrics`' jitter over
    energy) at most ``target``; 1 (no filter) when the dance already is; the longest when none is.
    The filtered dances are measured :data:`CHUNK` frames at a time (no whole-song copies)."""
    p = np.asarray(positions)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"smoothing_window needs (T, J, 3) positions, got shape {np.shape(positions)}")
    if jitter_ratio(p, skeleton, fps) <= target:
        return 1
    for w in windows:
        if w > len(p):
            break
        if jitter_ratio(p, skeleton, fps, window=w, order=order) <= target:
            return w
    return max((w for w in windows if w <= len(p)), default=1)


def lowpass_cutoff(positions: np.ndarray, *, skeleton: Skeleton, fps: float, target: float,
                   cutoffs: tuple[float, ...] = CUTOFFS_HZ) -> float:
    """The highest low-pass cut-off (Hz) of ``cutoffs`` (highest first) whose output (:func:`lowpass_rows`,
    a Hamming-windowed sinc of :func:`~dancekit.motion.filters.lowpass_taps` taps) has a jitter ratio
    (speed removed by a 5-frame average over the smoothed speed, :func:`dancekit.metrics`' jitter over
    energy) at most ``target``; 0 (no filter) when the dance already is; the lowest when none is. Measured
    :data:`CHUNK` frames at a time."""
    p = np.asarray(positions)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"lowpass_cutoff needs (T, J, 3) positions, got shape {np.shape(positions)}")
    if jitter_ratio(p, skeleton, fps) <= target:
        return 0.0
    for c in cutoffs:
        if jitter_ratio(p, skeleton, fps, cutoff=c) <= target:
            return float(c)
    return float(cutoffs[-1])


#: The cut-offs (Hz, highest first) :func:`jitter_cutoff` tries to bring a dance's tremor under a cap: lower
#: than :data:`CUTOFFS_HZ`, since the dances it is for (a genre model drawn by the seed, issue 15) already
#: passed the 3-Hz settle; at 1 Hz a waltz's one-step-per-beat sway (about 1.5 steps per second) is still half there.
CAP_CUTOFFS_HZ = (4.0, 3.0, 2.5, 2.0, 1.75, 1.5, 1.25, 1.0)


def jitter_cutoff(positions: np.ndarray, *, skeleton: Skeleton, fps: float, max_jitter: float,
                  cutoffs: tuple[float, ...] = CAP_CUTOFFS_HZ) -> float:
    """The highest low-pass cut-off (Hz) of ``cutoffs`` (highest first) whose output (:func:`lowpass_rows`) has
    a jitter of at most ``max_jitter`` m/s (the body-relative speed a 5-frame average removes, the
    :mod:`dancekit.metrics.stability` jitter, with ``skeleton.unit_scale`` to metres); 0 (no filter) when the
    dance already has; the lowest when none has. Only cut-offs whose kernel (:func:`lowpass_taps`) fits in
    the dance are tried (a dance shorter than every kernel: 0). Measured :data:`CHUNK` frames at a time."""
    from dancekit.motion.filters import lowpass_taps

    p = np.asarray(positions)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"jitter_cutoff needs (T, J, 3) positions, got shape {np.shape(positions)}")
    if not (np.isfinite(max_jitter) and max_jitter > 0):
        raise ParameterError(f"max_jitter must be a positive number of m/s, got {max_jitter!r}")
    cutoffs = tuple(c for c in cutoffs if lowpass_taps(c, fps=fps) <= len(p))
    if not cutoffs or _jitter_speed(p, skeleton, fps) <= max_jitter:
        return 0.0
    for c in cutoffs:
        if _jitter_speed(p, skeleton, fps, cutoff=c) <= max_jitter:
            return float(c)
    return float(cutoffs[-1])


def jitter_speed(positions: np.ndarray, *, skeleton: Skeleton, fps: float) -> float:
    """The jitter (m/s) of a dance ``(T, J, 3)`` (skeleton units) at ``fps``: the speed a 5-frame moving
    average removes, the number :func:`dancekit.metrics.stability.jitter` gives as ``"speed_residual"``
    (the per-song jitter guard's measure), computed without importing the metrics."""
    return _jitter_speed(np.asarray(positions), skeleton, fps)


def _jitter_speed(p: np.ndarray, skeleton: Skeleton, fps: float, *, cutoff: float | None = None) -> float:
    """The jitter of ``p`` (T, J, 3) (or of its low-pass at ``cutoff`` Hz) in m/s, as
    :func:`dancekit.metrics.stability.jitter` measures it (computed here without importing metrics): the mean
    body-relative joint speed (central differences, one-sided at the ends) minus that of the 5-frame moving
    average (edge frames repeated). Over pieces of :data:`CHUNK` frames with a 3-frame margin."""
    from dancekit.motion.filters import lowpass_kernel

    T = len(p)
    if T < 2:
        return 0.0
    r = skeleton.root
    h = lowpass_kernel(cutoff, fps=fps) if cutoff else None
    total = 0.0
    for a, b in chunks(T):  # the speeds at frames [a, b)
        lo, hi = max(a - 3, 0), min(b + 3, T)
        x = lowpass_rows(p, h, lo, hi) if h is not None else np.asarray(p[lo:hi], np.float64)
        rel = x - x[:, r: r + 1]
        raw = np.linalg.norm(np.gradient(rel, axis=0), axis=-1)[a - lo: b - lo]
        padded = np.concatenate([rel[:1]] * 2 * (lo == 0) + [rel] + [rel[-1:]] * 2 * (hi == T))
        c = np.cumsum(np.concatenate([np.zeros((1, *rel.shape[1:])), padded]), axis=0)
        avg = (c[5:] - c[:-5]) / 5  # the 5-frame average of rows lo + 2 - 2·[lo == 0] ...
        first = lo + 2 - 2 * (lo == 0)  # the frame avg[0] is centred on
        sm = np.linalg.norm(np.gradient(avg, axis=0), axis=-1)
        # the average's gradient at a piece's inner edge would be one-sided: a ≥ first + 1 there (margin 3)
        total += float(raw.sum() - sm[a - first: b - first].sum())
    return total / (T * p.shape[1]) * fps * skeleton.unit_scale


def jitter_ratio(p: np.ndarray, skeleton: Skeleton, fps: float, *, window: int | None = None,
                  order: int = 3, cutoff: float | None = None) -> float:
    """Mean body-relative speed removed by a 5-frame moving average, over the smoothed speed (the jitter
    over the energy of :mod:`dancekit.metrics.stability`, computed here without importing metrics), of the
    dance ``p`` (T, J, 3), or of ``savgol(p, window, order)`` when ``window`` is given, or of its
    low-pass at ``cutoff`` Hz (:func:`lowpass_rows`) when ``cutoff`` is. Summed over pieces
    of :data:`CHUNK` frames with a margin (the moving average and the filter are local), so a long song
    needs no whole-song float64 copies; the same ratio as one pass up to float rounding of the sums."""
    raw, smooth, _ = _jitter_sums(p, skeleton, fps, window=window, order=order, cutoff=cutoff)
    return float((raw - smooth) / smooth) if smooth > 0 else 0.0


def _jitter_sums(p: np.ndarray, skeleton: Skeleton, fps: float, *, window: int | None = None,
                 order: int = 3, cutoff: float | None = None) -> tuple[float, float, int]:
    """``(raw, smooth, n)``: the summed body-relative joint steps between frames (skeleton units per frame) of the
    dance ``p`` (T, J, 3) (or of ``savgol(p, window, order)`` / its low-pass at ``cutoff`` Hz), the same sum
    for its 5-frame moving average, and the number of steps summed; computed here without importing metrics,
    over pieces of :data:`CHUNK` frames with a margin (the moving average and the filter are local), so a
    long song needs no whole-song float64 copies."""
    from dancekit.motion.filters import lowpass_kernel, uniform_filter1d

    T = len(p)
    if T < 3:
        return 0.0, 0.0, 0
    r = skeleton.root
    h = lowpass_kernel(cutoff, fps=fps) if cutoff else None
    raw = smooth = 0.0
    for a, b in chunks(T - 1):  # the speeds between frames i and i + 1 for i in [a, b)
        lo, hi = max(a - 2, 0), min(b + 3, T)  # the frames the 5-frame average of frames a..b needs
        if h is not None:
            x = lowpass_rows(p, h, lo, hi)
        elif window is not None:
            x = savgol_rows(p, window, order, lo, hi)
        else:
            x = np.asarray(p[lo:hi], np.float64)
        rel = x - x[:, r: r + 1]
        raw += float(np.linalg.norm(np.diff(rel[a - lo: b + 1 - lo], axis=0), axis=-1).sum())
        sm = uniform_filter1d(rel, 5, axis=0)  # at lo > 0 / hi < T: 2 real frames of margin
        smooth += float(np.linalg.norm(np.diff(sm[a - lo: b + 1 - lo], axis=0), axis=-1).sum())
    return raw, smooth, (T - 1) * p.shape[1]


def smooth_positions(positions: np.ndarray, *, skeleton: Skeleton, fps: float, target: float | None = None,
                     window: int | None = None, order: int = 3) -> tuple[np.ndarray, int]:
    """A Savitzky-Golay filter (polynomial ``order``) over time on every joint coordinate: ``(positions,
    window)``, the filtered ``(T, J, 3)`` float64 array and the window used (1: unfiltered).

    Give ``window`` (odd frames) or ``target``, a jitter ratio (see :func:`smoothing_window`): then the
    window is the shortest that brings the dance to it, so a smooth dance is left alone and only a
    jittery one is filtered. The filter keeps polynomials of degree ``order`` exactly (so a steady step or
    a turn keeps its speed and the root's travel is kept), and removes frame-to-frame noise.
    """
    fps = check_fps(fps)
    p = _check(positions, "smooth_positions")
    if window is None:
        if target is None:
            raise ParameterError("smooth_positions needs a window or a target jitter ratio")
        window = smoothing_window(p, skeleton=skeleton, fps=fps, target=target, order=order)
    window = int(window)
    if window <= 1:
        return p, 1
    if window % 2 == 0:
        raise ParameterError(f"the smoothing window must be odd, got {window}")
    return savgol(p, window, order), window
