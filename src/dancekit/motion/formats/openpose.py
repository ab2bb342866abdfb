"""OpenPose JSON folders: one ``*.json`` file per frame (BODY_25; COCO-17 and COCO-18 on output).

Each file holds ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...]}]}``
(25 keypoints, pixels, image space, c = confidence in [0, 1]). Frames are
taken in natural sort order of the file names (``..._000000000012_keypoints.json``).

:func:`write_openpose` also writes the COCO layouts that MMPose, AIST++ 2D and ControlNet
pipelines use, in the same per-frame JSON (``pose_keypoints_2d`` holds 17 or 18 triples, and
``keypoint_format`` names the layout): ``coco17`` (:data:`COCO17_NAMES`, MMPose order) and
``coco18`` (:data:`COCO18_NAMES`, OpenPose's COCO model order, with a neck). Points of a 3D
dance that are not joints of its skeleton get a lower confidence (:func:`keypoint_confidence`).

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

__all__ = [
    "COCO17_NAMES",
    "COCO18_NAMES",
    "KEYPOINT_FORMATS",
    "interpolate_missing",
    "keypoint_confidence",
    "read_openpose",
    "write_openpose",
]

KEYPOINT_FORMATS = ("body25", "coco17", "coco18")
#: COCO-17 (MMPose, COCO keypoints) in BODY_25 names.
COCO17_NAMES = ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow",
                "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle")
#: COCO-18 (OpenPose's COCO model) in BODY_25 names.
COCO18_NAMES = ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip",
                "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar")
#: Confidence of a point derived from joints by geometry (a midpoint; the head joint as the nose).
DERIVED_CONFIDENCE = 0.5
#: Confidence of an invented point (eyes, ears, small toes, heels placed by fixed offsets).
INVENTED_CONFIDENCE = 0.2


def keypoint_confidence(skeleton) -> np.ndarray:
    """``(25,)`` confidence of each BODY_25 point projected from a 3D dance on ``skeleton``.

    1.0 for a joint of the skeleton (shoulders, elbows, wrists, hips, knees, ankles, the ``toe``
    roles as big toes, the ``neck`` and ``heel`` roles when present); :data:`DERIVED_CONFIDENCE`
    for a point computed from joints (MidHip, a Neck between the shoulders, the head joint as the
    Nose); :data:`INVENTED_CONFIDENCE` for points placed by fixed offsets (eyes, ears, small
    toes, heels without heel joints). See :meth:`dancekit.motion.Motion.project_2d`.
    """
    b25 = get_skeleton("body25")
    conf = np.ones(25)

    def set_(name: str, c: float) -> None:
        conf[b25.index(name)] = c

    for name in ("LEye", "REye", "LEar", "REar", "LSmallToe", "RSmallToe"):
        set_(name, INVENTED_CONFIDENCE)
    for side, s in (("left", "L"), ("right", "R")):
        if not skeleton.has(f"{side}_heel"):
            set_(f"{s}Heel", INVENTED_CONFIDENCE)
    set_("MidHip", DERIVED_CONFIDENCE)
    set_("Nose", DERIVED_CONFIDENCE)
    if not skeleton.has("neck"):
        set_("Neck", DERIVED_CONFIDENCE)
    return conf


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


def write_openpose(folder: str | os.PathLike, motion: Motion, *, keypoints: str = "body25") -> None:
    """Write a 2D motion as OpenPose JSON, one file per frame (``{i:012d}_keypoints.json``).

    A 3D motion is projected first with :meth:`Motion.project_2d` (default view), and its
    points get the confidences of :func:`keypoint_confidence` (1 for joints of the skeleton,
    less for derived and invented points); a 2D BODY_25 motion's keypoints get confidence 1.
    ``keypoints`` picks the layout: ``body25`` (25 points), ``coco17`` or ``coco18`` (see the
    module docstring). The folder is created if needed; each file is written atomically.

    Raises
    ------
    MotionFormatError
        If the motion is not on the ``body25`` skeleton (after projection), or for an unknown
        ``keypoints`` layout.
    """
    folder = Path(folder)
    if keypoints not in KEYPOINT_FORMATS:
        raise MotionFormatError(f"keypoints must be one of {', '.join(KEYPOINT_FORMATS)}, got {keypoints!r} ({folder})")
    conf = np.ones(25)
    if motion.skeleton.dims == 3:
        try:
            conf = keypoint_confidence(motion.skeleton)
            m = motion.project_2d()
        except ParameterError as exc:
            raise MotionFormatError(f"cannot write {folder}: {exc}") from exc
    else:
        m = motion
    if m.skeleton.name != "body25" or m.skeleton.num_joints != 25:
        raise MotionFormatError(f"OpenPose output needs a body25 motion, got {m.skeleton.name!r} ({folder})")
    pos = m.to_positions().astype(np.float64)
    if keypoints != "body25":
        sel = [m.skeleton.index(n) for n in (COCO17_NAMES if keypoints == "coco17" else COCO18_NAMES)]
        pos, conf = pos[:, sel], conf[sel]
    folder.mkdir(parents=True, exist_ok=True)
    K = pos.shape[1]
    for i, frame in enumerate(pos):
        flat = np.concatenate([frame, conf[:, None]], axis=1).reshape(-1)
        obj = {"version": 1.3, "keypoint_format": keypoints,
               "people": [{"person_id": [-1], "pose_keypoints_2d": [round(float(v), 3) for v in flat]}]}
        assert len(obj["people"][0]["pose_keypoints_2d"]) == 3 * K
        with atomic_path(folder / f"{i:012d}_keypoints.json") as tmp:
            tmp.write_text(json.dumps(obj))
