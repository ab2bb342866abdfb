"""The toolkit's public motion file: ``.npz`` (documented in docs/MOTION.md).

Keys:

``positions``        (T, J, 3) or (T, J, 2) float32, world positions in skeleton units
``fps``              float64 scalar, frames per second
``joint_names``      (J,) unicode strings
``parents``          (J,) int64, -1 for the root
``skeleton``         0-d unicode string: JSON of ``Skeleton.to_dict()`` (roles, offsets, units, up axis,
                     branch joints...)
``rotations``        (T, J_rig, 3, 3) float32, local rotations on the skeleton's rig (optional, when known)
``root_translation`` (T, 3) float32 (optional, with ``rotations``)
``rig_joint_names``  (J_rig,) unicode, with ``rotations``: the rig's joints (the J joints, then the
                     zero-offset branch joints ``"{parent}_to_{child}"``)
``rig_parents``      (J_rig,) int64, with ``rotations``: the rig's parents
``format``           0-d string ``"dancekit-motion"``; ``version`` int64 scalar, currently 2

The rig is ``Skeleton.from_dict(json.loads(skeleton)).rig()``; for a skeleton
without ``branch_joints`` it is the skeleton itself (``J_rig == J``). Its
offsets are the skeleton's offsets followed by zeros, so forward kinematics
of ``rotations`` on (``rig_parents``, those offsets) gives the joint positions
with the skeleton's rest bone lengths (see docs/MOTION.md). Version-1 files
(rotations on the J joints, no ``rig_*`` keys) read the same way.

Files are read with ``allow_pickle=False``.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, MotionFormatError
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import Skeleton

__all__ = ["read_npz", "write_npz"]

FORMAT = "dancekit-motion"
VERSION = 2


def write_npz(path: str | os.PathLike, motion: Motion) -> None:
    """Write ``motion`` to ``path`` (``.npz``, float32 arrays, atomically).

    Positions are always written (forward kinematics if the motion only has
    rotations); rotations (on ``skeleton.rig()``, with ``rig_joint_names`` and
    ``rig_parents``) and root translation when the motion has them.
    """
    sk = motion.skeleton
    arrays = {
        "positions": np.asarray(motion.to_positions(), dtype=np.float32),
        "fps": np.float64(motion.fps),
        "joint_names": np.asarray(sk.joint_names, dtype=str),
        "parents": np.asarray(sk.parents, dtype=np.int64),
        "skeleton": np.asarray(json.dumps(sk.to_dict())),
        "format": np.asarray(FORMAT),
        "version": np.int64(VERSION),
    }
    if motion.rotations is not None:
        arrays["rotations"] = np.asarray(motion.rotations, dtype=np.float32)
        arrays["root_translation"] = np.asarray(motion.root_translation, dtype=np.float32)
        rig = sk.rig()
        arrays["rig_joint_names"] = np.asarray(rig.joint_names, dtype=str)
        arrays["rig_parents"] = np.asarray(rig.parents, dtype=np.int64)
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez(tmp, **arrays)


def read_npz(path: str | os.PathLike) -> Motion:
    """Read a motion ``.npz`` written by :func:`write_npz`.

    A file without the ``skeleton`` key but with ``joint_names`` and
    ``parents`` gets a skeleton with zero offsets (positions only).

    Raises
    ------
    MotionFormatError
        If the file is missing, not an npz, lacks keys, or holds bad arrays
        (rotations that do not fit the skeleton's rig included); the message
        names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFormatError(f"motion file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise MotionFormatError(f"cannot read motion npz {path}: {exc}") from exc
    missing = [k for k in ("positions", "fps") if k not in data]
    if missing:
        raise MotionFormatError(f"{path}: missing keys {missing} (has {sorted(data)})")
    try:
        if "skeleton" in data:
            skeleton = Skeleton.from_dict(json.loads(str(data["skeleton"])))
        elif "joint_names" in data and "parents" in data:
            names = tuple(str(n) for n in data["joint_names"])
            skeleton = Skeleton(
                name=path.stem, joint_names=names, parents=tuple(int(p) for p in data["parents"]),
                offsets=np.zeros((len(names), 3)),
            )
        else:
            raise MotionFormatError(f"{path}: no 'skeleton' (or 'joint_names' + 'parents') key")
        fps = float(np.asarray(data["fps"]).reshape(()))
        if "rig_joint_names" in data and "rotations" in data:
            rig = skeleton.rig()
            names = tuple(str(n) for n in data["rig_joint_names"])
            parents = tuple(int(p) for p in data.get("rig_parents", rig.parents))
            if names != rig.joint_names or parents != rig.parents:
                raise MotionFormatError(
                    f"{path}: rig_joint_names/rig_parents do not match the rig of the stored skeleton "
                    f"{skeleton.name!r} ({rig.num_joints} joints)"
                )
        return Motion(
            skeleton=skeleton,
            fps=fps,
            positions=data["positions"],
            rotations=data.get("rotations"),
            root_translation=data.get("root_translation"),
        )
    except MotionFormatError:
        raise
    except (DancekitError, ValueError, TypeError, KeyError) as exc:
        raise MotionFormatError(f"{path}: {exc}") from exc
