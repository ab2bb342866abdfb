"""dancekit.motion: skeletons, the Motion container, rotations, kinematics and file formats.

- :class:`Skeleton`, :func:`get_skeleton` (``"tang2018"``, ``"body25"``, ``"smpl"``)
- :class:`Motion` (positions and/or local rotations at a frame rate)
- :mod:`dancekit.motion.rotations` (``a_to_b`` torch conversions)
- :mod:`dancekit.motion.kinematics` (forward / inverse kinematics)
- :mod:`dancekit.motion.formats` (``read_motion`` / ``write_motion``: npz, BVH,
  AIST++ pkl, OpenPose JSON folders, tang2018 dance folders; glTF ``.glb`` output)
- :mod:`dancekit.motion.retarget` (a dance onto the SMPL skeleton)
"""

from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import (
    CANONICAL_ROLES,
    Skeleton,
    body25_skeleton,
    get_skeleton,
    smpl_skeleton,
    tang2018_skeleton,
)

__all__ = [
    "CANONICAL_ROLES",
    "Motion",
    "Skeleton",
    "body25_skeleton",
    "get_skeleton",
    "read_motion",
    "smpl_skeleton",
    "tang2018_skeleton",
    "write_motion",
]


def __getattr__(name: str):
    # file formats are imported lazily (they pull in json/pickle readers)
    if name in ("read_motion", "write_motion"):
        from dancekit.motion import formats

        return getattr(formats, name)
    raise AttributeError(f"module 'dancekit.motion' has no attribute {name!r}")
