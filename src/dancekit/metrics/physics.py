"""Physical plausibility: foot skating, PFC, bone-length variation, ground penetration, torso lean.

Heights are measured along the skeleton's up axis above a ``floor`` height given in
skeleton units (0 by default: prepared datasets put the floor at 0). Thresholds are in
metres and metres per second (converted through ``skeleton.unit_scale``).

Foot skating
    For every foot joint (``skeleton.feet`` by default) and frame, the foot is *in contact*
    when it is at most ``contact_height`` (0.05 m) above the floor (by default a *local*
    floor: the lowest foot joint within ±1 s, since motion capture drifts vertically) and
    its speed is below
    ``contact_speed`` (1.0 m/s; a foot sweeping past the floor faster than that is swinging,
    not planted). A contact frame *skates* when the foot's horizontal speed exceeds
    ``slide_speed`` (0.25 m/s, i.e. 1 cm per frame at 25 fps). The skating ratio is
    skating frames / contact frames, pooled over foot joints.

PFC (physical foot contact, EDGE, Tseng et al. 2023)
    ``mean_t( min(v_l_ankle, v_l_toe) · min(v_r_ankle, v_r_toe) · â_t ) · 10⁴`` where ``v``
    is a foot's horizontal speed and ``â`` is the root's acceleration with its upward
    component clamped at 0, normalised by its maximum over the dance. EDGE measures foot
    speed in metres per frame at 30 fps; here speeds are in m/s times 1/30 s, which equals
    EDGE's numbers at 30 fps and does not depend on the frame rate otherwise.

Bone-length variation
    Per bone (parent → child), std / mean of its length over frames; the mean over bones
    (and the worst bone). Real motion capture has near-constant bones; generated positions
    often do not.

Ground penetration
    Per frame, the depth of the lowest joint below the floor (0 if above). Reported as the
    mean depth (m), the maximum depth (m) and the share of frames deeper than ``tolerance``
    (0.01 m).

Torso lean
    Per frame, the angle (degrees) between the up axis and the torso: the pelvis to the
    midpoint of the shoulders. Reported as the median and the 90th percentile over frames.
    It is compared with the real dances' value, not with 0: real tang2018 dances read 6-20
    degrees per dance (median 19) with this skeleton's pelvis joint. A generated body that tips
    over shows here (the foot and height metrics do not: the dual-learning model's dances,
    decoded by Gram-Schmidt, read 35-48 degrees; docs/DUAL.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from dancekit.errors import ParameterError
from dancekit.metrics._common import check_fps, check_positions, joint, root_index, to_metres
from dancekit.motion.analysis import floor_curve, heights, horizontal_axes, up_sign

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

__all__ = ["bone_length_variation", "foot_skating", "ground_penetration", "pfc", "torso_lean"]


def _foot_names(skeleton: Skeleton, feet: Sequence[str] | None) -> list[str]:
    names = list(feet) if feet is not None else list(skeleton.feet)
    if not names:
        names = [r for r in ("left_ankle", "right_ankle", "left_toe", "right_toe") if skeleton.has(r)]
    if not names:
        raise ParameterError(f"skeleton {skeleton.name!r} names no foot joints; pass feet=[...]")
    for n in names:
        joint(skeleton, n)  # a clear error for a missing joint
    return names


def foot_skating(
    positions: np.ndarray,
    *,
    fps: float,
    skeleton: Skeleton,
    floor: float | str = "local",
    floor_window: float = 2.0,
    contact_height: float = 0.05,
    contact_speed: float = 1.0,
    slide_speed: float = 0.25,
    feet: Sequence[str] | None = None,
) -> dict[str, float]:
    """Foot-skating ratio of one dance (see the module docstring for the definition).

    Parameters
    ----------
    positions : (T, J, 3) world positions in skeleton units
    fps : frames per second
    skeleton : gives the up axis, the units and the foot joints
    floor : floor height in skeleton units, or ``"local"``: per frame, the lowest foot-joint
        height within a centred window of ``floor_window`` seconds (robust to the slow
        vertical drift of motion capture, ~30 cm over a tang2018 dance)
    contact_height, contact_speed, slide_speed : thresholds in m and m/s
    feet : joint names or roles to test (default ``skeleton.feet``)

    Returns
    -------
    dict: ``ratio`` (skating / contact frames, NaN without contact), ``contact_share``
    (contact frames / all foot frames) and ``slide_speed_mean`` (m/s, mean horizontal speed
    of the skating frames, 0 if none).
    """
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=2), skeleton)
    names = _foot_names(skeleton, feet)
    h = list(horizontal_axes(skeleton))
    f = p[:, [skeleton.index(n) for n in names]]  # (T, F, 3)
    vel = np.gradient(f, axis=0) * fps
    height = heights(f, skeleton)  # (T, F) metres
    if isinstance(floor, str):
        if floor != "local":
            raise ParameterError(f"floor must be a height in skeleton units or 'local', got {floor!r}")
        # the running minimum of the lowest foot (metres along the up axis)
        local = floor_curve(p, skeleton, fps=fps, window_s=floor_window, percentile=0.0, smooth_s=0.0, feet=names)
        height = height - up_sign(skeleton) * local[:, None]
    else:
        height = height - float(floor) * skeleton.unit_scale
    speed = np.linalg.norm(vel, axis=-1)
    hspeed = np.linalg.norm(vel[..., h], axis=-1)
    contact = (height <= contact_height) & (speed < contact_speed)
    skate = contact & (hspeed > slide_speed)
    n_contact = int(contact.sum())
    return {
        "ratio": float(skate.sum() / n_contact) if n_contact else float("nan"),
        "contact_share": float(contact.mean()),
        "slide_speed_mean": float(hspeed[skate].mean()) if skate.any() else 0.0,
    }


def pfc(positions: np.ndarray, *, fps: float, skeleton: Skeleton) -> float:
    """EDGE's physical foot contact score of one dance (lower is better; see the module docstring).

    Needs the roles left/right ankle and toe (the ankle stands in for a missing toe).
    Returns 0 for a dance whose root never accelerates.
    """
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=3), skeleton)
    up = skeleton.up_index
    h = list(horizontal_axes(skeleton))
    dt = 1.0 / fps
    root = p[:, root_index(skeleton)]
    root_v = np.diff(root, axis=0) / dt
    root_a = np.diff(root_v, axis=0) / dt  # (T-2, 3)
    root_a[:, up] = np.maximum(root_a[:, up] * up_sign(skeleton), 0.0)
    a = np.linalg.norm(root_a, axis=-1)
    if a.max() <= 0:
        return 0.0
    a = a / a.max()

    def foot_speed(side: str) -> np.ndarray:
        js = [joint(skeleton, f"{side}_ankle")]
        if skeleton.has(f"{side}_toe"):
            js.append(joint(skeleton, f"{side}_toe"))
        f = p[:, js][:, :, h]  # (T, k, 2)
        v = np.linalg.norm(f[2:] - f[1:-1], axis=-1) / dt * (1.0 / 30.0)  # EDGE: metres per 1/30 s
        return v.min(axis=1)  # (T-2,)

    return float(np.mean(foot_speed("left") * foot_speed("right") * a) * 1e4)


def bone_length_variation(positions: np.ndarray, *, skeleton: Skeleton) -> dict[str, float]:
    """Bone-length variation (std / mean over frames per bone): ``mean`` and ``max`` over bones."""
    p = check_positions(positions, skeleton, min_frames=1)
    ratios = []
    for j, parent in enumerate(skeleton.parents):
        if parent is None or parent < 0:
            continue
        length = np.linalg.norm(p[:, j] - p[:, parent], axis=-1)
        mean = length.mean()
        if mean > 0:
            ratios.append(length.std() / mean)
    if not ratios:
        raise ParameterError(f"skeleton {skeleton.name!r} has no bone of non-zero length")
    r = np.asarray(ratios)
    return {"mean": float(r.mean()), "max": float(r.max())}


def ground_penetration(
    positions: np.ndarray, *, skeleton: Skeleton, floor: float = 0.0, tolerance: float = 0.01
) -> dict[str, float]:
    """How far the body sinks below the floor: ``mean_depth`` and ``max_depth`` (m), ``frame_share``."""
    p = to_metres(check_positions(positions, skeleton, min_frames=1), skeleton)
    lowest = heights(p, skeleton).min(axis=1) - floor * skeleton.unit_scale
    depth = np.maximum(-lowest, 0.0)
    return {
        "mean_depth": float(depth.mean()),
        "max_depth": float(depth.max()),
        "frame_share": float(np.mean(depth > tolerance)),
    }


def torso_lean(positions: np.ndarray, *, skeleton: Skeleton) -> dict[str, float]:
    """How far the torso leans from the vertical, in degrees: ``median_deg`` and ``p90_deg`` over frames.

    positions : (T, J, 3) world joint positions in skeleton units; the torso is the pelvis (root) to the
        midpoint of the ``left_shoulder`` and ``right_shoulder`` roles; 0 degrees = upright, 90 = lying.
    """
    p = np.asarray(check_positions(positions, skeleton, min_frames=1), np.float64)
    mid = 0.5 * (p[:, joint(skeleton, "left_shoulder")] + p[:, joint(skeleton, "right_shoulder")])
    v = mid - p[:, root_index(skeleton)]
    n = np.linalg.norm(v, axis=-1)
    if not np.all(n > 0):
        raise ParameterError("torso lean: the shoulders' midpoint coincides with the pelvis in some frame")
    cos = up_sign(skeleton) * v[:, skeleton.up_index] / n
    deg = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return {"median_deg": float(np.median(deg)), "p90_deg": float(np.percentile(deg, 90))}
