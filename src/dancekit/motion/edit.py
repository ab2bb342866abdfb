"""Editing a finished dance: continue a given motion, pass through keyframes, follow a path, keep body parts.

Pure NumPy on joint positions ``(T, J, 3)`` in skeleton units (``skeleton.unit_scale`` metres per unit) at
``fps`` frames per second; frame ``i`` is at ``i / fps`` s. Every function returns a new float64 array of the
same shape and leaves its input alone. The file readers (:func:`read_keyframes`, :func:`read_path`) raise a
one-line :class:`~dancekit.errors.ParameterError` naming the file.

The files:

* ``keys.json``: a list of keys, each ``{"time": seconds}`` or ``{"beat": index}`` (0-based, into the song's
  tracked beats) and ``"pose"``: a motion file (npz / bvh / glb / pkl: its first frame, whole pose) or
  ``{"joint_name": [x, y, z], ...}`` (chosen joints, skeleton units, world coordinates). A key with a
  ``"frame"`` instead of a time is a frame index.
* ``path.json``: ``{"points": [[x, z], ...]}`` in metres on the floor (the skeleton's two horizontal axes, in
  increasing axis order), optional ``"times": [...]`` (s, increasing, one per point); without times the root
  walks the polyline at constant speed over the whole dance.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancekit.errors import ParameterError
from dancekit.motion.analysis import heading_axes, horizontal_axes
from dancekit.motion.cleanup import DEFAULT_RADIUS_M
from dancekit.motion.footlock import smoothstep
from dancekit.motion.skeleton import Skeleton

__all__ = ["CROSSFADE_S", "KEY_SUPPORT_S", "Key", "MAX_SPEED_M_S", "MAX_SWAY_M", "PATH_CUTOFF_HZ", "apply_keyframes",
           "body_part_joints", "continue_from", "follow_path", "keep_joints", "key_correction", "read_keyframes",
           "read_path", "wendland"]

#: The fastest a keyed joint may have to travel between two keys (m/s); faster keys are refused.
MAX_SPEED_M_S = 5.0
#: Half-width (s) of a key's smooth correction: frames farther than this from every key are not changed.
KEY_SUPPORT_S = 1.0
#: The cut-off (Hz) below which the root's horizontal motion is the "slow trajectory" a path replaces.
PATH_CUTOFF_HZ = 0.5
#: The largest RMS (m) of the root's own sway kept around a path (a larger sway is scaled down to it).
MAX_SWAY_M = 0.05
#: The window (s) after a prefix over which the generated dance is faded onto the prefix's last pose.
CROSSFADE_S = 0.5


def wendland(r: np.ndarray) -> np.ndarray:
    """Wendland's C2 bump ``(1 - r)^4 (4 r + 1)`` for ``|r| < 1``, else 0: smooth (C2), 1 at 0, compactly
    supported, and positive definite (any set of distinct centres gives an invertible interpolation matrix)."""
    r = np.abs(np.asarray(r, np.float64))
    return np.where(r < 1.0, (1.0 - r) ** 4 * (4.0 * r + 1.0), 0.0)


@dataclass(frozen=True)
class Key:
    """One keyframe: at ``frame``, joints ``joints`` (indices) at ``positions`` (``(n, 3)``, skeleton units)."""

    frame: int
    joints: tuple[int, ...]
    positions: np.ndarray


def _fail(path, what: str) -> ParameterError:
    return ParameterError(f"{path}: {what}")


def _load_json(path: str | os.PathLike):
    p = Path(path)
    if not p.is_file():
        raise ParameterError(f"{p}: no such file")
    try:
        return json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise _fail(p, f"not valid JSON ({exc})") from None


def _number(path, where: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _fail(path, f"{where} must be a finite number, got {v!r}")
    return float(v)


def read_keyframes(path: str | os.PathLike, *, skeleton: Skeleton, fps: float, num_frames: int,
                   beats: Sequence[float] | None = None, max_speed: float = MAX_SPEED_M_S) -> list[Key]:
    """The keys of a ``keys.json`` (module docstring) for a dance of ``num_frames`` frames at ``fps`` on
    ``skeleton``: sorted by frame, a time rounded to the nearest frame. ``beats``: the song's beat times (s)
    for keys given by beat. Refused (ParameterError naming the file): a key outside the dance, an unknown
    joint, two keys on one frame for one joint, or a joint that would have to move faster than ``max_speed``
    m/s between two consecutive keys."""
    data = _load_json(path)
    if not isinstance(data, list) or not data:
        raise _fail(path, "expected a non-empty list of keys")
    keys: list[Key] = []
    for i, item in enumerate(data):
        if not isinstance(item, dict) or "pose" not in item:
            raise _fail(path, f"key {i} must be an object with a 'pose' and a 'time', 'beat' or 'frame'")
        when = [k for k in ("time", "beat", "frame") if k in item]
        if len(when) != 1:
            raise _fail(path, f"key {i} needs exactly one of 'time', 'beat', 'frame', got {when or 'none'}")
        if when[0] == "beat":
            b = item["beat"]
            if isinstance(b, bool) or not isinstance(b, int):
                raise _fail(path, f"key {i}: beat must be an integer index, got {b!r}")
            if beats is None or not 0 <= b < len(beats):
                n = 0 if beats is None else len(beats)
                raise _fail(path, f"key {i}: beat {b} is not among the song's {n} tracked beats")
            frame = int(round(float(beats[b]) * fps))
        elif when[0] == "time":
            frame = int(round(_number(path, f"key {i} time", item["time"]) * fps))
        else:
            frame = item["frame"]
            if isinstance(frame, bool) or not isinstance(frame, int):
                raise _fail(path, f"key {i}: frame must be an integer, got {frame!r}")
        if not 0 <= frame < num_frames:
            raise _fail(path, f"key {i} at {frame / fps:.2f} s is outside the dance (0-{(num_frames - 1) / fps:.2f} s)")
        joints, pos = _key_pose(path, i, item["pose"], skeleton)
        keys.append(Key(frame=frame, joints=joints, positions=pos))
    keys.sort(key=lambda k: k.frame)
    check_key_speed(keys, skeleton=skeleton, fps=fps, max_speed=max_speed, source=path)
    return keys


def _key_pose(path, i: int, pose, skeleton: Skeleton) -> tuple[tuple[int, ...], np.ndarray]:
    if isinstance(pose, str):
        from dancekit.motion.formats import read_motion

        file = Path(pose) if Path(pose).is_absolute() else Path(path).parent / pose
        m = read_motion(file)
        if not m.skeleton.same_as(skeleton):
            from dancekit.motion.retarget import map_by_role

            m = map_by_role(m, skeleton)
        return tuple(range(skeleton.num_joints)), np.asarray(m.to_positions()[0], np.float64)
    if not isinstance(pose, dict) or not pose:
        raise _fail(path, f"key {i}: pose must be a motion file or {{joint: [x, y, z]}}, got {pose!r}")
    joints, pos = [], []
    for name, xyz in pose.items():
        if name not in skeleton.joint_names:
            raise _fail(path, f"key {i}: skeleton {skeleton.name!r} has no joint {name!r}")
        if not isinstance(xyz, list) or len(xyz) != 3:
            raise _fail(path, f"key {i}: {name} must be [x, y, z], got {xyz!r}")
        joints.append(skeleton.joint_names.index(name))
        pos.append([_number(path, f"key {i} {name}", v) for v in xyz])
    return tuple(joints), np.asarray(pos, np.float64)


def check_key_speed(keys: Sequence[Key], *, skeleton: Skeleton, fps: float, max_speed: float = MAX_SPEED_M_S,
                    source="keys") -> None:
    """ParameterError (naming ``source``) when a joint is keyed twice on one frame, or would have to move
    faster than ``max_speed`` m/s between two consecutive keys of it."""
    last: dict[int, tuple[int, np.ndarray]] = {}
    for k in sorted(keys, key=lambda k: k.frame):
        for j, p in zip(k.joints, k.positions):
            if j in last:
                f0, p0 = last[j]
                if f0 == k.frame:
                    raise _fail(source, f"joint {skeleton.joint_names[j]} keyed twice at {k.frame / fps:.2f} s")
                speed = float(np.linalg.norm(p - p0)) * skeleton.unit_scale * fps / (k.frame - f0)
                if speed > max_speed:
                    raise _fail(source, f"joint {skeleton.joint_names[j]} would move at {speed:.1f} m/s between "
                                        f"{f0 / fps:.2f} s and {k.frame / fps:.2f} s (at most {max_speed:g} m/s)")
            last[j] = (k.frame, p)


def key_correction(num_frames: int, frames: np.ndarray, residuals: np.ndarray, *, support: float) -> np.ndarray:
    """The smooth correction ``(T, D)`` that equals ``residuals[i]`` (``(n, D)``) at ``frames[i]`` (distinct):
    a sum of :func:`wendland` bumps of half-width ``support`` frames centred on the keys, weights solved so the
    sum is exact at every key even where bumps overlap. Zero farther than ``support`` from every key."""
    frames = np.asarray(frames, np.float64)
    phi = wendland((frames[:, None] - frames[None, :]) / support)
    w = np.linalg.solve(phi, np.asarray(residuals, np.float64))
    t = np.arange(num_frames, dtype=np.float64)
    return wendland((t[:, None] - frames[None, :]) / support) @ w


def apply_keyframes(positions: np.ndarray, *, keys: Sequence[Key], fps: float,
                    support_s: float = KEY_SUPPORT_S) -> np.ndarray:
    """The dance ``(T, J, 3)`` through its keys: per keyed joint, :func:`key_correction` of the differences
    key − dance (half-width ``support_s`` s) added, so the joint is exactly at the key on the key's frame and
    smoothly corrected around it; unkeyed joints and frames farther than ``support_s`` from a joint's keys are
    unchanged."""
    p = np.array(positions, np.float64)
    per_joint: dict[int, list[tuple[int, np.ndarray]]] = {}
    for k in keys:
        for j, x in zip(k.joints, k.positions):
            per_joint.setdefault(j, []).append((k.frame, x))
    support = max(float(support_s) * fps, 1.0)
    for j, items in per_joint.items():
        frames = np.array([f for f, _ in items])
        res = np.stack([x for _, x in items]) - p[frames, j]
        p[:, j] += key_correction(len(p), frames, res, support=support)
        p[frames, j] = np.stack([x for _, x in items])  # exact to the last bit (the solve is exact to rounding)
    return p


def read_path(path: str | os.PathLike, *, radius_m: float = DEFAULT_RADIUS_M) -> tuple[np.ndarray, np.ndarray | None]:
    """The ``(N, 2)`` points (m) and optional ``(N,)`` times (s) of a ``path.json`` (module docstring).
    Refused (ParameterError naming the file): fewer than 2 points, a point farther than ``radius_m`` (the
    clean-up's dance floor) from the first, times not increasing from >= 0 or not one per point."""
    data = _load_json(path)
    if not isinstance(data, dict) or "points" not in data:
        raise _fail(path, "expected an object with 'points': [[x, z], ...]")
    pts = data["points"]
    if not isinstance(pts, list) or len(pts) < 2 or not all(isinstance(q, list) and len(q) == 2 for q in pts):
        raise _fail(path, "'points' must be a list of at least 2 [x, z] pairs (metres)")
    points = np.array([[_number(path, "a point", v) for v in q] for q in pts], np.float64)
    far = float(np.max(np.linalg.norm(points - points[0], axis=1)))
    if far > radius_m:
        raise _fail(path, f"the path reaches {far:.2f} m from its start, beyond the {radius_m:g}-m dance floor")
    unknown = set(data) - {"points", "times"}
    if unknown:
        raise _fail(path, f"unknown keys {sorted(unknown)} (expected 'points' and optional 'times')")
    times = None
    if "times" in data:
        ts = data["times"]
        if not isinstance(ts, list) or len(ts) != len(points):
            raise _fail(path, f"'times' must be a list of {len(points)} numbers (one per point)")
        times = np.array([_number(path, "a time", v) for v in ts], np.float64)
        if times[0] < 0 or np.any(np.diff(times) <= 0):
            raise _fail(path, "'times' must increase from 0 or later")
    return points, times


def path_positions(points: np.ndarray, times: np.ndarray | None, *, num_frames: int, fps: float) -> np.ndarray:
    """The path's floor position (m, ``(T, 2)``) at every frame: linear between timed points (held before the
    first time and after the last), or at constant speed along the polyline over the dance without times."""
    t = np.arange(num_frames, dtype=np.float64) / fps
    if times is None:
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        times = s / s[-1] * t[-1] if s[-1] > 0 and num_frames > 1 else np.linspace(0, t[-1], len(points))
    return np.stack([np.interp(t, times, points[:, 0]), np.interp(t, times, points[:, 1])], axis=1)


def _lowpass(x: np.ndarray, *, fps: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Gaussian low-pass along axis 0 (sigma from the -3 dB cut-off); the edges padded by point
    reflection (``2 x[0] - x[k]``), so a steady drift at an edge stays in the low-pass, not in the remainder."""
    from dancekit.motion.filters import gaussian_filter1d

    sigma = fps * math.sqrt(math.log(2.0)) / (math.sqrt(2.0) * math.pi * cutoff_hz)
    n = min(int(math.ceil(4 * sigma)), len(x) - 1)
    if n < 1:
        return np.array(x, np.float64)
    head = 2 * x[0] - x[n:0:-1]
    tail = 2 * x[-1] - x[-2:-n - 2:-1]
    y = gaussian_filter1d(np.concatenate([head, x, tail]), sigma, axis=0)
    return y[n:n + len(x)]


def follow_path(positions: np.ndarray, *, skeleton: Skeleton, fps: float, points: np.ndarray,
                times: np.ndarray | None = None, cutoff_hz: float = PATH_CUTOFF_HZ,
                max_sway_m: float = MAX_SWAY_M) -> np.ndarray:
    """The dance moved (every joint by the same horizontal shift per frame) so that the root's slow horizontal
    trajectory (its ``cutoff_hz`` low-pass) is the path ``points`` (m, ``(N, 2)``, optional ``times`` s): the
    root's own fast sway (root − its low-pass) is kept, scaled down to ``max_sway_m`` m RMS when larger (so
    the root stays within that of the path). Heights unchanged."""
    p = np.array(positions, np.float64)
    a, b = horizontal_axes(skeleton)
    root = p[:, skeleton.root][:, [a, b]]
    sway = root - _lowpass(root, fps=fps, cutoff_hz=cutoff_hz)
    rms = float(np.sqrt(np.mean(np.sum(sway ** 2, axis=1)))) * skeleton.unit_scale
    if rms > max_sway_m:
        sway *= max_sway_m / rms
    target = path_positions(points, times, num_frames=len(p), fps=fps) / skeleton.unit_scale + sway
    p[:, :, a] += (target - root)[:, None, 0]
    p[:, :, b] += (target - root)[:, None, 1]
    return p


def body_part_joints(skeleton: Skeleton, keep: str | Sequence[str]) -> tuple[int, ...]:
    """The joints of ``keep``: ``"lower"`` (the legs: hips, knees, ankles and the foot joints below),
    ``"upper"`` (every other joint but the root), or joint names (a list, or one comma-separated string).
    The root is never kept (the kept joints ride on the generated root)."""
    from dancekit.motion.energy import leg_joints

    legs = set(leg_joints(skeleton)) - {skeleton.root}
    if keep == "lower":
        return tuple(sorted(legs))
    if keep == "upper":
        return tuple(j for j in range(skeleton.num_joints) if j not in legs and j != skeleton.root)
    names = [n.strip() for n in keep.split(",")] if isinstance(keep, str) else list(keep)
    out = []
    for n in names:
        if n not in skeleton.joint_names:
            raise ParameterError(f"keep: skeleton {skeleton.name!r} has no joint {n!r} "
                                 f"(upper, lower, or names from {', '.join(skeleton.joint_names)})")
        j = skeleton.joint_names.index(n)
        if j == skeleton.root:
            raise ParameterError(f"keep: the root {n!r} cannot be kept (kept joints ride on the generated root)")
        out.append(j)
    return tuple(sorted(set(out)))


def keep_joints(positions: np.ndarray, take: np.ndarray, *, skeleton: Skeleton,
                joints: Sequence[int]) -> np.ndarray:
    """The dance ``(T, J, 3)`` with ``joints`` from ``take`` (``(T', J, 3)``, T' >= T, same skeleton and fps):
    each kept joint at the generated root plus its offset from the take's root, frame by frame."""
    p = np.array(positions, np.float64)
    tk = np.asarray(take, np.float64)[: len(p)]
    r = skeleton.root
    idx = list(joints)
    p[:, idx] = p[:, r][:, None] + (tk[:, idx] - tk[:, r][:, None])
    return p


def _yaw(positions: np.ndarray, skeleton: Skeleton, frame: int) -> float:
    """The heading angle (rad) about the up axis at ``frame``: the forward vector's angle in the floor plane."""
    a, b = horizontal_axes(skeleton)
    fwd = heading_axes(positions[frame:frame + 1], skeleton)[2][0]
    return math.atan2(fwd[b], fwd[a])


def continue_from(prefix: np.ndarray, positions: np.ndarray, *, skeleton: Skeleton, fps: float,
                  crossfade_s: float = CROSSFADE_S) -> np.ndarray:
    """The dance ``(T, J, 3)`` continuing ``prefix`` (``(P, J, 3)``, P < T, same skeleton and fps): frames
    ``[0, P)`` are the prefix exactly; frames ``[P, T)`` are the dance's, turned about the up axis and moved on
    the floor so that its frame ``P - 1`` has the prefix's last root position (horizontal) and heading, then
    the remaining difference in pose and in velocity to the prefix's last frames faded out (a smoothstep, so
    position and velocity continue across the seam) over ``crossfade_s`` s after P."""
    pre = np.asarray(prefix, np.float64)
    p = np.array(positions, np.float64)
    n = len(pre)
    if not 1 < n < len(p):
        raise ParameterError(f"the prefix ({n} frames) must be at least 2 frames and shorter than the dance "
                             f"({len(p)} frames)")
    a, b = horizontal_axes(skeleton)
    r = skeleton.root
    ang = _yaw(pre, skeleton, n - 1) - _yaw(p, skeleton, n - 1)
    c, s = math.cos(ang), math.sin(ang)
    pivot = p[n - 1, r].copy()
    rel = p[n - 2:] - pivot  # from the frame before the seam's: rel[1] is frame n - 1
    xa, xb = rel[..., a].copy(), rel[..., b].copy()
    rel[..., a] = c * xa - s * xb + pre[n - 1, r, a]
    rel[..., b] = s * xa + c * xb + pre[n - 1, r, b]
    rel[..., skeleton.up_index] += pivot[skeleton.up_index]
    gap = pre[n - 1] - rel[1]  # (J, 3) the pose left to bridge after the rigid alignment
    dv = (pre[n - 1] - pre[n - 2]) - (rel[1] - rel[0])  # (J, 3) and the velocity (per frame)
    w = max(int(round(crossfade_s * fps)), 1)
    k = np.arange(1, len(rel) - 1, dtype=np.float64)  # frames after n - 1
    fade = 1.0 - smoothstep(k / w)  # 1 with zero slope at the seam, 0 from w frames on
    out = np.empty_like(p)
    out[:n] = pre
    out[n:] = rel[2:] + fade[:, None, None] * (gap[None] + k[:, None, None] * dv[None])
    return out
