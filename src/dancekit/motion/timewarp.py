"""Beat-synchronous time warp: move a dance's kinematic beats onto the music's beats.

NumPy in, NumPy out (keyword-only arguments). A *warp* is the source time ``s(τ)`` of every output time
``τ``: output frame ``t`` (at ``t / fps`` s) shows the source dance at fractional frame ``s_t``. It is
monotone, keeps the dance's length (``s_0 = 0``, ``s_{T-1} = T - 1``) and its local speed ``ds/dτ`` (the
*rate*) stays within ``1 ± max_rate_change`` (default ±15 %) at every frame.

Three steps (:func:`beat_warp` runs them):

1. :func:`match_beats` — dynamic programming over candidate pairings ``(music beat m_i, kinematic beat
   k_j)`` with ``|k_j - m_i| <= max_shift``: the longest chain of pairs, increasing in both times, whose
   consecutive pairs (and the anchors ``(0, 0)`` and ``(D, D)``) need a mean rate within
   ``1 ± pair_rate_change`` (default ±13 %, below the frame bound so that the smoothing has room); ties
   go to the gentlest warp (sum of squared rate changes).
2. :func:`warp_rates` — the rate per output frame: the smoothest rate (least first and second
   differences: the dance's speed changes gradually) that puts the matched pairs on their beats, with two
   bounds: the rate within ``1 ± max_rate_change`` and its change from one frame to the next within
   ``± max_rate_step`` (default 2 %/frame: no visible speed jump). The pairs and the bounds are stiff
   penalties on the source frames, a convex piecewise quadratic with a banded Hessian, solved by
   semi-smooth Newton (``scipy.linalg.solveh_banded``, linear in the song's length); a pair the bounds
   cannot land is dropped.
3. :func:`warp_motion` — the dance sampled at the fractional source frames: rotations slerped, 3D
   positions bone by bone (:func:`warp_bones`, bone lengths kept), anything else linearly
   (:func:`warp_frames`, the toolkit's resampling rule).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancekit._checks import check_times
from dancekit.errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion.motion import Motion
    from dancekit.motion.skeleton import Skeleton

__all__ = [
    "BETWEEN_WEIGHT",
    "DEFAULT_MAX_RATE_CHANGE",
    "DEFAULT_MAX_RATE_STEP",
    "DEFAULT_MAX_SHIFT",
    "DEFAULT_PAIR_RATE_CHANGE",
    "DEFAULT_SMOOTH_S",
    "beat_warp",
    "match_beats",
    "warp_bones",
    "warp_frames",
    "warp_motion",
    "warp_rates",
]

#: Bound on the local speed change of the warp, per frame: the rate stays in ``[0.85, 1.15]``.
DEFAULT_MAX_RATE_CHANGE = 0.15
#: Bound on the mean rate between two matched beat pairs (room for the smoothing within the frame bound).
DEFAULT_PAIR_RATE_CHANGE = 0.13
#: Bound on the warp's rate change from one frame to the next (:func:`warp_rates`): ``|rate[t + 1] - rate[t]|
#: <= 0.02``, 2 % of the dance's speed per frame (at 25 fps: half the speed change of the whole ±15 % band
#: takes at least 0.15 s), so the speed changes smoothly, with no visible jump.
DEFAULT_MAX_RATE_STEP = 0.02
#: In :func:`warp_rates` a matched pair's landing is a penalty whose weight is the bounds' weight divided by
#: this: the bounds outweigh the pairs, which land as near as the bounds let them (and the pairs outweigh the
#: smoothness, whose weight is the bounds' / BOUND_WEIGHT).
PAIR_SOFTNESS = 1e6
#: Weight of a bound's squared violation in :func:`warp_rates` (the rate box, the step bound), against the
#: largest weight of the smoothness penalty: large enough that the bounds hold to the solver's round-off.
BOUND_WEIGHT = 1e4
#: Most semi-smooth Newton rounds of :func:`_bounded_source` (each one banded solve).
MAX_NEWTON = 60
#: A pair :func:`warp_rates`' first pass misses by more than this many frames is dropped (the bounds do not
#: let it land) and the rest solved again without its pull.
DROP_FRAMES = 1.0
#: Rounds of :func:`warp_rates` that move each kept pair's target by what it missed (the pairs are soft
#: penalties, weaker than the bounds: this lands the ones the bounds allow on their beats).
LANDING_ROUNDS = 4
#: Time scale of the warp's smoothness penalty on its rate, seconds (:func:`warp_rates`).
DEFAULT_SMOOTH_S = 0.5
#: A kinematic beat is paired only with music beats at most this many seconds away.
DEFAULT_MAX_SHIFT = 0.6
#: Weight of a kinematic beat that a step lands near a music beat without pairing it
#: (``match_beats(between_tolerance=...)``), against 1 for a pair: a pair (landed exactly) counts more.
BETWEEN_WEIGHT = 0.3


def match_beats(
    *,
    kinematic: np.ndarray,
    music: np.ndarray,
    duration: float,
    pair_rate_change: float = DEFAULT_PAIR_RATE_CHANGE,
    max_shift: float = DEFAULT_MAX_SHIFT,
    min_gap: float = 0.0,
    window: float = 30.0,
    between_tolerance: float = 0.0,
    max_rate_step: float | None = None,
    fps: float | None = None,
) -> np.ndarray:
    """Pair kinematic beats with music beats by dynamic programming.

    Parameters
    ----------
    kinematic : (K,) kinematic beat times of the dance, seconds (source times)
    music : (M,) music beat times, seconds (output times)
    duration : the dance's duration ``D`` in seconds; ``(0, 0)`` and ``(D, D)`` are fixed anchors
    pair_rate_change : consecutive pairs ``(m, k)``, ``(m', k')`` need ``|(k' - k) / (m' - m) - 1| <= this``
    max_shift : only pairs with ``|k - m| <= max_shift`` seconds are candidates
    min_gap : consecutive pairs at least this many seconds apart (output time)
    window : a pair's predecessor lies at most ``window`` seconds before it (the start anchor always counts)
    between_tolerance : seconds; when positive, a step from one pair to the next also scores every
        kinematic beat strictly between them that the straight warp of the step (the line through the two
        pairs) puts within this many seconds of a music beat, with weight :data:`BETWEEN_WEIGHT` (a pair:
        1): among chains of nearly as many pairs, the one whose unpaired kinematic beats land on beats too
        (the beat hit rate counts every kinematic beat). 0 (default): only the pairs count.
    max_rate_step, fps : when given, the warp's rate changes by at most ``max_rate_step`` per frame at ``fps``
        (:func:`warp_rates`), so two consecutive steps of the chain, ``dm`` and ``dm'`` seconds long, can
        differ in mean rate by at most ``max_rate_step · fps · (dm + dm') / 2`` (a ramp at the bound across
        both): a step that breaks it from the best chain into its predecessor is not taken (a greedy check:
        the predecessor's own best chain only). ``None`` (default): no such check.

    Returns
    -------
    (P, 2) float64 ``[[m, k], ...]``: the chosen pairs (music time, kinematic time), increasing in both,
    anchors excluded; ``(0, 2)`` when none can be paired.
    """
    if not 0 < pair_rate_change < 1:
        raise ParameterError(f"pair_rate_change must be in (0, 1), got {pair_rate_change}")
    if not max_shift > 0:
        raise ParameterError(f"max_shift must be positive seconds, got {max_shift}")
    if not between_tolerance >= 0:
        raise ParameterError(f"between_tolerance must be >= 0 seconds, got {between_tolerance}")
    if max_rate_step is not None and not (fps is not None and fps > 0):
        raise ParameterError(f"max_rate_step needs the frame rate (fps > 0), got fps={fps}")
    slope = np.inf if max_rate_step is None else float(max_rate_step) * float(fps)  # rate change per second
    k = check_times(kinematic, "kinematic beats")
    m = check_times(music, "music beats")
    D = float(duration)
    k = k[(k > 0) & (k < D)]
    m = m[(m > 0) & (m < D)]
    nodes = [(0.0, 0.0)]
    for mi in m:
        lo, hi = np.searchsorted(k, [mi - max_shift, mi + max_shift], side="left")
        nodes.extend((float(mi), float(kj)) for kj in k[lo:hi] if abs(kj - mi) <= max_shift)
    nodes.append((D, D))
    node = np.asarray(nodes, dtype=np.float64)  # sorted by music time (the anchors first and last)
    N = len(node)
    if N == 2:
        return np.zeros((0, 2))
    lo_r, hi_r = 1.0 - pair_rate_change, 1.0 + pair_rate_change
    score = np.full(N, -np.inf)
    back = np.full(N, -1, dtype=np.int64)
    rate_in = np.ones(N)  # the mean rate and length (s) of the best chain's last step into each node
    dm_in = np.zeros(N)
    score[0] = 0.0
    starts = np.searchsorted(node[:, 0], node[:, 0] - window, side="left")
    for n in range(1, N):
        first = 0 if n == N - 1 else int(starts[n])
        prev = np.arange(first, n) if first > 0 else np.arange(n)
        if first > 0:
            prev = np.concatenate([[0], prev])
        dm = node[n, 0] - node[prev, 0]
        dk = node[n, 1] - node[prev, 1]
        ok = (dm > max(min_gap, 1e-9)) & (dk > 1e-9) & np.isfinite(score[prev])
        if n == N - 1:
            ok |= (prev == 0) & (dm > 0)  # the identity warp is always allowed
        rate = np.where(ok, dk / np.where(dm > 0, dm, 1.0), 1.0)
        ok &= (rate >= lo_r - 1e-12) & (rate <= hi_r + 1e-12)
        if np.isfinite(slope):
            ok &= (prev == 0) | (np.abs(rate - rate_in[prev]) <= slope * (dm + dm_in[prev]) / 2 + 1e-12)
        if not ok.any():
            continue
        gain = np.full(len(prev), 0.0 if n == N - 1 else 1.0)
        if between_tolerance > 0:
            gain += BETWEEN_WEIGHT * _landing_between(node[prev], node[n], rate, ok, k, m, between_tolerance)
        cand = np.where(ok, score[prev] + gain - 1e-3 * ((rate - 1.0) / pair_rate_change) ** 2, -np.inf)
        best = int(np.argmax(cand))
        score[n] = cand[best]
        back[n] = prev[best]
        rate_in[n], dm_in[n] = rate[best], dm[best]
    chain = []
    n = int(back[N - 1])
    while n > 0:
        chain.append(node[n])
        n = int(back[n])
    return np.asarray(chain[::-1], dtype=np.float64).reshape(-1, 2)


def _landing_between(prev: np.ndarray, pair: np.ndarray, rate: np.ndarray, ok: np.ndarray, k: np.ndarray,
                     m: np.ndarray, tolerance: float) -> np.ndarray:
    """For every step ``prev[i] → pair`` (``(m, k)`` rows, ``rate`` = dk / dm, only where ``ok``), the number of
    kinematic beats ``k`` strictly between the two kinematic times whose time on the straight warp of the step,
    ``m_prev + (k - k_prev) / rate``, is within ``tolerance`` seconds of a music beat in ``m``."""
    out = np.zeros(len(prev))
    if not ok.any() or len(m) == 0:
        return out
    idx = np.flatnonzero(ok)
    lo = np.searchsorted(k, prev[idx, 1], side="right")
    hi = np.searchsorted(k, pair[1], side="left")
    width = int(np.max(hi - lo, initial=0))
    if width <= 0:
        return out
    j = lo[:, None] + np.arange(width)[None]
    inside = j < hi
    kk = k[np.minimum(j, len(k) - 1)]
    t = prev[idx, 0][:, None] + (kk - prev[idx, 1][:, None]) / rate[idx][:, None]
    q = np.searchsorted(m, t)
    d = np.minimum(np.abs(t - m[np.clip(q - 1, 0, len(m) - 1)]), np.abs(t - m[np.clip(q, 0, len(m) - 1)]))
    out[idx] = np.sum(inside & (d <= tolerance), axis=1)
    return out


def warp_rates(
    *,
    pairs: np.ndarray,
    n_frames: int,
    fps: float,
    max_rate_change: float = DEFAULT_MAX_RATE_CHANGE,
    smooth_s: float = DEFAULT_SMOOTH_S,
    max_rate_step: float | None = DEFAULT_MAX_RATE_STEP,
) -> np.ndarray:
    """The warp's source frame for every output frame, from matched beat pairs.

    Parameters
    ----------
    pairs : (P, 2) ``[music time, kinematic time]`` in seconds (:func:`match_beats`)
    n_frames : T, the number of frames (output and source alike)
    fps : frames per second
    max_rate_change : the rate (source frames per output frame) stays within ``1 ± max_rate_change``
    smooth_s : time scale of the smoothness penalty, seconds (larger: gentler rate changes)
    max_rate_step : the rate changes by at most this much from one frame to the next
        (``|rate[t + 1] - rate[t]| <= max_rate_step``, a fraction per frame at ``fps``: 0.02 is 2 %/frame);
        ``None``: no bound beyond the smoothness penalty

    Returns
    -------
    (T,) float64 source frames ``s``: ``s[0] = 0``, ``s[-1] = T - 1``, increasing, with
    ``s[t + 1] - s[t]`` in ``[1 - max_rate_change, 1 + max_rate_change]`` and (when ``max_rate_step`` is
    given) consecutive rates at most ``max_rate_step`` apart; matched pairs land on their beats
    (``s(m · fps) = k · fps``, interpolated linearly between frames) to ~0.01 frame where the bounds allow it
    comfortably, within half a frame where they are tight (else as near as the bounds let them).

    The rate is the smoothest (least first and second differences) that lands the pairs under the two bounds.
    Pairs and bounds are penalties on the source frames (:func:`_bounded_source`; the bounds
    :data:`PAIR_SOFTNESS` times stiffer than the pairs, so that pairs the bounds cannot land all at once land as
    near as they allow); each kept pair's target is then moved by what it missed (:data:`LANDING_ROUNDS`, the
    method of multipliers), so the pairs the bounds allow land on their beats. Pairs that still miss by more
    than :data:`DROP_FRAMES` are dropped and the rest solved again. A last forward pass clips the rates to the
    box and every step to ``± max_rate_step`` exactly (it moves them by the solver's tolerance).
    """
    T = int(n_frames)
    if T < 2:
        return np.zeros(max(T, 0))
    if not 0 < max_rate_change < 1:
        raise ParameterError(f"max_rate_change must be in (0, 1), got {max_rate_change}")
    if max_rate_step is not None and not (np.isfinite(max_rate_step) and max_rate_step > 0):
        raise ParameterError(f"max_rate_step must be positive (a rate change per frame), got {max_rate_step}")
    pairs = np.asarray(pairs, dtype=np.float64).reshape(-1, 2)
    n = T - 1  # one rate per output interval
    # quadratic form: a0 |r - 1|^2 + a1 |D1 r|^2 + a2 |D2 r|^2 (first and second differences of the rate)
    L = max(1.0, smooth_s * fps)
    a = (1e-3, L**2, L**4 / 4.0)
    lo, hi = 1.0 - max_rate_change, 1.0 + max_rate_change
    step = np.inf if max_rate_step is None else float(max_rate_step)
    mu = BOUND_WEIGHT * max(a[1], a[2])  # weight of a bound's squared violation
    knots = np.concatenate([[[0.0, 0.0]], pairs * float(fps), [[n, n]]])  # frames
    inner = knots[1:-1]
    keep = np.ones(len(inner), dtype=bool)
    rates = np.ones(n)
    # every pair soft (landed as near as the bounds let it); the pairs that then miss by more than
    # DROP_FRAMES are dropped and the rest solved again without their pull
    for _ in range(2):
        if not keep.any():
            rates = np.ones(n)  # nothing lands within the bounds: the identity
            break
        kept = np.concatenate([knots[:1], inner[keep], knots[-1:]])
        target = kept.copy()
        for _ in range(1 + LANDING_ROUNDS):  # the kept pairs' targets moved by what they missed (method of multipliers)
            rates = _bounded_source(target, mu / PAIR_SOFTNESS, n, a, lo, hi, step, mu)
            s = np.concatenate([[0.0], np.cumsum(rates)])
            target[1:-1, 1] += kept[1:-1, 1] - np.interp(kept[1:-1, 0], np.arange(T), s)
        miss = np.abs(np.interp(inner[:, 0], np.arange(T), s) - inner[:, 1])
        if not (keep & (miss > DROP_FRAMES)).any():
            break
        keep &= miss <= DROP_FRAMES
    return np.concatenate([[0.0], np.cumsum(_project(rates, lo, hi, step))])


def _project(rates: np.ndarray, lo: float, hi: float, step: float) -> np.ndarray:
    """The rates clipped to ``[lo, hi]`` and each within ``± step`` of the one before (a forward pass, which
    keeps the box), their sum kept (a constant added, then clipped again; a few rounds). Exact bounds on
    rates that held them to the solver's tolerance (it moves them by about that much)."""
    total = rates.sum()
    for _ in range(3):
        rates = np.clip(rates, lo, hi)
        if np.isfinite(step) and len(rates) > 1 and np.abs(np.diff(rates)).max() > step:
            for t in range(1, len(rates)):
                rates[t] = min(max(rates[t], rates[t - 1] - step), rates[t - 1] + step)
        rates = rates + (total - rates.sum()) / len(rates)
    rates = np.clip(rates, lo, hi)
    if np.isfinite(step) and len(rates) > 1 and np.abs(np.diff(rates)).max() > step:
        for t in range(1, len(rates)):
            rates[t] = min(max(rates[t], rates[t - 1] - step), rates[t - 1] + step)
    return rates


def _stencil_add(ab: np.ndarray, b: np.ndarray, start: np.ndarray, v: tuple, w: np.ndarray, c: np.ndarray) -> None:
    """Add ``Σ_k w_k / 2 (v · s[start_k : start_k + len(v)] - c_k)²`` to the quadratic ``s' H s / 2 - b' s``:
    ``H`` in LAPACK's upper banded storage ``ab`` (``ab[u + i - j, j] = H[i, j]``, ``u = len(ab) - 1``)."""
    u = len(ab) - 1
    for i, vi in enumerate(v):
        np.add.at(b, start + i, w * c * vi)
        for j in range(i, len(v)):
            np.add.at(ab[u - (j - i)], start + j, w * vi * v[j])


def _bounded_source(knots: np.ndarray, w_pair: float, n: int, a: tuple, lo: float, hi: float, step: float,
                    mu: float) -> np.ndarray:
    """:func:`warp_rates`' programme in the source frames ``s`` (``n + 1`` of them, ``s[0] = 0`` and
    ``s[n] = n`` held): ``½ Σ`` of ``a0 (r - 1)²``, ``a1 (Δr)²``, ``a2 (Δ²r)²`` (``r = Δs``, the rate), every
    inner knot's ``w_pair (s(x) - y)²`` (``s`` interpolated linearly at ``x``) and ``mu`` times the squared
    violation of the rate box ``[lo, hi]`` and of the steps ``|Δr| <= step``: a convex piecewise quadratic
    whose Hessian is banded (half-bandwidth 3), minimised by damped semi-smooth Newton: the bounds the iterate
    leaves are penalised, that quadratic solved (``scipy.linalg.solveh_banded``, linear in ``n``), the step
    towards its minimiser halved until the objective goes down, until the set of bounds left is that of the
    minimiser. Returns the rates ``(n,)``."""
    from scipy.linalg import solveh_banded

    x, y = knots[1:-1, 0], knots[1:-1, 1]
    i0 = np.clip(np.floor(x).astype(int), 0, n - 1)
    f = x - i0
    t1, t2, t3 = np.arange(n), np.arange(n - 1), np.arange(max(n - 2, 0))

    def parts(s: np.ndarray):
        r = np.diff(s)
        return r, np.diff(r), np.diff(r, 2), (1 - f) * s[i0] + f * s[i0 + 1] - y

    def objective(s: np.ndarray) -> float:
        r, d1, d2, res = parts(s)
        box = np.maximum(r - hi, 0.0) + np.maximum(lo - r, 0.0)
        viol = np.maximum(np.abs(d1) - step, 0.0)
        return float(0.5 * (a[0] * np.sum((r - 1) ** 2) + a[1] * d1 @ d1 + a[2] * d2 @ d2 + w_pair * res @ res
                            + mu * (box @ box + viol @ viol)))

    def newton_point(up, dn, over, under) -> np.ndarray:
        ab, b = np.zeros((4, n + 1)), np.zeros(n + 1)
        wr = a[0] + mu * (over | under)
        _stencil_add(ab, b, t1, (-1.0, 1.0), wr, (a[0] + mu * (hi * over + lo * under)) / wr)
        wd = a[1] + mu * (up | dn)
        _stencil_add(ab, b, t2, (1.0, -2.0, 1.0), wd, mu * step * (up.astype(float) - dn) / wd if np.isfinite(step)
                     else np.zeros(len(t2)))
        _stencil_add(ab, b, t3, (-1.0, 3.0, -3.0, 1.0), np.full(len(t3), a[2]), np.zeros(len(t3)))
        if len(x):
            wp = np.full(len(x), w_pair)
            for i, vi in enumerate(((1 - f), f)):
                np.add.at(b, i0 + i, wp * y * vi)
            np.add.at(ab[3], i0, wp * (1 - f) ** 2)
            np.add.at(ab[3], i0 + 1, wp * f**2)
            np.add.at(ab[2], i0 + 1, wp * f * (1 - f))
        # s[0] = 0 and s[n] = n held: their columns move to the right-hand side
        for k in range(1, 4):  # H[n - k, n] = ab[3 - k, n]
            if n - k >= 1:
                b[n - k] -= ab[3 - k, n] * n
        s = np.zeros(n + 1)
        s[n] = n
        if n >= 2:
            sub = ab[:, 1:n].copy()
            for k in range(1, 4):  # entries coupling to s[0] (above the first free row) are outside the block
                sub[3 - k, :k] = 0.0
            s[1:n] = solveh_banded(sub, b[1:n])
        return s

    none = np.zeros(n, dtype=bool)
    s = newton_point(none[1:], none[1:], none, none)
    fval = objective(s)
    for _ in range(MAX_NEWTON):
        r, d1, _, _ = parts(s)
        bounds = (d1 > step, d1 < -step, r > hi, r < lo)
        p = newton_point(*bounds) - s
        if np.abs(p).max() < 1e-10:
            break
        alpha = 1.0
        while True:
            trial = s + alpha * p
            ft = objective(trial)
            if ft <= fval or alpha < 1e-4:
                break
            alpha *= 0.5
        if ft > fval:
            break
        s, fval = trial, ft
        r, d1, _, _ = parts(s)
        if alpha == 1.0 and all(np.array_equal(u, v) for u, v in zip(bounds, (d1 > step, d1 < -step, r > hi, r < lo),
                                                                     strict=True)):
            break
    return np.diff(s)


def warp_frames(x: np.ndarray, *, source_frames: np.ndarray) -> np.ndarray:
    """Frames ``(T, ...)`` sampled at fractional source frames ``(T',)`` by linear interpolation (a new
    array in the dtype of ``x``; frames outside ``[0, T - 1]`` are clamped)."""
    x = np.asarray(x)
    s = np.clip(np.asarray(source_frames, dtype=np.float64), 0, len(x) - 1)
    i0 = np.floor(s).astype(int)
    i1 = np.minimum(i0 + 1, len(x) - 1)
    w = (s - i0).reshape((-1,) + (1,) * (x.ndim - 1)).astype(x.dtype)
    return x[i0] * (1 - w) + x[i1] * w


def warp_bones(positions: np.ndarray, *, skeleton: Skeleton, source_frames: np.ndarray) -> np.ndarray:
    """3D joint positions ``(T, J, 3)`` sampled at fractional source frames ``(T',)`` bone by bone: the
    root's position interpolated linearly, every bone vector (parent → child) interpolated linearly,
    then scaled to the linear interpolation of its two lengths (normalised lerp, close to slerp for the
    small turns between neighbouring frames), chained from the root. Bones keep their lengths (a
    straight lerp of positions shortens a turning bone). Returns float64 ``(T', J, 3)``."""
    p = np.asarray(positions, dtype=np.float64)
    s = np.clip(np.asarray(source_frames, dtype=np.float64), 0, len(p) - 1)
    i0 = np.floor(s).astype(int)
    i1 = np.minimum(i0 + 1, len(p) - 1)
    w = (s - i0)[:, None]
    out = np.empty((len(s),) + p.shape[1:])
    for j in skeleton.topological_order:
        parent = skeleton.parents[j]
        if parent < 0:
            out[:, j] = p[i0, j] * (1 - w) + p[i1, j] * w
            continue
        b0, b1 = p[i0, j] - p[i0, parent], p[i1, j] - p[i1, parent]
        v = b0 * (1 - w) + b1 * w
        length = np.linalg.norm(b0, axis=-1, keepdims=True) * (1 - w) + np.linalg.norm(b1, axis=-1, keepdims=True) * w
        norm = np.linalg.norm(v, axis=-1, keepdims=True)
        v = np.where(norm > 1e-12, v / np.maximum(norm, 1e-12) * length, v)
        out[:, j] = out[:, parent] + v
    return out


def warp_motion(motion: Motion, *, source_frames: np.ndarray) -> Motion:
    """The :class:`~dancekit.motion.Motion` sampled at fractional source frames ``(T',)`` (same fps and
    skeleton): rotations by quaternion slerp and the root translation linearly; a 3D motion of positions
    alone bone by bone (:func:`warp_bones`: bone lengths kept), a 2D one linearly."""
    from dancekit.motion.motion import Motion

    s = np.clip(np.asarray(source_frames, dtype=np.float64), 0, motion.num_frames - 1)

    def lerp(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else warp_frames(a, source_frames=s)

    if motion.rotations is None and motion.positions is not None and motion.positions.shape[-1] == 3:
        pos = warp_bones(motion.positions, skeleton=motion.skeleton, source_frames=s)
        return Motion(motion.skeleton, motion.fps, pos.astype(motion.positions.dtype), None,
                      lerp(motion.root_translation))

    rot = None
    if motion.rotations is not None:
        import torch

        from dancekit.motion.rotations import matrix_to_quaternion, quaternion_slerp, quaternion_to_matrix

        i0 = np.floor(s).astype(int)
        i1 = np.minimum(i0 + 1, motion.num_frames - 1)
        q = matrix_to_quaternion(torch.from_numpy(motion.rotations.astype(np.float64)))
        tt = torch.from_numpy(s - i0)[:, None].expand(len(s), q.shape[1])
        rot = quaternion_to_matrix(quaternion_slerp(q[i0], q[i1], tt)).numpy().astype(motion.rotations.dtype)
    return Motion(motion.skeleton, motion.fps, lerp(motion.positions), rot, lerp(motion.root_translation))


def beat_warp(
    positions: np.ndarray,
    *,
    music_beats: np.ndarray,
    fps: float,
    max_rate_change: float = DEFAULT_MAX_RATE_CHANGE,
    pair_rate_change: float = DEFAULT_PAIR_RATE_CHANGE,
    max_shift: float = DEFAULT_MAX_SHIFT,
    smooth: float | None = None,
    between_tolerance: float = 0.0,
    smooth_s: float = DEFAULT_SMOOTH_S,
    max_rate_step: float | None = DEFAULT_MAX_RATE_STEP,
    step_pairing: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """The beat-synchronous warp of a dance: its source frames and the matched beat pairs.

    Parameters
    ----------
    positions : (T, J, 3) (or (T, J, 2)) joint positions at ``fps``, any units
    music_beats : (M,) music beat times, seconds from the dance's first frame
    fps : frames per second
    max_rate_change, pair_rate_change, max_shift, between_tolerance, smooth_s, max_rate_step : see
        :func:`warp_rates` and :func:`match_beats`
    smooth : speed smoothing of the kinematic beats, seconds (default that of
        :func:`dancekit.motion.analysis.kinematic_beats`)
    step_pairing : the pairing skips steps the rate's step bound cannot follow (:func:`match_beats` given
        ``max_rate_step`` and ``fps``); False: it pairs by ``pair_rate_change`` only and :func:`warp_rates`
        drops what the bound does not let land

    Returns
    -------
    ``(source_frames, pairs)``: (T,) float64 fractional source frames (:func:`warp_frames` applies
    them) and (P, 2) matched ``[music, kinematic]`` times in seconds: the pairs the warp lands within half a
    frame (a pair the rate bounds cannot land is dropped from the list). Without a landed pair the warp is
    the identity (``source_frames == arange(T)``).
    """
    from dancekit.motion.analysis import DEFAULT_BEAT_SMOOTH, kinematic_beats

    p = np.asarray(positions, dtype=np.float64)
    T = len(p)
    if T < 3:
        return np.arange(T, dtype=np.float64), np.zeros((0, 2))
    kin = kinematic_beats(p, fps=fps, smooth=DEFAULT_BEAT_SMOOTH if smooth is None else smooth)
    pairs = match_beats(kinematic=kin, music=music_beats, duration=(T - 1) / fps,
                        pair_rate_change=pair_rate_change, max_shift=max_shift,
                        between_tolerance=between_tolerance, fps=fps,
                        max_rate_step=max_rate_step if step_pairing else None)
    if len(pairs) == 0:
        return np.arange(T, dtype=np.float64), pairs
    source = warp_rates(pairs=pairs, n_frames=T, fps=fps, max_rate_change=max_rate_change, smooth_s=smooth_s,
                        max_rate_step=max_rate_step)
    landed = np.abs(np.interp(pairs[:, 0] * fps, np.arange(T), source) - pairs[:, 1] * fps) <= 0.5
    if not landed.any():
        return np.arange(T, dtype=np.float64), np.zeros((0, 2))
    return source, pairs[landed]
