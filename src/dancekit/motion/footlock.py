"""Contact-aware foot locking: planted feet that do not skate, the legs solved by two-bone IK.

NumPy in, NumPy out (keyword-only arguments). Arrays are world joint positions ``(T, J, 3)`` in the
skeleton's units at ``fps`` frames per second; thresholds are in metres and m/s (converted through
:attr:`~dancekit.motion.Skeleton.unit_scale`). Only the legs change: pelvis, spine, arms and head keep their
positions exactly.

=============================  ====================================================================
function                       what
=============================  ====================================================================
:func:`foot_contacts`          per foot and frame, is the foot planted (low + slow, with hysteresis
                               and a minimum duration)
:func:`two_bone_ik`            analytic hip-knee-ankle IK: the knee for an ankle target, bone
                               lengths kept, the knee bending toward its original side
:func:`lock_feet`              the foot pinned at its contact position during every contact, the leg
                               solved by :func:`two_bone_ik`, offsets carried smoothly across the
                               swing between contacts (positions blended: the foot's velocity
                               is continuous at every edge of a hold)
:func:`lock_feet_to_share`     :func:`lock_feet` with its contact speeds scaled down until the locked
                               dance plants its feet no longer than a target share (a genre's real one,
                               :func:`dancekit.motion.floor.planted_share`)
:func:`leg_rotations`          the local rotations of a rotation-based motion updated for new leg
                               positions (twist kept)
=============================  ====================================================================

The legs are :func:`dancekit.motion.analysis.leg_chains` (also importable from here); the floor measures are in
:mod:`dancekit.motion.floor`, the smoothing filters in :mod:`dancekit.motion.filters` and the jitter measures
in :mod:`dancekit.motion.jitter`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.analysis import heights, horizontal_axes, leg_chains, up_sign
from dancekit.motion.floor import local_floor, planted_share
from dancekit.motion.skeleton import Skeleton

__all__ = ["PLANT_SCALES", "FootLockReport", "foot_contacts", "leg_chains", "leg_rotations", "lock_feet",
           "lock_feet_to_share", "smoothstep", "two_bone_ik"]

#: Contact thresholds (metres above the local floor, m/s), chosen on the validation songs
#: (``benchmarks/tune_feet.py``): a foot enters a contact below ``ON`` and leaves it above ``OFF``.
CONTACT_HEIGHT_ON_M = 0.05
CONTACT_HEIGHT_OFF_M = 0.08
CONTACT_SPEED_ON = 0.5
CONTACT_SPEED_OFF = 0.9
MIN_CONTACT_S = 0.12
BLEND_S = 0.32
#: The shortest hold (s) by default: a foot stopped for less is not held. The pipeline stage sets it per
#: model from its checkpoint's ``"foot_lock"`` entry (:func:`dancekit.pipelines.stages.foot_lock_options`).
MIN_HOLD_S = 0.12
#: A held foot is re-planted (a new hold begins after a short gap) once the original foot has moved this far
#: from where it is held, or the leg could not reach it: generated dances glide with a foot near the floor
#: for seconds, and holding it there would stretch the leg.
MAX_DRIFT_M = 0.2
#: The most the whole body is lowered (m) so that a held foot stays within ``reach_share`` of the leg's reach.
MAX_DROP_M = 0.12
#: The factors :func:`lock_feet_to_share` tries on the lock's contact speeds, the lock as set first.
PLANT_SCALES = (1.0, 0.8, 0.6, 0.45, 0.3)


def _check(positions: np.ndarray, name: str) -> np.ndarray:
    p = np.array(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"{name} needs (T, J, 3) positions, got shape {np.shape(positions)}")
    return p


def _hysteresis(on: np.ndarray, stay: np.ndarray, min_len: int) -> np.ndarray:
    """Runs that start where ``on`` holds and last while ``stay`` holds; runs shorter than min_len dropped."""
    out = np.zeros(len(on), dtype=bool)
    t, T = 0, len(on)
    while t < T:
        if on[t]:
            e = t
            while e + 1 < T and stay[e + 1]:
                e += 1
            if e - t + 1 >= min_len:
                out[t : e + 1] = True
            t = e + 1
        else:
            t += 1
    return out


def foot_contacts(
    positions: np.ndarray,
    *,
    skeleton: Skeleton,
    fps: float,
    height_on: float = CONTACT_HEIGHT_ON_M,
    height_off: float = CONTACT_HEIGHT_OFF_M,
    speed_on: float = CONTACT_SPEED_ON,
    speed_off: float = CONTACT_SPEED_OFF,
    min_contact_s: float = MIN_CONTACT_S,
    floor_window_s: float = 2.0,
) -> np.ndarray:
    """Planted feet: ``(T, L)`` booleans, one column per leg of :func:`leg_chains` (left first).

    A foot's height is its lowest joint (ankle, heel, toe) above the *local floor* (the lowest joint of
    the body within ±``floor_window_s``/2, since captured floors are not level); its speed is the
    horizontal speed of its mean foot joint (m/s, central differences). A contact starts where the foot is
    below ``height_on`` metres and slower than ``speed_on`` m/s, lasts while it stays below ``height_off``
    and slower than ``speed_off`` (hysteresis: no flicker at the threshold), and counts when it lasts at
    least ``min_contact_s`` seconds.
    """
    fps = check_fps(fps)
    p = _check(positions, "foot_contacts")
    legs = leg_chains(skeleton)
    if not legs:
        return np.zeros((len(p), 0), dtype=bool)
    if not (height_on <= height_off and speed_on <= speed_off):
        raise ParameterError("foot contacts need height_on <= height_off and speed_on <= speed_off")
    floor = local_floor(p, skeleton, fps, floor_window_s)
    a, b = horizontal_axes(skeleton)
    min_len = max(1, int(round(min_contact_s * fps)))
    cols = []
    for _hip, _knee, ankle, below in legs:
        foot = [ankle, *below]
        h = heights(p[:, foot], skeleton).min(axis=1) * skeleton.unit_scale - floor
        centre = p[:, foot][:, :, [a, b]].mean(axis=1)
        speed = np.linalg.norm(np.gradient(centre, axis=0), axis=-1) * fps * skeleton.unit_scale if len(p) > 1 \
            else np.zeros(len(p))
        cols.append(_hysteresis((h <= height_on) & (speed <= speed_on), (h <= height_off) & (speed <= speed_off),
                                min_len))
    return np.stack(cols, axis=1)


def lock_feet_to_share(positions: np.ndarray, *, skeleton: Skeleton, fps: float, target: float,
                       scales: tuple[float, ...] = PLANT_SCALES, speed_on: float = CONTACT_SPEED_ON,
                       speed_off: float = CONTACT_SPEED_OFF, **lock_options) -> tuple[np.ndarray, float]:
    """:func:`lock_feet`, holding the feet no longer than real dancers plant theirs: ``(locked, scale)``.

    The lock holds every stop of a foot near the floor; on a slow, calm dance that plants the feet far
    longer than real dancers of the genre do (a waltz drawn for a quiet song: 0.36-0.43 of the foot-frames
    against the real waltzes' 0.28). Here the lock's contact speeds (``speed_on``, ``speed_off``, m/s) are
    scaled by each factor of ``scales`` in turn (the first is the lock as set, normally 1); the first lock
    whose :func:`planted_share` is at most ``target`` ends the search, and of it and the one before, the
    share closer to ``target`` is kept. A dance already at or under ``target`` is locked as set: the lock
    never holds more than it would without a target.

    Parameters
    ----------
    positions : (T, J, 3) world positions in skeleton units at ``fps``
    target : the planted-foot share to stay near (0-1), e.g. the genre's real share
    scales : decreasing positive factors on the contact speeds
    speed_on, speed_off, **lock_options : :func:`lock_feet`'s settings

    Returns
    -------
    locked : (T, J, 3) float64, as :func:`lock_feet` returns
    scale : the factor kept
    """
    if not (np.isfinite(target) and 0.0 <= target <= 1.0):
        raise ParameterError(f"target must be a share in [0, 1], got {target!r}")
    if not scales or any(not (np.isfinite(x) and x > 0) for x in scales) or list(scales) != sorted(scales, reverse=True):
        raise ParameterError(f"scales must be decreasing positive numbers, got {scales!r}")
    best: tuple[float, np.ndarray, float] | None = None  # (|share - target|, locked, scale)
    for x in scales:
        locked = lock_feet(positions, skeleton=skeleton, fps=fps, speed_on=speed_on * x, speed_off=speed_off * x,
                           **lock_options)
        share = planted_share(locked, skeleton=skeleton, fps=fps)
        if not np.isfinite(share):  # no legs: nothing to hold
            return locked, float(x)
        gap = abs(share - target)
        if best is None or gap < best[0]:
            best = (gap, locked, float(x))
        if share <= target:
            break
    assert best is not None
    return best[1], best[2]


def two_bone_ik(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, target: np.ndarray, *,
                pole: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Analytic two-bone IK for every frame: ``(knee, ankle)`` new positions, each ``(T, 3)``.

    The hip stays; the thigh keeps its length ``|knee - hip|`` and the shin ``|ankle - knee|`` (each frame's
    own lengths); the ankle goes to ``target`` when it is reachable (``| l1 - l2 | <= |target - hip| <=
    l1 + l2``), else as close as the leg reaches along the hip → target direction (straight or folded). The
    knee bends in the plane through the hip, the target and the original knee, on the original knee's
    side (the pole), so a leg that was bent forward stays bent forward; ``pole`` ``(T, 3)``: another
    direction from the hip to bend toward (its part perpendicular to the hip → target axis counts).
    """
    hip, knee, ankle, target = (np.asarray(x, np.float64) for x in (hip, knee, ankle, target))
    l1 = np.linalg.norm(knee - hip, axis=-1)
    l2 = np.linalg.norm(ankle - knee, axis=-1)
    to = target - hip
    d = np.linalg.norm(to, axis=-1)
    lo, hi = np.abs(l1 - l2), l1 + l2
    d_c = np.clip(d, lo + 1e-9 * hi, hi * (1 - 1e-12))
    u = to / np.maximum(d, 1e-12)[:, None]
    # the pole: the original knee's offset from the hip, perpendicular to the new leg axis
    kv = knee - hip if pole is None else np.asarray(pole, np.float64)
    v = kv - (kv * u).sum(-1, keepdims=True) * u
    vn = np.linalg.norm(v, axis=-1)
    # a knee exactly on the axis (straight leg): bend toward the original ankle's side, else any normal
    fallback = ankle - hip
    fallback = fallback - (fallback * u).sum(-1, keepdims=True) * u
    any_normal = np.cross(u, np.where(np.abs(u[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    fallback = np.where(np.linalg.norm(fallback, axis=-1, keepdims=True) > 1e-9, fallback, any_normal)
    v = np.where(vn[:, None] > 1e-9 * np.maximum(l1, 1e-12)[:, None], v, fallback)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    cos_a = np.clip((l1**2 + d_c**2 - l2**2) / (2 * l1 * d_c), -1.0, 1.0)
    sin_a = np.sqrt(1.0 - cos_a**2)
    new_knee = hip + l1[:, None] * (cos_a[:, None] * u + sin_a[:, None] * v)
    new_ankle = hip + d_c[:, None] * u
    return new_knee, new_ankle


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end] (inclusive) of every run of True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return [(int(s), int(e) - 1) for s, e in zip(edges[::2], edges[1::2], strict=True)]


def smoothstep(x: np.ndarray | float) -> np.ndarray:
    """``3x² − 2x³`` of ``x`` clipped to [0, 1]: 0 → 1 with zero slope at both ends (float64 array)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _offsets(target: np.ndarray, original: np.ndarray, contact: np.ndarray, blend: int) -> np.ndarray:
    """(T, K, 3) offsets (the old, offset-space blend, kept for comparison: ``lock_feet(..., c1_blend=False)``):
    ``target - original`` in contacts; across a swing between two contacts a smoothstep from the offset at
    the end of one to the offset at the start of the next (when the swing is shorter than 2 blends), else
    each decays to 0 over ``blend`` frames; 0 far from any contact. The foot's velocity jumps from 0 to the
    original foot's at a hold's edges."""
    T = len(original)
    off = np.zeros_like(original)
    runs = _runs(contact)
    if not runs:
        return off
    for s, e in runs:
        off[s : e + 1] = target[s : e + 1] - original[s : e + 1]
    # before the first contact and after the last
    s0, e_last = runs[0][0], runs[-1][1]
    for k in range(1, blend + 1):
        w = smoothstep(np.array(1.0 - k / (blend + 1)))
        if s0 - k >= 0:
            off[s0 - k] = w * off[s0]
        if e_last + k < T:
            off[e_last + k] = w * off[e_last]
    for (_, e), (s, _) in zip(runs[:-1], runs[1:], strict=True):
        gap = s - e - 1
        if gap <= 0:
            continue
        t = np.arange(1, gap + 1)
        if gap <= 2 * blend:
            w = smoothstep(t / (gap + 1))[:, None, None]
            off[e + 1 : s] = (1 - w) * off[e] + w * off[s]
        else:
            w_out = smoothstep(1.0 - t / (blend + 1))[:, None, None]
            w_in = smoothstep(1.0 - (gap + 1 - t) / (blend + 1))[:, None, None]
            off[e + 1 : s] = w_out * off[e] + w_in * off[s]
    return off


def _wanted(target: np.ndarray, original: np.ndarray, held: np.ndarray, blend: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the foot joints should be, ``(T, K, 3)``, and how much of the lock acts in each frame ``(T,)`` in
    [0, 1], blending *positions* so the foot's velocity is continuous (C1) at every edge of a hold.

    In a hold the foot is at ``target`` (still). Across a swing of at most ``2 * blend`` frames between two
    holds it goes from the first hold's position to the second's along a smoothstep (zero velocity at both
    ends), plus the original foot's own swing (its path minus the straight line between its end points,
    e.g. the lift) weighted by ``sin²(π x)``, which is 0 with a zero slope at both ends. Elsewhere it is
    handed from the held position to the original foot (and back) by a smoothstep over ``blend`` frames:
    ``(1 - w) held + w original``, so it leaves a hold at rest and reaches the original foot at the original
    foot's speed. Far from any hold it is the original foot (weight 0)."""
    T = len(original)
    want = original.copy()
    weight = np.zeros(T)
    runs = _runs(held)
    if not runs:
        return want, weight
    for s, e in runs:
        want[s : e + 1] = target[s : e + 1]
        weight[s : e + 1] = 1.0

    def hand_over(t: np.ndarray, held_at: int, w: np.ndarray) -> None:  # w: the original foot's weight
        want[t] = (1 - w)[:, None, None] * target[held_at] + w[:, None, None] * original[t]
        weight[t] = np.maximum(weight[t], 1 - w)

    k = np.arange(1, blend + 1)
    w = smoothstep(k / (blend + 1))
    s0, e_last = runs[0][0], runs[-1][1]
    before, after = s0 - k, e_last + k
    hand_over(before[before >= 0], s0, w[before >= 0])
    hand_over(after[after < T], e_last, w[after < T])
    for (_, e), (s, _) in zip(runs[:-1], runs[1:], strict=True):
        gap = s - e - 1
        if gap <= 0:
            continue
        t = np.arange(e + 1, s)
        if gap <= 2 * blend:
            x = ((t - e) / (gap + 1))[:, None, None]
            line = (1 - x) * original[e] + x * original[s]
            want[t] = (1 - smoothstep(x)) * target[e] + smoothstep(x) * target[s] \
                + np.sin(np.pi * x) ** 2 * (original[t] - line)
            weight[t] = 1.0
        else:
            hand_over(e + k, e, w)
            hand_over(s - k, s, w)
    return want, weight


def _segments(p: np.ndarray, contact: np.ndarray, hip: int, foot: list[int], skeleton: Skeleton,
              max_drift_m: float, gap: int, min_len: int) -> list[tuple[int, int]]:
    """Holds [start, end] within the contacts: each holds the foot at its first frame's position while the
    original ankle stays within ``max_drift_m`` (horizontally) of it and the leg reaches it (hip-to-target no
    longer than 99.5 % of thigh + shin); then ``gap`` frames are left free and a new hold begins."""
    a, b = horizontal_axes(skeleton)
    ankle, knee = foot[0], skeleton.parents[foot[0]]
    reach = np.linalg.norm(p[:, knee] - p[:, hip], axis=-1) + np.linalg.norm(p[:, ankle] - p[:, knee], axis=-1)
    limit = max_drift_m / skeleton.unit_scale
    out = []
    for s, e in _runs(contact):
        t0 = s
        while t0 <= e:
            t = _hold_end(p, t0, e, ankle, hip, (a, b), limit, reach)
            if t - t0 + 1 >= min_len:
                out.append((t0, t))
            t0 = t + 1 + gap
    return out


def _hold_end(p: np.ndarray, t0: int, e: int, ankle: int, hip: int, axes: tuple[int, int], limit: float,
              reach: np.ndarray) -> int:
    """The last frame ``t`` in ``[t0, e]`` of a hold planted at frame ``t0``: every frame in ``(t0, t]`` keeps the
    original ankle within ``limit`` (horizontally, ``axes``) of the planted ankle and the planted ankle within
    ``0.995 * reach`` of the hip. Each test is the one of the frame-by-frame rule (``np.hypot`` of the horizontal
    offset, ``np.linalg.norm`` of the hip-to-anchor vector), computed for all frames at once; a frame whose
    batched value lies within 1e-9 (relative) of its bound is tested again exactly as that rule does, so the
    decision is the rule's whatever the rounding of the batched arithmetic."""
    if t0 >= e:
        return t0
    anchor = p[t0, ankle]
    u = np.arange(t0 + 1, e + 1)
    drift = np.hypot(p[u, ankle, axes[0]] - anchor[axes[0]], p[u, ankle, axes[1]] - anchor[axes[1]])
    to_hip = anchor - p[u, hip]  # (n, 3)
    dist = np.sqrt((to_hip * to_hip).sum(axis=-1))
    bound = 0.995 * reach[u]
    keep = (drift <= limit) & (dist <= bound)
    near = (np.abs(drift - limit) <= 1e-9 * abs(limit)) | (np.abs(dist - bound) <= 1e-9 * np.abs(bound))
    for k in np.flatnonzero(near):  # the frame-by-frame rule's own arithmetic
        keep[k] = bool(np.hypot(*(p[u[k], ankle, list(axes)] - anchor[list(axes)])) <= limit
                       and np.linalg.norm(anchor - p[u[k], hip]) <= 0.995 * reach[u[k]])
    stop = np.flatnonzero(~keep)
    return e if not len(stop) else t0 + int(stop[0])


@dataclass
class FootLockReport:
    """What :func:`lock_feet` did: ``contacts`` ``(T, L)`` planted frames per leg, ``reach_error`` ``(T, L)``
    the ankle's distance from its target where the leg could not reach it, ``drop`` ``(T,)`` how far the
    whole body was lowered (skeleton units), ``held`` ``(T, L)`` the frames in which each foot is held still."""

    contacts: np.ndarray
    reach_error: np.ndarray
    drop: np.ndarray
    held: np.ndarray | None = None


def lock_feet(
    positions: np.ndarray,
    *,
    skeleton: Skeleton,
    fps: float,
    contacts: np.ndarray | None = None,
    blend_s: float = BLEND_S,
    max_drift_m: float = MAX_DRIFT_M,
    floor_on: bool = True,
    max_drop_m: float = MAX_DROP_M,
    reach_share: float = 0.97,
    min_hold_s: float = MIN_HOLD_S,
    c1_blend: bool = True,
    pole_sigma: float = 0.08,
    sink_sigma_s: float = 0.06,
    return_report: bool = False,
    **contact_options,
) -> np.ndarray | tuple[np.ndarray, FootLockReport]:
    """Pin every planted foot where it was planted: a new ``(T, J, 3)`` float64 array (and a
    :class:`FootLockReport` with ``return_report``).

    Per contact of :func:`foot_contacts` (or ``contacts`` ``(T, L)`` given), the foot joints (ankle, heel,
    toe) are held at their positions of the contact's first frame while the original ankle stays within
    ``max_drift_m`` of it and the leg can reach it; beyond that the foot is re-planted after a few free
    frames (:func:`_segments`: a dance that glides gets steps, not a stretched leg). With ``floor_on`` a held
    foot is also put down: its lowest joint on the local floor (the lowest joint within ±1 s). Where a held
    foot would be farther from its hip than ``reach_share`` of thigh + shin, the whole body is lowered
    (rigidly, by at most ``max_drop_m``, smoothly over the blend: the pelvis sinks and the knees bend, as a
    dancer's do) instead of stretching the leg straight; a free foot the lowered body would push through
    the floor is lifted onto it (a landing softened by a ``sink_sigma_s`` Gaussian, never lower than the
    floor). A stop shorter than ``min_hold_s`` is not held (a hold of a few frames is a stop-and-go of the
    foot, jitter rather than a step). The leg is solved by :func:`two_bone_ik` (hip fixed, thigh and shin
    lengths kept), the knee toward its original side nudged toward the toes where the lock acts (a nearly
    straight leg's side is noise), the pole low-passed over time (Gaussian, ``pole_sigma`` seconds: a knee
    that swivels about the hip-ankle axis from one frame to the next is a flip); the foot bones hang from
    the new ankle with their own lengths. Between holds the foot's *position* is blended (:func:`_wanted`:
    a smoothstep from one hold to the next across a short swing, a ``blend_s`` hand-over to and from the
    original foot elsewhere), so its velocity is continuous at every edge of a hold (``c1_blend=False``: the
    former offset blend, :func:`_offsets`, whose foot stops dead and starts at full speed). Joints that are
    not in a leg below the hip are untouched.
    """
    fps = check_fps(fps)
    p = _check(positions, "lock_feet")
    legs = leg_chains(skeleton)
    if contacts is None:
        contacts = foot_contacts(p, skeleton=skeleton, fps=fps, **contact_options)
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.shape != (len(p), len(legs)):
        raise ParameterError(f"contacts must have shape {(len(p), len(legs))}, got {contacts.shape}")
    a, b = horizontal_axes(skeleton)
    blend = max(1, int(round(blend_s * fps)))
    gap = max(2, blend)
    floor = local_floor(p, skeleton, fps, 2.0) / skeleton.unit_scale  # (T,) skeleton units
    min_len = max(1, int(round(min_hold_s * fps)))
    err = np.zeros((len(p), len(legs)))
    parents = list(skeleton.parents)
    up = np.zeros(3)
    up[skeleton.up_index] = up_sign(skeleton)
    targets, helds = [], []
    drop = np.zeros(len(p))  # how far the body is lowered (skeleton units) so the held feet are in reach
    for hip, knee, ankle, below in legs:
        foot = [ankle, *below]
        target = p[:, foot].copy()
        held = np.zeros(len(p), dtype=bool)
        for s, e in _segments(p, contacts[:, len(targets)], hip, foot,
                              skeleton, max_drift_m, gap, min_len):
            pinned = p[s, foot].copy()  # the foot where it was planted (the hold's first frame) ...
            if floor_on:  # ... put down on the local floor
                pinned[:, skeleton.up_index] -= up_sign(skeleton) * (heights(pinned, skeleton).min() - floor[s])
            target[s : e + 1] = pinned
            held[s : e + 1] = True
        targets.append(target)
        helds.append(held)
        if max_drop_m > 0 and held.any():
            reach = reach_share * (np.linalg.norm(p[:, knee] - p[:, hip], axis=-1)
                                   + np.linalg.norm(p[:, ankle] - p[:, knee], axis=-1))
            r = target[:, 0] - p[:, hip]
            dv = r @ up  # < 0: the ankle below the hip
            dh2 = np.maximum((r * r).sum(-1) - dv**2, 0.0)
            need = -dv - np.sqrt(np.maximum(reach**2 - dh2, 0.0))
            drop = np.maximum(drop, np.where(held, np.clip(need, 0.0, max_drop_m / skeleton.unit_scale), 0.0))
    if drop.any():  # lowered smoothly: at least as far as needed around every frame, no sudden sink
        from dancekit.motion.filters import gaussian_filter1d, maximum_filter1d

        drop = gaussian_filter1d(maximum_filter1d(drop, 2 * blend + 1), blend / 2)
        p -= drop[:, None, None] * up  # p is this function's own float64 copy: lowered in place
    out = p.copy()
    for leg, (hip, knee, ankle, below) in enumerate(legs):
        foot = [ankle, *below]
        orig = p[:, foot]  # (T, F, 3), the body lowered
        if c1_blend:
            want, weight = _wanted(targets[leg], orig, helds[leg], blend)
        else:
            want = orig + _offsets(targets[leg], orig, helds[leg], blend)
            weight = np.ones(len(p))
        if drop.any():  # a lowered body must not push a free foot through the floor
            sink = np.maximum(floor - heights(want, skeleton).min(axis=1), 0.0) * (drop > 0)
            if sink_sigma_s > 0 and c1_blend and sink.any():  # a softer landing, never lower than the floor
                from dancekit.motion.filters import gaussian_filter1d

                sink = np.maximum(sink, gaussian_filter1d(sink, sink_sigma_s * fps))
            want = want + sink[:, None, None] * up
        off = want - orig
        changed = np.abs(off).max(axis=(1, 2)) > 0
        if not changed.any():
            continue
        t = np.flatnonzero(changed)
        # the knee bends toward its own side, nudged toward the toes (a nearly straight leg's side is noise
        # and would flip); the nudge acts where the lock does (its weight, or the ankle moved by 2 cm or more)
        # and fades with it; the original knee's side is low-passed over time (a swivel of the knee about the
        # hip-ankle axis from one frame to the next is a flip, not a dance)
        toe = want[:, -1] - want[:, 0]
        toe = toe - (toe @ up)[:, None] * up
        toe /= np.maximum(np.linalg.norm(toe, axis=-1, keepdims=True), 1e-12)
        thigh = np.linalg.norm(p[:, knee] - p[:, hip], axis=-1, keepdims=True)
        if c1_blend:
            moved = np.linalg.norm(off[:, 0], axis=-1) * skeleton.unit_scale / 0.02
            act = np.clip(np.maximum(weight, moved), 0.0, 1.0)
            side = p[:, knee] - p[:, hip]
            if pole_sigma > 0:
                from dancekit.motion.filters import gaussian_filter1d

                side = gaussian_filter1d(side, pole_sigma * fps, axis=0)
            pole = (side + 0.25 * thigh * act[:, None] * toe)[t]
        else:
            pole = ((p[:, knee] - p[:, hip]) + 0.25 * thigh * toe)[t]
        new_knee, new_ankle = two_bone_ik(p[t, hip], p[t, knee], p[t, ankle], want[t, 0], pole=pole)
        out[t, knee] = new_knee
        out[t, ankle] = new_ankle
        err[t, leg] = np.linalg.norm(new_ankle - want[t, 0], axis=-1)
        # foot bones: directions from the wanted foot, lengths from the original frame
        for j in below:
            q = parents[j]
            length = np.linalg.norm(p[t, j] - p[t, q], axis=-1, keepdims=True)
            qi, ji = foot.index(q), foot.index(j)
            d = want[t, ji] - want[t, qi]
            d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
            out[t, j] = out[t, q] + length * d
    if return_report:
        held = np.stack(helds, axis=1) if helds else np.zeros((len(p), 0), dtype=bool)
        return out, FootLockReport(contacts=contacts, reach_error=err, drop=drop, held=held)
    return out


def _minimal_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the smallest rotations taking unit vectors a to b (N, 3)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    v = np.cross(a, b)
    c = (a * b).sum(-1)
    K = np.zeros((len(a), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 0] = -v[:, 2], v[:, 1], v[:, 2]
    K[:, 1, 2], K[:, 2, 0], K[:, 2, 1] = -v[:, 0], -v[:, 1], v[:, 0]
    R = np.eye(3) + K + (K @ K) / np.maximum(1.0 + c, 1e-9)[:, None, None]
    opposite = c < -1 + 1e-9
    if opposite.any():  # a half turn about any axis perpendicular to a
        n = np.cross(a[opposite], np.where(np.abs(a[opposite, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        R[opposite] = 2 * n[:, :, None] * n[:, None, :] - np.eye(3)
    return R


def leg_rotations(rotations: np.ndarray, old_positions: np.ndarray, new_positions: np.ndarray, *,
                  skeleton: Skeleton) -> np.ndarray:
    """Local rig rotations ``(T, J_rig, 3, 3)`` for leg positions changed by :func:`lock_feet`.

    For every joint of a leg from the hip down, its world rotation is turned by the smallest rotation that
    takes its old child bone (world direction) onto the new one, so its twist about the bone is kept; the
    local rotations follow (``R[j] = G[parent]ᵀ G[j]``). Joints above the hips keep their rotations, so the
    forward kinematics moves only the legs. The rotations must be those of ``old_positions``.
    """
    from dancekit.motion.kinematics import rig_rotations

    rot = np.array(rig_rotations(np.asarray(rotations, np.float64), skeleton))
    rig = skeleton.rig()
    parents = list(rig.parents)
    order = []
    for hip, _knee, _ankle, below in leg_chains(skeleton):
        order += [hip, _knee, _ankle, *below]
    if not order:
        return rot
    # world rotations of every rig joint (parents first)
    from dancekit.motion.skeleton import parents_first_order

    G = np.empty_like(rot)
    for j in parents_first_order(parents):
        G[:, j] = rot[:, j] if parents[j] < 0 else G[:, parents[j]] @ rot[:, j]
    G_new = G.copy()
    old = np.asarray(old_positions, np.float64)
    new = np.asarray(new_positions, np.float64)
    for j in order:
        kids = [c for c, q in enumerate(parents) if q == j and c < skeleton.num_joints]
        if kids:
            c = kids[0]
            a = old[:, c] - old[:, j]
            b = new[:, c] - new[:, j]
            moved = np.abs(b - a).max(axis=-1) > 0
            if moved.any():
                G_new[moved, j] = _minimal_rotation(a[moved], b[moved]) @ G[moved, j]
        q = parents[j]
        rot[:, j] = np.swapaxes(G_new[:, q], -1, -2) @ G_new[:, j]
    return rot
