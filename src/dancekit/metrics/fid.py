"""The AIST++ benchmark: FID_k, FID_g, Div_k, Div_g, and the Fréchet distance itself.

Kinetic features (FID_k)
    Per joint, over frames ``i = 1 .. T-1`` (frame time ``dt = 1 / fps``):

    * mean horizontal kinetic energy ``mean_i |v_i^h|^2`` and mean vertical kinetic energy
      ``mean_i (v_i^up)^2``, where ``v_i`` is the joint velocity averaged over the frame
      differences ``p[k] - p[k-1]`` with ``k`` in ``[i - w, i + w]`` (``w = 2``, clipped to
      the sequence) divided by ``dt``;
    * mean energy expenditure ``mean_i |a_i|``, where ``a_i`` averages the accelerations
      ``(p[m+1] - 2 p[m] + p[m-1]) / dt^2`` with ``m`` in ``[i - w, i + w]`` (clipped).

    Positions are in metres (through ``skeleton.unit_scale``) so the features are in m²/s² and
    m/s² whatever the units of the data; the vector is ``[KE_h, KE_v, EE]`` for joint 0, then
    joint 1, ... (3J values, 72 for 24 joints).

    ``bug_compatible=True`` reproduces the public reference implementation, whose
    acceleration term reads ``v1 = (p[m] - p[m-1] / frame_time)`` (the parenthesis closes
    after the division, so ``v1`` mixes a position with a velocity and depends on where the
    dancer stands). As there, positions are first shifted so the root of frame 0 is at the
    origin. Only the energy-expenditure columns change.

Geometric features (FID_g)
    The 32 boolean relational features of Müller et al. (2005) in the selection used by the
    AIST++ / Bailando evaluation code, evaluated on frames ``1 .. T-1`` and averaged over
    frames (so each value is the fraction of frames where the relation holds). Joints are
    taken through the skeleton's canonical roles; ``belly`` is the pelvis and ``chest`` the
    midpoint of pelvis and neck (tang2018 has no spine joints), the neck is the midpoint of the
    shoulders when the skeleton has no neck role (tang2018) and a missing toe role falls back
    to the ankle. Distances are measured in
    units of the body: ``hl`` (humerus: left shoulder to left elbow), ``sw`` (shoulder
    width) and ``hw`` (hip width), read from the skeleton's rest pose (or, when its offsets
    are all zero, the median over the frames), in metres. Velocities use the true frame
    time ``1 / fps``; ``bug_compatible=True`` uses the reference's fixed ``1 / 120`` s
    (correct only for 120 fps data; AIST++ is 60 fps). As in the reference, ``f_move``
    projects the velocity of its third joint relative to its first onto the first → second
    direction (its fourth joint is unused), so features 4 and 5 coincide.
    See :data:`GEOMETRIC_FEATURE_NAMES` for the list.

Normalisation, FID and diversity
    Features of both sets are z-scored with the mean and standard deviation of the
    reference set. Columns whose reference standard deviation is below ``min_std`` carry
    no information and are dropped from both sets (the count is reported). FID is the
    Fréchet distance between Gaussians fitted to the two normalised sets; Div is the mean
    Euclidean distance over all pairs of normalised feature vectors of one set.

Fréchet distance and the imaginary part of sqrtm (policy)
    ``d² = |mu1 - mu2|² + tr(S1) + tr(S2) - 2 tr(sqrtm(S1 S2))``. ``scipy.linalg.sqrtm`` of
    the product of two covariance matrices can return a complex matrix or non-finite values
    when the product is (nearly) singular, which is the rule with fewer samples than feature
    dimensions. Policy: (1) if the result is finite and its largest imaginary magnitude is
    at most ``imag_tol`` times its largest real magnitude, the imaginary part is discarded;
    (2) otherwise ``eps * I`` (``eps`` relative to the mean variance) is added to both
    covariances and sqrtm is recomputed once; (3) if the imaginary part is still large it is
    discarded and a warning is issued. What happened is returned in ``info`` (``offset``,
    ``max_imag``, ``retried``) so a report can show it.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy import linalg

from dancekit.errors import ParameterError
from dancekit.metrics._common import (
    check_fps,
    check_positions,
    joint,
    root_index,
    to_metres,
    y_up,
)
from dancekit.motion.analysis import horizontal_axes, rest_pose

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

__all__ = [
    "GEOMETRIC_FEATURE_NAMES",
    "average_pairwise_distance",
    "body_dimensions",
    "feature_sets",
    "fid_diversity",
    "frechet_distance",
    "frechet_distance_from_stats",
    "feature_names",
    "fid_breakdown",
    "geometric_features",
    "kinetic_features",
    "normalize_features",
    "segments",
]

# ---------------------------------------------------------------------------------------------
# Fréchet distance


def frechet_distance_from_stats(
    mu1: np.ndarray,
    sigma1: np.ndarray,
    mu2: np.ndarray,
    sigma2: np.ndarray,
    *,
    eps: float = 1e-6,
    imag_tol: float = 1e-3,
    return_info: bool = False,
) -> float | tuple[float, dict]:
    """Fréchet distance between N(mu1, sigma1) and N(mu2, sigma2).

    Parameters
    ----------
    mu1, mu2 : (D,) means
    sigma1, sigma2 : (D, D) covariances
    eps : diagonal offset (relative to the mean variance) added when sqrtm fails the check
    imag_tol : largest imaginary magnitude of sqrtm, relative to its largest real magnitude,
        that is discarded silently (see the module docstring for the full policy)
    return_info : also return ``{"offset", "max_imag", "retried"}``

    Returns
    -------
    float (and the info dict): the squared Fréchet distance, clipped at 0 (it is a sum of
    squares, but rounding can make it slightly negative).
    """
    mu1, mu2 = np.atleast_1d(np.asarray(mu1, np.float64)), np.atleast_1d(np.asarray(mu2, np.float64))
    s1, s2 = np.atleast_2d(np.asarray(sigma1, np.float64)), np.atleast_2d(np.asarray(sigma2, np.float64))
    if mu1.shape != mu2.shape or s1.shape != s2.shape or s1.shape != (mu1.size, mu1.size):
        raise ParameterError(
            f"Fréchet distance: shapes do not match: mu {mu1.shape} / {mu2.shape}, sigma {s1.shape} / {s2.shape}"
        )
    if not (np.isfinite(mu1).all() and np.isfinite(mu2).all() and np.isfinite(s1).all() and np.isfinite(s2).all()):
        raise ParameterError("Fréchet distance: means or covariances contain NaN or inf")

    def _sqrtm(a: np.ndarray) -> tuple[np.ndarray, float, bool]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = linalg.sqrtm(a)
        out = np.asarray(out)
        finite = bool(np.isfinite(out).all())
        if not finite:
            return out, float("inf"), False
        imag = float(np.abs(out.imag).max()) if np.iscomplexobj(out) else 0.0
        scale = max(float(np.abs(out.real).max()), 1e-300)
        return out, imag, imag <= imag_tol * scale

    info = {"offset": 0.0, "max_imag": 0.0, "retried": False}
    covmean, imag, ok = _sqrtm(s1 @ s2)
    info["max_imag"] = imag
    if not ok:
        mean_var = max(float(np.trace(s1) + np.trace(s2)) / (2 * len(s1)), 1e-12)
        offset = eps * mean_var
        eye = np.eye(len(s1)) * offset
        covmean, imag, ok = _sqrtm((s1 + eye) @ (s2 + eye))
        info.update(offset=offset, max_imag=imag, retried=True)
        if not np.isfinite(covmean).all():
            raise ParameterError("Fréchet distance: sqrtm is not finite even after adding eps * I to the covariances")
        if not ok:
            warnings.warn(
                f"Fréchet distance: sqrtm has an imaginary part of {imag:.3g} after adding {offset:.3g} * I; "
                "it is discarded",
                RuntimeWarning,
                stacklevel=2,
            )
    covmean = np.real(covmean)
    diff = mu1 - mu2
    value = float(diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean))
    value = max(value, 0.0)
    return (value, info) if return_info else value


def frechet_distance(
    x: np.ndarray, y: np.ndarray, *, eps: float = 1e-6, imag_tol: float = 1e-3, return_info: bool = False
) -> float | tuple[float, dict]:
    """Fréchet distance between Gaussians fitted to two sample sets ``x (N, D)`` and ``y (M, D)``.

    Means and (unbiased) covariances are estimated from the samples; see
    :func:`frechet_distance_from_stats` for the sqrtm policy.

    Raises
    ------
    ParameterError
        If either set has fewer than 2 samples or the dimensions differ.

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(size=(100, 4))
    >>> round(frechet_distance(x, x), 6)
    0.0
    """
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if x.ndim != 2 or y.ndim != 2 or x.shape[1] != y.shape[1]:
        raise ParameterError(f"Fréchet distance needs two (N, D) arrays of the same D, got {x.shape} and {y.shape}")
    if len(x) < 2 or len(y) < 2:
        raise ParameterError(f"Fréchet distance needs at least 2 samples per set, got {len(x)} and {len(y)}")
    s1 = np.atleast_2d(np.cov(x, rowvar=False))
    s2 = np.atleast_2d(np.cov(y, rowvar=False))
    return frechet_distance_from_stats(
        x.mean(0), s1, y.mean(0), s2, eps=eps, imag_tol=imag_tol, return_info=return_info
    )


# ---------------------------------------------------------------------------------------------
# kinetic features


def _window_means(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Mean of rows ``x[lo_i .. hi_i]`` (inclusive) for every i; ``x`` is (N, ...)."""
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)], axis=0)
    count = (hi - lo + 1).reshape((-1,) + (1,) * (x.ndim - 1))
    return (c[hi + 1] - c[lo]) / count


def kinetic_features(
    positions: np.ndarray,
    *,
    fps: float,
    skeleton: Skeleton,
    window: int = 2,
    bug_compatible: bool = False,
) -> np.ndarray:
    """AIST++ kinetic features of one dance.

    Parameters
    ----------
    positions : (T, J, 3) world joint positions in skeleton units, ``T >= 3``
    fps : frames per second of ``positions``
    skeleton : gives ``up_axis``, ``unit_scale`` and the root joint
    window : half-width ``w`` of the averaging window, in frames (2 in AIST++)
    bug_compatible : reproduce the reference's acceleration parenthesis bug (see module docstring)

    Returns
    -------
    (3J,) float64: ``[KE_h (m²/s²), KE_v (m²/s²), EE (m/s²)]`` per joint, joint-major.
    """
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=3), skeleton)
    if int(window) < 1:
        raise ParameterError(f"kinetic feature window must be >= 1 frame, got {window}")
    w = int(window)
    r = root_index(skeleton)
    p = p - p[0:1, r : r + 1, :]  # the reference works on positions relative to the first root
    T = len(p)
    dt = 1.0 / fps
    up = skeleton.up_index
    h = list(horizontal_axes(skeleton))

    i = np.arange(1, T)
    # velocities: frame differences d[k-1] = p[k] - p[k-1], k in [max(1, i-w), min(T-1, i+w)]
    d = np.diff(p, axis=0)  # (T-1, J, 3)
    lo = np.maximum(1, i - w) - 1
    hi = np.minimum(T - 1, i + w) - 1
    v = _window_means(d, lo, hi) / dt  # (T-1, J, 3)
    ke_h = np.mean(np.sum(v[..., h] ** 2, axis=-1), axis=0)  # (J,)
    ke_v = np.mean(v[..., up] ** 2, axis=0)

    # accelerations at m = 1 .. T-2, averaged over m in [max(1, i-w), min(T-2, i+w)]
    if bug_compatible:
        v2 = (p[2:] - p[1:-1]) / dt
        v1 = p[1:-1] - p[:-2] / dt  # sic: the reference's misplaced parenthesis
        acc = (v2 - v1) / dt
    else:
        acc = (p[2:] - 2.0 * p[1:-1] + p[:-2]) / dt**2  # (T-2, J, 3), row m-1 is frame m
    lo = np.maximum(1, i - w) - 1
    hi = np.minimum(T - 2, i + w) - 1
    a = _window_means(acc, lo, hi)  # (T-1, J, 3)
    ee = np.mean(np.linalg.norm(a, axis=-1), axis=0)
    return np.stack([ke_h, ke_v, ee], axis=1).reshape(-1)


# ---------------------------------------------------------------------------------------------
# geometric (Müller) features

# (kind, joints, threshold): thresholds are (multiplier, body dimension) or an angle range.
# kinds: nmove (velocity of j4 rel. j1 along the normal of plane j1 j2 j3), nplane (j4 beyond the
# plane through j3 with normal j1 -> j2), move (velocity of j3 rel. j1 along j1 -> j2), angle
# (angle between j1 -> j2 and j3 -> j4 strictly inside the range, degrees), plane (j4 beyond the
# plane j1 j2 j3, normal (j3 - j1) x (j2 - j1)), fast (speed of j1).
_GEOMETRIC = [
    ("r_hand_moving_forward", "nmove", ("neck", "right_hip", "left_hip", "right_wrist"), (1.8, "hl")),
    ("l_hand_moving_forward", "nmove", ("neck", "left_hip", "right_hip", "left_wrist"), (1.8, "hl")),
    ("r_hand_above_neck", "nplane", ("chest", "neck", "neck", "right_wrist"), (0.2, "hl")),
    ("l_hand_above_neck", "nplane", ("chest", "neck", "neck", "left_wrist"), (0.2, "hl")),
    ("chest_moving_up_r", "move", ("belly", "chest", "chest", "right_wrist"), (1.8, "hl")),
    ("chest_moving_up_l", "move", ("belly", "chest", "chest", "left_wrist"), (1.8, "hl")),
    ("r_elbow_bent", "angle", ("right_elbow", "right_shoulder", "right_elbow", "right_wrist"), (0.0, 110.0)),
    ("l_elbow_bent", "angle", ("left_elbow", "left_shoulder", "left_elbow", "left_wrist"), (0.0, 110.0)),
    ("hands_far_apart", "nplane", ("left_shoulder", "right_shoulder", "left_wrist", "right_wrist"), (2.5, "sw")),
    ("hands_separating", "move", ("left_wrist", "right_wrist", "right_wrist", "left_wrist"), (1.4, "hl")),
    ("l_hand_moving_rel_r_to_root", "move", ("right_wrist", "root", "left_wrist", "root"), (1.4, "hl")),
    ("r_hand_moving_rel_l_to_root", "move", ("left_wrist", "root", "right_wrist", "root"), (1.4, "hl")),
    ("r_hand_fast", "fast", ("right_wrist",), (2.5, "hl")),
    ("l_hand_fast", "fast", ("left_wrist",), (2.5, "hl")),
    ("r_foot_in_front", "plane", ("root", "left_hip", "left_toe", "right_ankle"), (0.38, "hl")),
    ("l_foot_in_front", "plane", ("root", "right_hip", "right_toe", "left_ankle"), (0.38, "hl")),
    ("r_foot_raised", "nplane", ("zero", "y_unit", "y_min", "right_ankle"), (1.2, "hl")),
    ("l_foot_raised", "nplane", ("zero", "y_unit", "y_min", "left_ankle"), (1.2, "hl")),
    ("feet_far_apart", "nplane", ("left_hip", "right_hip", "left_ankle", "right_ankle"), (2.1, "hw")),
    ("r_knee_bent", "angle", ("right_knee", "right_hip", "right_knee", "right_ankle"), (0.0, 110.0)),
    ("l_knee_bent", "angle", ("left_knee", "left_hip", "left_knee", "left_ankle"), (0.0, 110.0)),
    ("r_foot_fast", "fast", ("right_ankle",), (2.5, "hl")),
    ("l_foot_fast", "fast", ("left_ankle",), (2.5, "hl")),
    ("r_arm_raised", "angle", ("neck", "root", "right_shoulder", "right_elbow"), (25.0, 180.0)),
    ("l_arm_raised", "angle", ("neck", "root", "left_shoulder", "left_elbow"), (25.0, 180.0)),
    ("r_leg_raised", "angle", ("neck", "root", "right_hip", "right_knee"), (50.0, 180.0)),
    ("l_leg_raised", "angle", ("neck", "root", "left_hip", "left_knee"), (50.0, 180.0)),
    ("root_behind_feet", "plane", ("right_ankle", "neck", "left_ankle", "root"), (0.5, "hl")),
    ("torso_horizontal", "angle", ("neck", "root", "zero", "y_unit"), (70.0, 110.0)),
    ("r_hand_low", "nplane", ("zero", "minus_y_unit", "y_min", "right_wrist"), (-1.2, "hl")),
    ("l_hand_low", "nplane", ("zero", "minus_y_unit", "y_min", "left_wrist"), (-1.2, "hl")),
    ("root_fast", "fast", ("root",), (2.3, "hl")),
]

#: Names of the 32 geometric features, in the order of :func:`geometric_features`.
GEOMETRIC_FEATURE_NAMES: tuple[str, ...] = tuple(name for name, _, _, _ in _GEOMETRIC)

_ROLES = (
    "neck",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)


def body_dimensions(skeleton: Skeleton, positions: np.ndarray | None = None) -> dict[str, float]:
    """Humerus length ``hl``, shoulder width ``sw`` and hip width ``hw`` in metres.

    Measured on the skeleton's rest pose (forward kinematics of its offsets); when the
    offsets are all zero, the median over the frames of ``positions`` (skeleton units) is used.
    """
    pairs = {
        "hl": ("left_shoulder", "left_elbow"),
        "sw": ("left_shoulder", "right_shoulder"),
        "hw": ("left_hip", "right_hip"),
    }
    rest = rest_pose(skeleton) if np.any(skeleton.offsets) else None
    out = {}
    for key, (a, b) in pairs.items():
        ia, ib = joint(skeleton, a), joint(skeleton, b)
        if rest is not None and np.linalg.norm(rest[ia] - rest[ib]) > 0:
            value = float(np.linalg.norm(rest[ia] - rest[ib]))
        elif positions is not None:
            value = float(np.median(np.linalg.norm(positions[:, ia] - positions[:, ib], axis=-1)))
        else:
            raise ParameterError(f"skeleton {skeleton.name!r} has no rest pose; pass positions to measure {key}")
        out[key] = value * skeleton.unit_scale
    return out


def _role_positions(p: np.ndarray, skeleton: Skeleton) -> dict[str, np.ndarray]:
    """(T, 3) trajectories of every joint name the feature table uses (p in metres, y up)."""
    out = {role: p[:, joint(skeleton, role)] for role in _ROLES if role != "neck"}
    # tang2018 has no neck joint (it is virtual there): the midpoint of the shoulders stands in
    if skeleton.has("neck"):
        out["neck"] = p[:, joint(skeleton, "neck")]
    else:
        out["neck"] = 0.5 * (out["left_shoulder"] + out["right_shoulder"])
    out["root"] = p[:, root_index(skeleton)]
    for side in ("left", "right"):
        toe = f"{side}_toe"
        out[toe] = p[:, joint(skeleton, toe)] if skeleton.has(toe) else out[f"{side}_ankle"]
    out["belly"] = out["root"]
    out["chest"] = 0.5 * (out["root"] + out["neck"])
    T = len(p)
    out["zero"] = np.zeros((T, 3))
    out["y_unit"] = np.tile([0.0, 1.0, 0.0], (T, 1))
    out["minus_y_unit"] = np.tile([0.0, -1.0, 0.0], (T, 1))
    y_min = np.zeros((T, 3))
    y_min[:, 1] = p[:, :, 1].min(axis=1)
    out["y_min"] = y_min
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def geometric_features(
    positions: np.ndarray,
    *,
    fps: float,
    skeleton: Skeleton,
    bug_compatible: bool = False,
    per_frame: bool = False,
) -> np.ndarray:
    """AIST++ geometric (Müller relational) features of one dance.

    Parameters
    ----------
    positions : (T, J, 3) world joint positions in skeleton units, ``T >= 2``
    fps : frames per second
    skeleton : needs the canonical roles neck, left/right shoulder, elbow, wrist, hip, knee,
        ankle (toe optional: the ankle stands in), plus ``up_axis`` and ``unit_scale``
    bug_compatible : use the reference's fixed frame time of 1/120 s for velocities
    per_frame : return the boolean features per frame ``(T-1, 32)`` instead of their mean

    Returns
    -------
    (32,) float64 in [0, 1]: the fraction of frames 1 .. T-1 where each relation holds
    (names in :data:`GEOMETRIC_FEATURE_NAMES`).
    """
    fps = check_fps(fps)
    raw = check_positions(positions, skeleton, min_frames=2)
    p = y_up(to_metres(raw, skeleton), skeleton)
    dims = body_dimensions(skeleton, raw)
    frame_time = 1.0 / 120.0 if bug_compatible else 1.0 / fps
    pos = _role_positions(p, skeleton)
    cur = {k: v[1:] for k, v in pos.items()}
    prev = {k: v[:-1] for k, v in pos.items()}

    cols = []
    with np.errstate(invalid="ignore", divide="ignore"):
        for _, kind, js, thr in _GEOMETRIC:
            if kind == "angle":
                lo, hi = thr
                a = _unit(cur[js[1]] - cur[js[0]])
                b = _unit(cur[js[3]] - cur[js[2]])
                ang = np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))
                cols.append((ang > lo) & (ang < hi))
                continue
            threshold = thr[0] * dims[thr[1]]
            if kind == "fast":
                speed = np.linalg.norm(cur[js[0]] - prev[js[0]], axis=-1) / frame_time
                cols.append(speed > threshold)
            elif kind == "plane":
                a, b, c, q = (cur[j] for j in js)
                normal = _unit(np.cross(c - a, b - a))
                cols.append(np.sum(normal * (q - a), axis=-1) > threshold)
            elif kind == "nplane":
                n1, n2, a, q = (cur[j] for j in js)
                normal = _unit(n2 - n1)
                cols.append(np.sum(normal * (q - a), axis=-1) > threshold)
            elif kind == "move":
                j1, j2, j3 = js[0], js[1], js[2]
                vel = ((cur[j3] - cur[j1]) - (prev[j3] - prev[j1])) / frame_time
                direction = _unit(cur[j2] - cur[j1])
                cols.append(np.sum(vel * direction, axis=-1) > threshold)
            elif kind == "nmove":
                j1, j2, j3, j4 = js
                vel = ((cur[j4] - cur[j1]) - (prev[j4] - prev[j1])) / frame_time
                normal = _unit(np.cross(cur[j3] - cur[j1], cur[j2] - cur[j1]))
                cols.append(np.sum(vel * normal, axis=-1) > threshold)
            else:  # pragma: no cover - table is static
                raise AssertionError(kind)
    feats = np.stack(cols, axis=1)  # (T-1, 32) bool; NaN comparisons are False
    if per_frame:
        return feats
    return feats.mean(axis=0).astype(np.float64)


# ---------------------------------------------------------------------------------------------
# sets of dances: segments, normalisation, FID and diversity


def segments(positions: np.ndarray, *, fps: float, seconds: float | None) -> list[np.ndarray]:
    """Cut a dance into consecutive non-overlapping segments of ``seconds``.

    The remainder shorter than a segment is dropped; a dance shorter than one segment is
    kept whole. ``seconds=None`` returns the whole dance.
    """
    if seconds is None:
        return [positions]
    if not seconds > 0:
        raise ParameterError(f"segment length must be positive seconds, got {seconds}")
    n = int(round(seconds * check_fps(fps)))
    if n < 3 or len(positions) < n:
        return [positions]
    return [positions[k : k + n] for k in range(0, len(positions) - n + 1, n)]


def feature_sets(
    dances: Sequence[np.ndarray],
    *,
    fps: float,
    skeleton: Skeleton,
    kind: str,
    segment_seconds: float | None = None,
    bug_compatible: bool = False,
) -> np.ndarray:
    """Kinetic or geometric features of every segment of every dance, stacked ``(N, D)``."""
    if kind not in ("kinetic", "geometric"):
        raise ParameterError(f"feature kind must be 'kinetic' or 'geometric', got {kind!r}")
    fn = kinetic_features if kind == "kinetic" else geometric_features
    rows = []
    for positions in dances:
        for seg in segments(np.asarray(positions), fps=fps, seconds=segment_seconds):
            rows.append(fn(seg, fps=fps, skeleton=skeleton, bug_compatible=bug_compatible))
    if not rows:
        raise ParameterError("no dances to compute features of")
    return np.stack(rows)


def normalize_features(
    reference: np.ndarray, *others: np.ndarray, min_std: float = 1e-8
) -> tuple[np.ndarray, ...]:
    """Z-score ``reference`` and ``others`` with the reference's mean and standard deviation.

    Columns whose reference standard deviation is ``<= min_std`` are dropped from every set.
    Returns ``(reference_z, *others_z, kept_mask)``.
    """
    ref = np.asarray(reference, np.float64)
    if ref.ndim != 2:
        raise ParameterError(f"reference features must be (N, D), got {ref.shape}")
    mean = ref.mean(0)
    std = ref.std(0)
    keep = std > min_std
    out = [(ref[:, keep] - mean[keep]) / std[keep]]
    for o in others:
        o = np.asarray(o, np.float64)
        if o.ndim != 2 or o.shape[1] != ref.shape[1]:
            raise ParameterError(f"features must be (N, {ref.shape[1]}), got {o.shape}")
        out.append((o[:, keep] - mean[keep]) / std[keep])
    return (*out, keep)


def feature_names(kind: str, skeleton: Skeleton) -> tuple[str, ...]:
    """Names of the columns of :func:`kinetic_features` (``"joint:KE_h"``, ``"joint:KE_v"``,
    ``"joint:EE"``, joint-major) or :func:`geometric_features` (:data:`GEOMETRIC_FEATURE_NAMES`)."""
    if kind == "geometric":
        return GEOMETRIC_FEATURE_NAMES
    if kind != "kinetic":
        raise ParameterError(f"feature kind must be 'kinetic' or 'geometric', got {kind!r}")
    return tuple(f"{j}:{q}" for j in skeleton.joint_names for q in ("KE_h", "KE_v", "EE"))


def fid_breakdown(
    pred_z: np.ndarray, ref_z: np.ndarray, names: Sequence[str], *, top: int = 5
) -> list[dict]:
    """Which features a Fréchet distance comes from: the one-dimensional Fréchet distance of each column.

    For column ``i`` of z-scored features, ``d_i = (mean_p - mean_r)² + (std_p - std_r)²`` (the
    Fréchet distance of the two columns' Gaussians on their own). The FID is not the sum of the
    ``d_i`` (it also sees correlations), but with the reference z-scored a column whose reference
    barely varies (a geometric feature true in one reference segment) shows up here with a huge
    ``d_i``: a few generated segments that differ from the reference there then decide the FID.

    Parameters
    ----------
    pred_z : (N, D) z-scored generated features (:func:`normalize_features`)
    ref_z : (M, D) z-scored reference features
    names : the D column names (after dropping the constant reference columns)
    top : how many columns to return

    Returns
    -------
    list of ``{"feature", "d", "share", "mean_z", "std_z"}``, largest ``d`` first: ``share`` is
    ``d`` over the sum of all columns' ``d``; ``mean_z`` / ``std_z`` are the generated column's
    mean and standard deviation in reference standard deviations from the reference mean.
    """
    p, r = np.asarray(pred_z, np.float64), np.asarray(ref_z, np.float64)
    if p.ndim != 2 or r.ndim != 2 or p.shape[1] != r.shape[1] or len(names) != p.shape[1]:
        raise ParameterError(
            f"fid_breakdown: shapes do not match: pred {p.shape}, ref {r.shape}, {len(names)} names"
        )
    d = (p.mean(0) - r.mean(0)) ** 2 + (p.std(0) - r.std(0)) ** 2
    total = float(d.sum())
    order = np.argsort(-d, kind="stable")[: max(int(top), 0)]
    return [
        {"feature": str(names[i]), "d": float(d[i]), "share": float(d[i] / total) if total > 0 else 0.0,
         "mean_z": float(p[:, i].mean() - r[:, i].mean()), "std_z": float(p[:, i].std())}
        for i in order
    ]


def average_pairwise_distance(features: np.ndarray) -> float:
    """Mean Euclidean distance over all unordered pairs of rows of ``features (N, D)``."""
    f = np.asarray(features, np.float64)
    n = len(f)
    if n < 2:
        raise ParameterError(f"diversity needs at least 2 feature vectors, got {n}")
    sq = np.sum(f**2, axis=1)
    d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * f @ f.T, 0.0)
    iu = np.triu_indices(n, k=1)
    return float(np.sqrt(d2[iu]).mean())


def fid_diversity(
    pred: Sequence[np.ndarray],
    ref: Sequence[np.ndarray],
    *,
    fps: float,
    skeleton: Skeleton,
    kind: str,
    segment_seconds: float | None = None,
    bug_compatible: bool = False,
    ref_fps: float | None = None,
) -> dict:
    """FID and diversity of one feature kind (``"kinetic"`` → FID_k / Div_k, ``"geometric"`` → FID_g / Div_g).

    Parameters
    ----------
    pred : generated dances, each (T_i, J, 3) in skeleton units at ``fps``
    ref : real dances (the reference distribution), at ``ref_fps`` (default ``fps``)
    segment_seconds : cut every dance into segments of this length first (None: whole dances)

    Returns
    -------
    dict with ``fid``, ``div`` (generated), ``div_ref``, ``n_pred`` / ``n_ref`` (feature
    vectors), ``dims_used`` (after dropping constant reference columns) and ``sqrtm`` (info).
    """
    fp = feature_sets(pred, fps=fps, skeleton=skeleton, kind=kind, segment_seconds=segment_seconds,
                      bug_compatible=bug_compatible)
    fr = feature_sets(ref, fps=ref_fps or fps, skeleton=skeleton, kind=kind, segment_seconds=segment_seconds,
                      bug_compatible=bug_compatible)
    fr_z, fp_z, keep = normalize_features(fr, fp)
    if not keep.any():
        raise ParameterError(f"every {kind} feature is constant over the reference dances; FID is undefined")
    fid, info = frechet_distance(fp_z, fr_z, return_info=True)
    return {
        "fid": fid,
        "div": average_pairwise_distance(fp_z),
        "div_ref": average_pairwise_distance(fr_z),
        "n_pred": int(len(fp)),
        "n_ref": int(len(fr)),
        "dims_used": int(keep.sum()),
        "dims_total": int(keep.size),
        "sqrtm": info,
    }
