"""What both renderers share: validated, y-up metre positions, bones, sides and a camera path.

Conventions: the scene is in metres with ``+y`` up and the floor at ``y = 0``. A camera
at azimuth ``a`` and elevation ``e`` sits at ``target + d * (sin a cos e, sin e, cos a cos e)``
and looks at ``target``; image ``x`` points right and image ``y`` up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.filters import gaussian_filter1d, percentile_filter1d
from dancekit.render._motion import _CHUNK

#: rotation taking each supported up axis onto +y (right-handed, det = +1)
_TO_Y_UP = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    "x": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "-y": np.diag([1.0, -1.0, -1.0]),  # image space (rows grow downwards)
}

SIDE_LEFT, SIDE_CENTRE, SIDE_RIGHT = 1, 0, -1


@dataclass(frozen=True)
class Scene:
    """A motion ready to draw.

    Attributes
    ----------
    positions : np.ndarray, (T, J, 3) float32
        Joint positions in metres, ``+y`` up, the floor at ``y = 0``.
    bones : np.ndarray, (B, 2) int
        ``(child, parent)`` joint pairs.
    sides : np.ndarray, (J,) int8
        ``+1`` left, ``-1`` right, ``0`` centre (picks the colours).
    head : int or None
        Joint drawn as a head disc.
    fps : float
        Frames per second.
    target : np.ndarray, (T, 3) float32
        Camera look-at point per frame: the root's horizontal path smoothed without lag,
        at a constant height (the body's middle).
    height : float
        Typical standing height of the figure (metres).
    facing_azimuth : float or None
        Azimuth (radians) of the figure's average facing direction, None when unknown.
    """

    positions: np.ndarray
    bones: np.ndarray
    sides: np.ndarray
    head: int | None
    fps: float
    target: np.ndarray
    height: float
    facing_azimuth: float | None

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])


def prepare_scene(
    positions: np.ndarray,
    *,
    parents,
    fps: float,
    up_axis: str = "y",
    unit_scale: float = 0.01,
    sides=None,
    head: int | None = None,
    smooth_s: float = 0.5,
    follow_ground: bool = True,
) -> Scene:
    """Validate a motion and turn it into a :class:`Scene`.

    Parameters
    ----------
    positions : array-like, (T, J, 3)
        Joint positions in the skeleton's units.
    parents : array-like, (J,) int
        Parent of each joint, ``-1`` for a root.
    fps : float
        Frames per second.
    up_axis : {"y", "z", "x", "-y"}
        Which axis of ``positions`` points up (``"-y"``: image space, y grows downwards).
    unit_scale : float
        Metres per unit of ``positions`` (0.01 for centimetres).
    sides : array-like, (J,) or None
        ``+1`` left / ``-1`` right / ``0`` centre per joint; None draws all joints alike.
    head : int or None
        Index of a joint to draw as a head disc.
    smooth_s : float
        Standard deviation (seconds) of the Gaussian that smooths the camera path.
    follow_ground : bool
        Put the floor under the feet in every frame (see :func:`ground_level`); False
        keeps one floor height for the whole motion.

    Raises
    ------
    ParameterError
        On a bad shape, a non-finite value or an out-of-range index.
    """
    fps = check_fps(fps)
    pos = np.asarray(positions)
    if pos.ndim != 3 or pos.shape[-1] != 3:
        raise ParameterError(f"positions must have shape (T, J, 3), got {pos.shape}")
    T, J, _ = pos.shape
    if T < 1 or J < 1:
        raise ParameterError(f"positions must hold at least one frame and one joint, got {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise ParameterError("positions contain NaN or infinite values")
    par = np.asarray(parents)
    if par.shape != (J,) or not np.issubdtype(par.dtype, np.integer):
        raise ParameterError(f"parents must be {J} integers (one per joint), got {par!r}")
    if np.any(par < -1) or np.any(par >= J) or np.any(par == np.arange(J)):
        raise ParameterError(f"parents must index joints 0..{J - 1} (or -1 for a root), got {par.tolist()}")
    roots = np.flatnonzero(par < 0)
    if roots.size == 0:
        raise ParameterError("parents has no root (no joint with parent -1)")
    if up_axis not in _TO_Y_UP:
        raise ParameterError(f"up_axis must be one of {sorted(_TO_Y_UP)}, got {up_axis!r}")
    try:
        scale = float(unit_scale)
    except (TypeError, ValueError):
        raise ParameterError(
            f"unit_scale must be a positive number (metres per unit), got {unit_scale!r}"
        ) from None
    if not math.isfinite(scale) or scale <= 0:
        raise ParameterError(f"unit_scale must be a positive number (metres per unit), got {unit_scale!r}")
    if sides is None:
        side = np.zeros(J, np.int8)
    else:
        side = np.sign(np.asarray(sides, dtype=np.int64)).astype(np.int8)
        if side.shape != (J,):
            raise ParameterError(f"sides must hold one value per joint ({J}), got shape {side.shape}")
    if head is not None and not (0 <= int(head) < J):
        raise ParameterError(f"head must be a joint index in 0..{J - 1}, got {head!r}")

    p = np.empty(pos.shape, np.float64)  # (T, J, 3) metres, y up; per frame, 4,096 frames at a time
    for a in range(0, T, _CHUNK):
        p[a: a + _CHUNK] = (pos[a: a + _CHUNK].astype(np.float64) * scale) @ _TO_Y_UP[up_axis].T
    p[:, :, 1] -= ground_level(p[:, :, 1].min(axis=1), fps=fps, follow=follow_ground)[:, None]
    height = float(np.percentile(p[:, :, 1].max(axis=1), 50))
    height = max(height, 0.1)

    root = int(roots[0])
    sigma = max(smooth_s * fps, 1e-6)
    path = p[:, root, :].copy()
    if T > 1:
        path[:, 0] = gaussian_filter1d(path[:, 0], sigma)
        path[:, 2] = gaussian_filter1d(path[:, 2], sigma)
    mid = np.median(0.5 * (p[:, :, 1].max(axis=1) + np.maximum(p[:, :, 1].min(axis=1), 0.0)))
    path[:, 1] = mid

    facing = None
    if np.any(side > 0) and np.any(side < 0):
        left = p[:, side > 0].mean(axis=1) - p[:, side < 0].mean(axis=1)  # (T, 3)
        fwd = np.stack([-left[:, 2], np.zeros(T), left[:, 0]], axis=1)  # left x up: facing direction
        norm = np.linalg.norm(fwd, axis=1, keepdims=True)
        fwd = np.divide(fwd, norm, out=np.zeros_like(fwd), where=norm > 1e-9)
        mean = fwd.mean(axis=0)
        if np.hypot(mean[0], mean[2]) > 0.3:
            facing = float(math.atan2(mean[0], mean[2]))

    bones = np.array([(j, int(par[j])) for j in range(J) if par[j] >= 0], dtype=np.int64).reshape(-1, 2)
    return Scene(
        positions=p.astype(np.float32),
        bones=bones,
        sides=side,
        head=None if head is None else int(head),
        fps=fps,
        target=path.astype(np.float32),
        height=height,
        facing_azimuth=facing,
    )


def ground_level(lowest: np.ndarray, *, fps: float, follow: bool = True, window_s: float = 3.0) -> np.ndarray:
    """Floor height per frame ``(T,)`` from the height of the lowest joint per frame ``(T,)``.

    Motion capture often drifts vertically (in tang2018 the feet of some dances rise by
    up to 0.5 m over a song), which would make a figure float above a fixed floor. With
    ``follow`` the floor is the 10th percentile of the lowest joint over a sliding
    ``window_s`` window, smoothed (sigma 0.5 s): slow drift is removed while jumps
    (shorter than the window) still leave the floor. Without ``follow`` it is the 5th
    percentile over the whole motion.
    """
    if not follow or lowest.shape[0] < 3:
        return np.full(lowest.shape, np.percentile(lowest, 5))
    size = max(3, int(round(window_s * fps)) | 1)
    level = percentile_filter1d(lowest, 10, size)
    return gaussian_filter1d(level, 0.5 * fps)


def default_azimuth(scene: Scene, *, offset: float = 30.0) -> float:
    """Camera azimuth in degrees: ``offset`` degrees beside the figure's average front
    (a three-quarter view), or ``offset`` itself when the front is unknown."""
    if scene.facing_azimuth is None:
        return float(offset)
    return float(math.degrees(scene.facing_azimuth) + offset)


def camera_basis(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-space ``(right, up, forward)`` unit vectors of a camera (angles in radians)."""
    ce, se = math.cos(elevation), math.sin(elevation)
    fwd = np.array([-ce * math.sin(azimuth), -se, -ce * math.cos(azimuth)])
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    return right, up, fwd


def fit_distance(scene: Scene, basis, *, tan_half_x: float, tan_half_y: float, margin: float = 0.88) -> float:
    """Smallest camera distance that keeps every joint of every frame inside the image.

    A point at ``rel = p - target`` has camera coordinates ``(rel.right, rel.up, rel.fwd + d)``
    and is inside when ``|x| <= margin * tan_half_x * z`` (same for y), which is linear in ``d``.
    """
    right, up, fwd = basis
    most = -np.inf
    for a in range(0, scene.num_frames, _CHUNK):  # per frame: a chunk at a time, the same maximum
        rel = scene.positions[a: a + _CHUNK] - scene.target[a: a + _CHUNK, None, :]  # (n, J, 3)
        x = np.abs(rel @ right)
        y = np.abs(rel @ up)
        z = rel @ fwd
        most = max(most, float((np.maximum(x / (margin * tan_half_x), y / (margin * tan_half_y)) - z).max()))
    return float(max(most, 0.5 * scene.height, 0.5))
