"""OpenPose BODY_25 JSON folders: one ``*.json`` file per frame.

Each file holds ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...]}]}``
(25 keypoints, pixels, image space, c = confidence in [0, 1]). Frames are
taken in natural sort order of the file names (``..._000000000012_keypoints.json``).

Missing detections are filled as in Dance Revolution (§4.1): a frame without
people, or a keypoint with confidence below ``confidence_threshold``, is
linearly interpolated from the nearest valid frames before and after (held
constant before the first and after the last valid frame).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import MotionFormatError, ParameterError
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import get_skeleton

__all__ = ["interpolate_missing", "read_openpose", "write_openpose"]


def _natural_key(p: Path) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def interpolate_missing(points: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Fill invalid keypoints by linear interpolation over time, per keypoint.

    Parameters
    ----------
    points : np.ndarray, shape (T, K, D)
    valid : np.ndarray of bool, shape (T, K)

    Returns
    -------
    np.ndarray, shape (T, K, D)
        Invalid entries replaced by linear interpolation between the nearest
        valid frames (constant extrapolation at the ends).

    Raises
    ------
    ParameterError
        If a keypoint is never valid.
    """
    points = np.array(points, dtype=np.float64)
    T, K, D = points.shape
    t = np.arange(T)
    for k in range(K):
        ok = valid[:, k]
        if ok.all():
            continue
        if not ok.any():
            raise ParameterError(f"keypoint {k} is missing in every frame")
        for d in range(D):
            points[~ok, k, d] = np.interp(t[~ok], t[ok], points[ok, k, d])
    return points


def read_openpose(
    folder: str | os.PathLike, *, fps: float = 25.0, confidence_threshold: float = 0.1, person: int = 0
) -> Motion:
    """Read a folder of OpenPose BODY_25 JSON files into a 2D Motion (``body25`` skeleton, pixels).

    Parameters
    ----------
    folder : path
        Folder with one ``*.json`` per frame.
    fps : float
        Frame rate of the video the keypoints come from.
    confidence_threshold : float
        Keypoints with ``c < confidence_threshold`` (and ``c == 0`` always) count as missing.
    person : int
        Index in ``people`` to read.

    Raises
    ------
    MotionFormatError
        If the folder is missing or empty, a file is not valid JSON, a keypoint
        list is not 75 numbers, values are not finite, or a keypoint is
        missing in every frame (names the file or folder).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MotionFormatError(f"OpenPose folder not found: {folder}")
    files = sorted(folder.glob("*.json"), key=_natural_key)
    if not files:
        raise MotionFormatError(f"no *.json files in OpenPose folder {folder}")
    T = len(files)
    pts = np.zeros((T, 25, 2))
    conf = np.zeros((T, 25))
    for i, f in enumerate(files):
        try:
            obj = json.loads(f.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise MotionFormatError(f"cannot parse OpenPose file {f}: {exc}") from exc
        people = obj.get("people") if isinstance(obj, dict) else None
        if not isinstance(people, list):
            raise MotionFormatError(f"{f}: no 'people' list")
        if len(people) <= person:
            continue  # nobody detected: the whole frame is interpolated
        kp = people[person].get("pose_keypoints_2d") if isinstance(people[person], dict) else None
        try:
            arr = np.asarray(kp, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise MotionFormatError(f"{f}: pose_keypoints_2d is not numeric ({exc})") from exc
        if arr.shape != (75,):
            raise MotionFormatError(f"{f}: pose_keypoints_2d must hold 25 x (x, y, c) = 75 numbers, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise MotionFormatError(f"{f}: pose_keypoints_2d contains NaN/inf")
        arr = arr.reshape(25, 3)
        pts[i], conf[i] = arr[:, :2], arr[:, 2]
    valid = (conf >= confidence_threshold) & (conf > 0)
    try:
        filled = interpolate_missing(pts, valid)
    except ParameterError as exc:
        raise MotionFormatError(f"{folder}: {exc}") from exc
    return Motion(skeleton=get_skeleton("body25"), fps=fps, positions=filled.astype(np.float32))


def write_openpose(folder: str | os.PathLike, motion: Motion) -> None:
    """Write a 2D motion as OpenPose JSON, one file per frame (``{i:012d}_keypoints.json``).

    A 3D motion is projected first with :meth:`Motion.project_2d` (default
    view). Every keypoint gets confidence 1. The folder is created if needed;
    each file is written atomically.

    Raises
    ------
    MotionFormatError
        If the motion is not on the ``body25`` skeleton (after projection).
    """
    folder = Path(folder)
    m = motion.project_2d() if motion.skeleton.dims == 3 else motion
    if m.skeleton.name != "body25" or m.skeleton.num_joints != 25:
        raise MotionFormatError(f"OpenPose output needs a body25 motion, got {m.skeleton.name!r} ({folder})")
    folder.mkdir(parents=True, exist_ok=True)
    pos = m.to_positions().astype(np.float64)
    for i, frame in enumerate(pos):
        flat = np.concatenate([frame, np.ones((25, 1))], axis=1).reshape(-1)
        obj = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": [round(float(v), 3) for v in flat]}]}
        with atomic_path(folder / f"{i:012d}_keypoints.json") as tmp:
            tmp.write_text(json.dumps(obj))
