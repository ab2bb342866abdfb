"""AIST++ SMPL motion files (``.pkl``): :func:`read_aistpp` and :func:`write_aistpp`.

An AIST++ motion pickle is a dict with ``smpl_poses`` (T, 72): 24 axis-angle
rotations per frame in SMPL joint order (root first), ``smpl_trans`` (T, 3)
and optionally ``smpl_scaling`` (1,) (AIST++ stores the translation
multiplied by that scale). The motion is at 60 fps in AIST++.

:func:`write_aistpp` retargets any 3D dance onto the SMPL skeleton
(:func:`dancekit.motion.retarget.retarget_to_smpl`) and writes that dict
(``smpl_poses`` float32 (T, 72), ``smpl_trans`` float32 (T, 3),
``smpl_scaling`` float32 (1,)), resampled to 60 fps by default.

The pickle is loaded with a restricted unpickler that only accepts NumPy
arrays and plain containers, so a malicious file cannot run code.
"""

from __future__ import annotations

import io
import os
import pickle
from pathlib import Path

import numpy as np
import torch

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, MotionFormatError
from dancekit.motion.motion import Motion
from dancekit.motion.rotations import axis_angle_to_matrix
from dancekit.motion.skeleton import Skeleton, smpl_skeleton

__all__ = ["AISTPP_FPS", "SMPL_PELVIS_REST", "read_aistpp", "write_aistpp"]

AISTPP_FPS = 60.0
# Approximate rest position of the SMPL pelvis joint relative to the model
# origin (metres, hand-set): SMPL rotates the body about this point, so the
# world pelvis is ``SMPL_PELVIS_REST + smpl_trans / smpl_scaling``.
SMPL_PELVIS_REST = np.array([0.0, -0.24, 0.03])

_ALLOWED = {
    ("numpy", "ndarray"), ("numpy", "dtype"),
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"), ("numpy._core.numeric", "_frombuffer"),
    ("builtins", "dict"), ("builtins", "list"), ("builtins", "tuple"), ("builtins", "float"),
    ("collections", "OrderedDict"),
}


class _SafeUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) in _ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refusing to load {module}.{name}")


def read_aistpp(
    path: str | os.PathLike,
    *,
    fps: float = AISTPP_FPS,
    skeleton: Skeleton | None = None,
    pelvis_rest: np.ndarray | None = None,
) -> Motion:
    """Read an AIST++ SMPL ``.pkl`` into a Motion on the ``smpl`` skeleton (metres, y up).

    Parameters
    ----------
    path : path to the ``.pkl``
    fps : frames per second (AIST++: 60)
    skeleton : an SMPL-ordered skeleton (e.g. ``smpl_skeleton(offsets_path=...)``);
        default: the built-in approximate one
    pelvis_rest : (3,) rest position of the pelvis joint (default :data:`SMPL_PELVIS_REST`)

    Returns
    -------
    Motion
        ``rotations`` (T, 24, 3, 3) float64, ``root_translation`` = pelvis_rest +
        smpl_trans / smpl_scaling (T, 3), positions by forward kinematics.

    Raises
    ------
    MotionFormatError
        If the file is missing, not a pickle of the expected dict, or the arrays
        have wrong shapes or non-finite values (names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFormatError(f"AIST++ file not found: {path}")
    try:
        obj = _SafeUnpickler(io.BytesIO(path.read_bytes())).load()
    except (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError) as exc:
        raise MotionFormatError(f"cannot unpickle AIST++ file {path}: {exc}") from exc
    if not isinstance(obj, dict) or "smpl_poses" not in obj or "smpl_trans" not in obj:
        raise MotionFormatError(f"{path}: expected a dict with 'smpl_poses' and 'smpl_trans'")
    try:
        poses = np.asarray(obj["smpl_poses"], dtype=np.float64)
        trans = np.asarray(obj["smpl_trans"], dtype=np.float64)
        scaling = float(np.asarray(obj.get("smpl_scaling", 1.0), dtype=np.float64).reshape(-1)[0])
    except (TypeError, ValueError, IndexError) as exc:
        raise MotionFormatError(f"{path}: non-numeric SMPL arrays ({exc})") from exc
    if poses.ndim != 2 or poses.shape[1] != 72 or poses.shape[0] == 0:
        raise MotionFormatError(f"{path}: smpl_poses must be (T, 72), got {poses.shape}")
    T = poses.shape[0]
    if trans.shape != (T, 3):
        raise MotionFormatError(f"{path}: smpl_trans must be ({T}, 3), got {trans.shape}")
    if not (np.all(np.isfinite(poses)) and np.all(np.isfinite(trans))) or not (scaling > 0):
        raise MotionFormatError(f"{path}: NaN/inf values or a non-positive smpl_scaling")
    rest = SMPL_PELVIS_REST if pelvis_rest is None else np.asarray(pelvis_rest, dtype=np.float64)
    rot = axis_angle_to_matrix(torch.from_numpy(poses.reshape(T, 24, 3))).numpy()
    try:
        m = Motion(
            skeleton=skeleton if skeleton is not None else smpl_skeleton(),
            fps=fps,
            rotations=rot,
            root_translation=trans / scaling + rest,
        )
    except DancekitError as exc:
        raise MotionFormatError(f"{path}: {exc}") from exc
    return m.with_positions()


def write_aistpp(path: str | os.PathLike, motion: Motion, *, fps: float | None = AISTPP_FPS) -> float:
    """Write a 3D dance as an AIST++ SMPL ``.pkl`` (atomically); returns ``smpl_scaling``.

    The dance is resampled to ``fps`` (None: kept; AIST++ tools assume 60), retargeted onto the
    SMPL skeleton (:func:`~dancekit.motion.retarget.retarget_to_smpl`: rotations whose forward
    kinematics with the :func:`~dancekit.motion.skeleton.smpl_skeleton` rest offsets points every
    limb like the dance's) and stored as ``smpl_poses`` (T, 72) axis-angle, ``smpl_trans`` (T, 3) =
    ``scaling * (pelvis - SMPL_PELVIS_REST)`` in the dance's units and ``smpl_scaling`` (1,), so
    that :func:`read_aistpp` gives the dance on the SMPL body (metres) and the AIST++ convention
    (``joints * scaling``) gives it at the dance's size. No SMPL model file is needed.

    Raises
    ------
    MotionFormatError
        For a 2D motion or a skeleton without the limb roles (names the file).
    """
    from dancekit.motion.retarget import retarget_to_smpl, smpl_axis_angle

    path = Path(path)
    try:
        m = motion if fps is None or fps == motion.fps else motion.resample(fps)
        smpl, scaling = retarget_to_smpl(m)
    except DancekitError as exc:
        raise MotionFormatError(f"cannot write {path} as AIST++ SMPL: {exc}") from exc
    assert smpl.rotations is not None and smpl.root_translation is not None
    obj = {
        "smpl_poses": smpl_axis_angle(smpl.rotations).astype(np.float32),
        "smpl_trans": (scaling * (np.asarray(smpl.root_translation, np.float64) - SMPL_PELVIS_REST)).astype(np.float32),
        "smpl_scaling": np.array([scaling], dtype=np.float32),
    }
    with atomic_path(path, suffix=".pkl") as tmp:
        tmp.write_bytes(pickle.dumps(obj, protocol=4))
    return scaling
