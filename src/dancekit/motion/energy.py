"""Lift a dance that moves too little: the deviation from its slow mean pose, low-passed, scaled by a gain.

A generated dance can be calm (regression towards a mean pose) and, once its frame-to-frame flicker is
filtered out, move with half the energy of a real dance. This module scales what the dance *does* around
where it *is*, without re-adding the flicker:

* per joint, the **slow mean** pose: a centred moving mean over ``mean_s`` seconds (of the local rotation
  matrices, projected back onto rotations, for a motion with rotations; of the body-relative joint
  positions otherwise);
* the **deviation** from it (a rotation vector, the log of ``mean.T @ rotation``; or a position offset),
  split by a zero-phase windowed-sinc low-pass at ``band_hz`` (:func:`dancekit.motion.filters.fir_lowpass`)
  into a low band and the rest;
* the low band scaled by a gain ``g >= 1``, the rest (the flicker band) left as it is or, with ``damp``
  in (0, 1], scaled by ``g ** -damp``: ``deviation + (g - 1) lowpass(deviation) + (g ** -damp - 1) (deviation -
  lowpass(deviation))``;
* optionally only part of the body: ``legs=False`` keeps the legs' rotations (or body-relative positions),
  ``root=False`` the root's orientation (rotation motions).

The gain is one per dance: the smallest ``g`` in ``[1, max_gain]`` that brings the dance's **smoothed
energy** (:func:`smoothed_energy`: mean body-relative joint speed after a 5-frame centred moving average,
m/s, the quantity of :func:`dancekit.metrics.smoothed_energy`) to ``floor`` (m/s); ``g = 1`` (nothing
changes) for a dance already at or above the floor. One gain for the whole dance keeps its dynamics: a
quiet passage stays quieter than a loud one. The root translation is not touched (the root path is the
clean-up's), nor are the bone lengths (rotations: positions by forward kinematics; positions: each frame's
bone lengths restored, bone directions from the lifted dance).

All functions are pure NumPy (float64 arithmetic; the positions path piece by piece, keeping float32 copies):
positions ``(T, J, 3)`` in skeleton units, rotations ``(T, J_rig, 3, 3)`` local, ``fps`` frames per second,
energies in m/s.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dancekit.errors import ParameterError
from dancekit.motion.skeleton import Skeleton, keep_bone_lengths

__all__ = ["DEFAULT_BAND_HZ", "DEFAULT_MAX_GAIN", "DEFAULT_MEAN_S", "ENERGY_FRAMES", "energy_gain", "leg_joints",
           "leg_rotations", "lift_positions", "lift_rotations", "rotation_exp", "rotation_log", "smoothed_energy"]

#: The moving mean (s) the deviation is taken from.
DEFAULT_MEAN_S = 1.5
#: The cut-off (Hz) of the deviation's low band (the part the gain scales).
DEFAULT_BAND_HZ = 2.5
#: The largest gain.
DEFAULT_MAX_GAIN = 2.0
#: Frames of the centred moving average before the energy's speed (the metrics' convention).
ENERGY_FRAMES = 5


def smoothed_energy(positions: np.ndarray, *, skeleton: Skeleton, fps: float) -> float:
    """Mean body-relative joint speed (m/s) after a :data:`ENERGY_FRAMES`-frame centred moving average of the
    positions (edge frames repeated; speeds by central differences): the number
    :func:`dancekit.metrics.smoothed_energy` gives, computed here without importing the metrics, piece by
    piece (:func:`dancekit.motion.filters.chunks`, a 3-frame margin: the same sums)."""
    from dancekit.motion.filters import chunks

    p = np.asarray(positions)
    if len(p) < 2:
        return 0.0
    return _chunked_energy(lambda a, b: np.asarray(p[a:b], np.float64), len(p), skeleton=skeleton, fps=fps,
                           chunks=chunks)


def _chunked_energy(rows: Callable[[int, int], np.ndarray], n: int, *, skeleton: Skeleton, fps: float,
                    chunks) -> float:
    """:func:`smoothed_energy` of the dance whose frames ``[a, b)`` ``rows(a, b)`` gives (float64 (b - a, J, 3)),
    ``n`` frames, piece by piece."""
    from dancekit.motion.filters import uniform_filter1d

    total, m = 0.0, ENERGY_FRAMES // 2 + 1
    for a, b in chunks(n):
        lo, hi = max(0, a - m), min(n, b + m)
        x = rows(lo, hi)
        x = x - x[:, skeleton.root: skeleton.root + 1]
        # the metrics' moving average puts (w - 1) // 2 frames before; uniform_filter1d w // 2 (equal for odd w)
        v = np.gradient(uniform_filter1d(x, ENERGY_FRAMES, axis=0), axis=0)[a - lo: b - lo]
        total += float(np.linalg.norm(v, axis=-1).sum())
    return total / (n * skeleton.num_joints) * float(fps) * skeleton.unit_scale


def rotation_log(r: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` (axis × angle in radians, angle in [0, π]) of rotation matrices
    ``(..., 3, 3)``, through unit quaternions (Shepperd's method: stable at every angle)."""
    r = np.asarray(r, np.float64)
    m = r.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    diag = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    q = np.empty((len(m), 4))  # w, x, y, z
    k = np.argmax(np.concatenate([tr[:, None], diag], axis=1), axis=1)
    i = k == 0
    s = np.sqrt(np.maximum(1.0 + tr[i], 1e-300)) * 2
    q[i] = np.stack([0.25 * s, (m[i, 2, 1] - m[i, 1, 2]) / s, (m[i, 0, 2] - m[i, 2, 0]) / s,
                     (m[i, 1, 0] - m[i, 0, 1]) / s], axis=1)
    for a in range(3):
        i = k == a + 1
        b, c = (a + 1) % 3, (a + 2) % 3
        s = np.sqrt(np.maximum(1.0 + 2 * m[i, a, a] - tr[i], 1e-300)) * 2
        qa = np.empty((int(i.sum()), 4))
        qa[:, 0] = (m[i, c, b] - m[i, b, c]) / s
        qa[:, 1 + a] = 0.25 * s
        qa[:, 1 + b] = (m[i, b, a] + m[i, a, b]) / s
        qa[:, 1 + c] = (m[i, c, a] + m[i, a, c]) / s
        q[i] = qa
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # w >= 0: the angle in [0, π]
    v = q[:, 1:]
    n = np.linalg.norm(v, axis=1)
    angle = 2 * np.arctan2(n, q[:, 0])
    scale = np.where(n > 1e-12, angle / np.maximum(n, 1e-300), 2.0)  # small angles: 2 v
    return (v * scale[:, None]).reshape(r.shape[:-2] + (3,))


def rotation_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` (Rodrigues' formula)."""
    w = np.asarray(w, np.float64)
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    k = np.zeros(w.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    return np.eye(3) + a * k + b * (k @ k)


def _check(mean_s: float, band_hz: float, fps: float) -> None:
    if not (np.isfinite(mean_s) and mean_s > 0):
        raise ParameterError(f"the energy stage's mean window must be positive seconds, got {mean_s}")
    if not (np.isfinite(band_hz) and 0 < band_hz < fps / 2):
        raise ParameterError(f"the energy stage's band must be in (0, {fps / 2:g}) Hz, got {band_hz}")


def _split(x: np.ndarray, *, fps: float, mean_s: float, band_hz: float) -> np.ndarray:
    """The low band (``band_hz`` low-pass, zero phase) of ``x`` (T, ...) along time; float64."""
    from dancekit.motion.filters import fir_lowpass, lowpass_kernel

    h = lowpass_kernel(band_hz, fps=fps)
    if len(x) < len(h):  # too short for the FIR: the whole deviation is the low band
        return np.array(x, np.float64)
    return fir_lowpass(x, h)


def energy_gain(lifted: Callable[[float], float], *, energy: float, floor: float, max_gain: float,
                iterations: int = 4) -> float:
    """The gain in ``[1, max_gain]`` whose lifted dance has smoothed energy ``floor`` (m/s): ``lifted(g)`` is
    that energy for gain ``g``; ``energy`` the dance's own (gain 1). Secant steps from ``floor / energy``
    (energy grows nearly linearly with the gain); 1 when the dance is at or above the floor, ``max_gain``
    when even that does not reach it."""
    if not energy < floor:
        return 1.0
    if energy <= 0:
        return float(max_gain)
    g0, e0 = 1.0, float(energy)
    g1 = float(np.clip(floor / energy, 1.0, max_gain))
    for _ in range(iterations):
        e1 = lifted(g1)
        if abs(e1 - floor) <= 1e-4 * floor or e1 == e0:
            break
        g2 = float(np.clip(g1 + (floor - e1) * (g1 - g0) / (e1 - e0), 1.0, max_gain))
        if g2 == g1:  # pinned at a bound
            break
        g0, e0, g1 = g1, e1, g2
    return g1


def lift_positions(positions: np.ndarray, *, skeleton: Skeleton, fps: float, floor: float,
                   max_gain: float = DEFAULT_MAX_GAIN, mean_s: float = DEFAULT_MEAN_S,
                   band_hz: float = DEFAULT_BAND_HZ, damp: float = 0.0,
                   legs: bool = True) -> tuple[np.ndarray, float]:
    """A positions-only dance ``(T, J, 3)`` lifted towards ``floor`` m/s of smoothed energy, and its gain.

    The body-relative positions (every joint minus the root of the frame) are split into their
    ``mean_s``-second moving mean and the deviation from it; the deviation's ``band_hz`` low band is scaled by
    the gain (:func:`energy_gain`), the root kept where it was, and each frame's bone lengths restored (bone
    directions from the lifted dance, parents first). Piece by piece (:func:`dancekit.motion.filters.chunks`,
    with margins over the filters' reach: the same numbers as one pass), so an hour-long dance needs two float32
    copies of itself (the low band and the result), not float64 ones. Returns ``(positions float32 (T, J, 3),
    gain)``; gain 1: ``(positions, 1.0)``, the input itself."""
    from dancekit.motion.filters import chunks, lowpass_kernel, lowpass_rows, uniform_filter1d

    _check(mean_s, band_hz, fps)
    p = np.asarray(positions)
    n = len(p)
    e = smoothed_energy(p, skeleton=skeleton, fps=fps)
    if not e < floor or n < 3:
        return p, 1.0
    size = max(1, int(round(mean_s * fps)))
    h = lowpass_kernel(band_hz, fps=fps)
    margin = size // 2 + len(h) // 2 + 2
    kept = [] if legs else leg_joints(skeleton)
    low = np.empty(p.shape, np.float32)  # the deviation's low band, body-relative (the root's row is 0)
    high = np.empty(p.shape, np.float32) if damp else None
    for a, b in chunks(n):
        lo, hi = max(0, a - margin), min(n, b + margin)
        x = np.asarray(p[lo:hi], np.float64)
        x -= x[:, skeleton.root: skeleton.root + 1]
        dev = x - uniform_filter1d(x, size, axis=0)
        band = lowpass_rows(dev, h, a - lo, b - lo)  # odd reflection only at the song's own ends
        band[:, kept] = 0.0  # the legs (hips down) where they were relative to the root
        low[a:b] = band
        if high is not None:
            rest = dev[a - lo: b - lo] - band
            rest[:, kept] = 0.0
            high[a:b] = rest

    def rows(g: float, a: int, b: int) -> np.ndarray:
        q = np.asarray(p[a:b], np.float64) + (g - 1.0) * low[a:b]
        if high is not None:
            q += (g ** -damp - 1.0) * high[a:b]
        return keep_bone_lengths(q, p[a:b], skeleton)

    gain = energy_gain(lambda g: _chunked_energy(lambda a, b: rows(g, a, b), n, skeleton=skeleton, fps=fps,
                                                 chunks=chunks), energy=e, floor=floor, max_gain=max_gain)
    if not gain > 1.0:
        return p, 1.0
    out = np.empty(p.shape, np.float32)
    for a, b in chunks(n):
        out[a:b] = rows(gain, a, b)
    return out, gain


def leg_joints(skeleton: Skeleton) -> list[int]:
    """The joints of the skeleton's legs (hip, knee, ankle and the foot joints below;
    :func:`dancekit.motion.analysis.leg_chains`)."""
    from dancekit.motion.analysis import leg_chains

    return sorted({j for hip, knee, ankle, below in leg_chains(skeleton) for j in (hip, knee, ankle, *below)})


def leg_rotations(skeleton: Skeleton, n_rotations: int) -> list[int]:
    """The rotations (of ``n_rotations``: the skeleton's joints, or its rig's, :meth:`Skeleton.rig`) that move only
    leg joints: every rotation whose descendants are all in :func:`leg_joints` (the hips' branch joints below
    the pelvis too)."""
    rig = skeleton.rig() if n_rotations != skeleton.num_joints else skeleton
    legs = set(leg_joints(skeleton))
    below: dict[int, set[int]] = {j: set() for j in range(rig.num_joints)}
    for j in range(rig.num_joints):  # every joint's ancestors get it as a descendant
        a = rig.parents[j]
        while a >= 0:
            below[a].add(j)
            a = rig.parents[a]
    real = skeleton.num_joints  # rig joints past the real ones are branch joints (they coincide with their parent)
    moved = {j: {k for k in d if k < real} for j, d in below.items()}
    return [j for j, d in moved.items() if d and d <= legs]


def lift_rotations(rotations: np.ndarray, *, fk: Callable[[np.ndarray], np.ndarray], skeleton: Skeleton,
                   fps: float, floor: float, max_gain: float = DEFAULT_MAX_GAIN, mean_s: float = DEFAULT_MEAN_S,
                   band_hz: float = DEFAULT_BAND_HZ, damp: float = 0.0, root: bool = True,
                   legs: bool = True) -> tuple[np.ndarray, float]:
    """Local rotations ``(T, J_rig, 3, 3)`` lifted towards ``floor`` m/s of smoothed energy, and the gain.

    Per joint (the root's orientation too), the slow mean rotation ``M`` (the ``mean_s``-second moving mean of
    the matrices, projected onto rotations by SVD) and the deviation ``w = log(M.T R)``; the new rotation is
    ``M exp(w + (g - 1) lowpass(w))``. ``fk(rotations) -> positions (T, J, 3)`` (the caller's forward kinematics
    with the root translation kept) measures the energy for the gain search (:func:`energy_gain`). Returns
    ``(rotations float64, gain)``; gain 1 returns the input unchanged (as float64)."""
    from dancekit.motion.filters import uniform_filter1d

    _check(mean_s, band_hz, fps)
    r = np.asarray(rotations, np.float64)
    n = len(r)
    e = smoothed_energy(fk(r), skeleton=skeleton, fps=fps)
    if not e < floor or n < 3:
        return r.copy(), 1.0
    size = max(1, int(round(mean_s * fps)))
    m = uniform_filter1d(r.reshape(n, -1), size, axis=0).reshape(r.shape)
    u, _, vt = np.linalg.svd(m)
    u[..., :, -1] *= np.sign(np.linalg.det(u @ vt))[..., None]
    m = u @ vt
    w = rotation_log(np.swapaxes(m, -1, -2) @ r)  # (T, J_rig, 3)
    low = _split(w, fps=fps, mean_s=mean_s, band_hz=band_hz)
    high = w - low
    kept = ([] if root else [skeleton.root]) + ([] if legs else leg_rotations(skeleton, r.shape[1]))
    low[:, kept] = 0.0  # the root's orientation (heading, lean) and / or the legs' rotations as they were
    high[:, kept] = 0.0

    def lifted(g: float) -> np.ndarray:
        return m @ rotation_exp(w + (g - 1.0) * low + (g ** -damp - 1.0) * high)

    gain = energy_gain(lambda g: smoothed_energy(fk(lifted(g)), skeleton=skeleton, fps=fps), energy=e,
                       floor=floor, max_gain=max_gain)
    return (lifted(gain), gain) if gain > 1.0 else (r.copy(), 1.0)
