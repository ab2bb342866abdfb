"""Physical clean-up of generated dances: feet on the floor, a root path that stays on a dance floor.

NumPy in, NumPy out (keyword-only arguments). Arrays are world joint positions ``(T, J, 3)`` in the
skeleton's units at ``fps`` frames per second; the skeleton gives the up axis and metres per unit
(:attr:`~dancekit.motion.Skeleton.unit_scale`). Every step moves whole frames rigidly (a vertical
offset, or a turn about the vertical axis through the root), so poses, bone lengths and the motion of
the feet relative to the body are kept.

=============================  ====================================================================
function                       what
=============================  ====================================================================
:func:`ground_contact`         vertical offset per frame so that the lowest joint touches the floor
                               (height 0) at least once in every ``window_s`` and never goes below it
:func:`contain_root_path`      turns the travel back toward the start once the root is farther than
                               ``radius_m`` (a bounded turning rate), so the figure stays on a floor
:func:`clean_up`               both, in that order
=============================  ====================================================================
"""

from __future__ import annotations

import math

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.analysis import heights, horizontal_axes, up_sign
from dancekit.motion.skeleton import Skeleton

__all__ = ["DEFAULT_HARD_RADIUS_M", "DEFAULT_RADIUS_M", "GROUND_SMOOTH_S", "GROUND_WINDOW_S", "RootPathTurner",
           "clean_up", "contain_root_path", "ground_contact", "ground_offset", "root_path_turns", "turn_and_move"]

#: Distance from the start (m) beyond which the travel is turned back toward the start.
DEFAULT_RADIUS_M = 4.0
#: Distance from the start (m) that the root never exceeds (a last resort: the outward step is dropped).
DEFAULT_HARD_RADIUS_M = 12.0
#: :func:`ground_contact`'s window (s): the lowest joint touches the floor at least once in every window
GROUND_WINDOW_S = 0.2
#: :func:`ground_contact`'s smoothing of the offset (s, a Gaussian's standard deviation)
GROUND_SMOOTH_S = 0.05


def ground_offset(
    positions: np.ndarray, *, skeleton: Skeleton, fps: float, window_s: float = GROUND_WINDOW_S,
    smooth_s: float = GROUND_SMOOTH_S
) -> np.ndarray:
    """The height ``(T,)`` (skeleton units, along the up direction) to take off every frame so that the
    lowest joint rests on the floor (height 0): see :func:`ground_contact`."""
    from dancekit.motion.filters import gaussian_filter1d, minimum_filter1d

    fps = check_fps(fps)
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"ground_contact needs (T, J, 3) positions, got shape {p.shape}")
    low = heights(p, skeleton).min(axis=1)  # (T,)
    size = max(1, int(round(window_s * fps)) | 1)
    offset = minimum_filter1d(low, size)
    if smooth_s:
        offset = gaussian_filter1d(offset, smooth_s * fps)
    return np.minimum(offset, low)


def ground_contact(
    positions: np.ndarray, *, skeleton: Skeleton, fps: float, window_s: float = GROUND_WINDOW_S,
    smooth_s: float = GROUND_SMOOTH_S
) -> np.ndarray:
    """Put the lowest joint on the floor (height 0 along the up axis): a new ``(T, J, 3)`` float64 array.

    The vertical offset at frame ``t`` (:func:`ground_offset`) is the running minimum of the lowest
    joint's height over a centred ``window_s`` window, Gaussian-smoothed (standard deviation ``smooth_s``
    seconds), and never more than the lowest joint's own height there (no penetration). So the slow
    float and the bobbing of the whole figure go, while faster vertical motion (a step, a rise of less
    than ``window_s / 2``) stays; the lowest joint touches the floor at least once in every window.
    """
    p = np.array(positions, dtype=np.float64)
    offset = ground_offset(p, skeleton=skeleton, fps=fps, window_s=window_s, smooth_s=smooth_s)
    p[..., skeleton.up_index] -= up_sign(skeleton) * offset[:, None]
    return p


def _positive_dot(a0: float, a1: float, b0: float, b1: float) -> bool:
    """Whether ``[a0, a1] @ [b0, b1] > 0`` as NumPy computes it: the products summed on Python floats, or NumPy's
    own dot product where the sum is within 1e-12 (relative) of 0 (a fused multiply-add there may round the
    other way)."""
    dot = a0 * b0 + a1 * b1
    if abs(dot) <= 1e-12 * (abs(a0 * b0) + abs(a1 * b1)):
        dot = float(np.array([a0, a1]) @ np.array([b0, b1]))
    return dot > 0


def root_path_turns(
    positions: np.ndarray,
    *,
    skeleton: Skeleton,
    fps: float,
    radius_m: float = DEFAULT_RADIUS_M,
    turn_rate: float = 0.5,
    turn_time_s: float = 0.5,
    hard_radius_m: float = DEFAULT_HARD_RADIUS_M,
) -> tuple[np.ndarray, np.ndarray]:
    """The turns that keep the root's horizontal path within a dance floor (:func:`contain_root_path`).

    Returns ``(angle, root)``: ``(T,)`` radians of the turn of every frame about the vertical axis
    through the root, counter-clockwise in the plane of :func:`~dancekit.motion.analysis.horizontal_axes`
    ``(a, b)``, and the root's new horizontal position ``(T, 2)`` on those axes, skeleton units.

    Inside ``radius_m`` metres of the start the dance is unchanged (up to the heading it already had to
    take). Beyond it, while the root moves outward, the whole figure turns about the vertical axis
    through its root (its travel direction with it) toward the start at up to ``turn_rate`` rad/s,
    eased in and out with a first-order lag of ``turn_time_s`` seconds (no sudden turns): a straight
    drift becomes a loop, as ballroom dancers travel and come back. Whatever the song's length the root
    never gets farther than ``hard_radius_m`` metres from its start: a step that would cross it loses
    its outward part.
    """
    p = np.array(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3 or len(p) == 0:
        raise ParameterError(f"contain_root_path needs (T, J, 3) positions, got shape {p.shape}")
    a, b = horizontal_axes(skeleton)
    root = p[:, skeleton.root, :][:, [a, b]].copy()  # (T, 2) skeleton units
    turner = RootPathTurner(root[0], unit_scale=float(skeleton.unit_scale), fps=fps, radius_m=radius_m,
                            turn_rate=turn_rate, turn_time_s=turn_time_s, hard_radius_m=hard_radius_m)
    steps = np.diff(root, axis=0)
    angle = np.zeros(len(p))
    new_root = np.empty_like(root)
    new_root[0] = turner.root
    d0, d1 = steps[:, 0].tolist(), steps[:, 1].tolist()
    for t in range(1, len(p)):
        new_root[t], angle[t] = turner.step_xy(d0[t - 1], d1[t - 1])
    return angle, new_root


class RootPathTurner:
    """The turns of :func:`root_path_turns` one step at a time (its state carried), for a motion that arrives
    frame by frame: :meth:`step` takes the root's next horizontal step ``(2,)`` (skeleton units, on the axes of
    :func:`~dancekit.motion.analysis.horizontal_axes`) and returns the root's new place ``(2,)`` and the turn
    (radians) of that frame. ``start``: the root's first place ``(2,)``; the other parameters as
    :func:`root_path_turns`'s (``unit_scale``: metres per skeleton unit).

    The arithmetic is on Python floats (the same IEEE operations, in the same order, as on arrays' elements;
    ``hypot`` and the dot products whose value is kept are NumPy's, a dot product only compared with 0 is NumPy's
    where its sign is within rounding)."""

    def __init__(self, start: np.ndarray, *, unit_scale: float, fps: float, radius_m: float = DEFAULT_RADIUS_M,
                 turn_rate: float = 0.5, turn_time_s: float = 0.5, hard_radius_m: float = DEFAULT_HARD_RADIUS_M):
        fps = check_fps(fps)
        if not (0 < radius_m <= hard_radius_m):
            raise ParameterError(f"need 0 < radius_m <= hard_radius_m, got {radius_m}, {hard_radius_m}")
        self.fps, self.turn_rate = fps, turn_rate
        self.start = np.array(start, dtype=np.float64)
        self._s0, self._s1 = float(self.start[0]), float(self.start[1])
        self._x, self._y = self._s0, self._s1  # the root's place after the last step
        self.R = radius_m / unit_scale
        self.H = hard_radius_m / unit_scale
        self.alpha = 1.0 - math.exp(-1.0 / (turn_time_s * fps)) if turn_time_s > 0 else 1.0
        self.theta, self.omega = 0.0, 0.0

    @property
    def root(self) -> np.ndarray:
        """The root's place after the last step ``(2,)``."""
        return np.array([self._x, self._y])

    def step(self, step: np.ndarray) -> tuple[np.ndarray, float]:
        """The root's next step ``(2,)`` in → its new place ``(2,)`` and the frame's turn (radians)."""
        nx, ny = self.step_xy(float(step[0]), float(step[1]))[0]
        return np.array([nx, ny]), self.theta

    def step_xy(self, v0: float, v1: float) -> tuple[tuple[float, float], float]:
        """:meth:`step` on Python floats: the step ``(v0, v1)`` → the new place ``(x, y)`` and the turn."""
        s0, s1, x, y = self._s0, self._s1, self._x, self._y
        c0, c1 = x - s0, y - s1
        co, si = math.cos(self.theta), math.sin(self.theta)
        st0, st1 = co * v0 - si * v1, si * v0 + co * v1  # the step turned by theta
        dist = float(np.hypot(c0, c1))
        target = 0.0
        if dist > self.R and _positive_dot(c0, c1, st0, st1):
            cross = c0 * st1 - c1 * st0  # > 0: the step points counter-clockwise of outward
            target = self.turn_rate if cross > 0 else -self.turn_rate  # so turning it further turns it back
        self.omega += self.alpha * (target - self.omega)
        self.theta += self.omega / self.fps
        co, si = math.cos(self.theta), math.sin(self.theta)
        st0, st1 = co * v0 - si * v1, si * v0 + co * v1
        nx, ny = x + st0, y + st1
        if np.hypot(nx - s0, ny - s1) > self.H:  # last resort: drop the outward part of the step
            prev, nxt, step = np.array([x, y]), np.array([nx, ny]), np.array([st0, st1])
            out = (nxt - self.start) / np.hypot(*(nxt - self.start))
            step = step - max(0.0, float(step @ out)) * out
            nx, ny = (float(v) for v in prev + step)
        self._x, self._y = nx, ny
        return (nx, ny), self.theta


def turn_and_move(positions: np.ndarray, *, skeleton: Skeleton, angle: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Every frame turned by ``angle`` ``(T,)`` about the vertical axis through its root and moved so the
    root is at ``root`` ``(T, 2)`` (see :func:`root_path_turns`): a new ``(T, J, 3)`` float64 array."""
    p = np.array(positions, dtype=np.float64)
    a, b = horizontal_axes(skeleton)
    rel = p[:, :, [a, b]] - p[:, skeleton.root, :][:, None, [a, b]]
    ca, sa = np.cos(angle)[:, None], np.sin(angle)[:, None]
    rx = ca * rel[..., 0] - sa * rel[..., 1]
    ry = sa * rel[..., 0] + ca * rel[..., 1]
    p[..., a] = rx + root[:, None, 0]
    p[..., b] = ry + root[:, None, 1]
    return p


def contain_root_path(
    positions: np.ndarray,
    *,
    skeleton: Skeleton,
    fps: float,
    radius_m: float = DEFAULT_RADIUS_M,
    turn_rate: float = 0.5,
    turn_time_s: float = 0.5,
    hard_radius_m: float = DEFAULT_HARD_RADIUS_M,
) -> np.ndarray:
    """Keep the root's horizontal path within a dance floor: a new ``(T, J, 3)`` float64 array (the turns
    of :func:`root_path_turns` applied by :func:`turn_and_move`)."""
    angle, root = root_path_turns(positions, skeleton=skeleton, fps=fps, radius_m=radius_m, turn_rate=turn_rate,
                                  turn_time_s=turn_time_s, hard_radius_m=hard_radius_m)
    return turn_and_move(positions, skeleton=skeleton, angle=angle, root=root)


def clean_up(
    positions: np.ndarray,
    *,
    skeleton: Skeleton,
    fps: float,
    ground: bool = True,
    contain: bool = True,
    radius_m: float = DEFAULT_RADIUS_M,
) -> np.ndarray:
    """:func:`contain_root_path` then :func:`ground_contact` (each switchable): ``(T, J, 3)`` float64."""
    p = np.asarray(positions, dtype=np.float64)
    if contain:
        p = contain_root_path(p, skeleton=skeleton, fps=fps, radius_m=radius_m)
    if ground:
        p = ground_contact(p, skeleton=skeleton, fps=fps)
    return p
