"""Motion file formats: one module per format, and :func:`read_motion` / :func:`write_motion`.

=====================  ==============================  =======================
what                   recognised by                   module
=====================  ==============================  =======================
dancekit npz           ``*.npz``                       :mod:`.npz`
BVH                    ``*.bvh``                       :mod:`.bvh`
AIST++ SMPL            ``*.pkl``                       :mod:`.aistpp`
glTF 2.0 binary        ``*.glb``                       :mod:`.gltf`
OpenPose BODY_25       folder of ``*_keypoints.json``  :mod:`.openpose`
                       or ``*.json`` files
tang2018 dance         folder with ``skeletons.json``  :mod:`.tang2018` (read only)
=====================  ==============================  =======================
"""

from __future__ import annotations

import os
from pathlib import Path

from dancekit.errors import MotionFormatError
from dancekit.motion.formats.npz import read_npz, write_npz
from dancekit.motion.formats.tang2018 import AudioSlice, read_tang2018
from dancekit.motion.motion import Motion

__all__ = [
    "AudioSlice",
    "detect_format",
    "read_motion",
    "read_npz",
    "read_tang2018",
    "write_motion",
    "write_npz",
]


def detect_format(path: str | os.PathLike) -> str:
    """The format of a motion path: ``"npz"``, ``"bvh"``, ``"glb"``, ``"aistpp"``, ``"openpose"`` or ``"tang2018"``.

    Files are recognised by suffix, folders by content (``skeletons.json`` →
    tang2018; ``*.json`` files → OpenPose). A path that does not exist yet is
    recognised by suffix (a suffix-less path means an OpenPose folder).

    Raises
    ------
    MotionFormatError
        If the format cannot be recognised.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        if (path / "skeletons.json").is_file():
            return "tang2018"
        if any(path.glob("*.json")):
            return "openpose"
        raise MotionFormatError(f"folder {path} holds neither skeletons.json (tang2018) nor *.json (OpenPose)")
    formats = {".npz": "npz", ".bvh": "bvh", ".glb": "glb", ".pkl": "aistpp"}
    if suffix in formats:
        return formats[suffix]
    if not path.exists() and suffix == "":
        return "openpose"
    if suffix in (".mid", ".midi"):
        raise MotionFormatError(f"{path} is a MIDI file (music), not a motion: `dancekit info` describes it, "
                                "`dancekit dance` needs a song (wav, ogg, mp3, ...)")
    raise MotionFormatError(f"unknown motion format for {path} (expected .npz, .bvh, .glb, .pkl or a folder)")


def read_motion(path: str | os.PathLike, **kwargs) -> Motion:
    """Read any supported motion file or folder (see the module table).

    Keyword arguments go to the format's reader (e.g. ``fps=`` for AIST++ and
    OpenPose, ``confidence_threshold=`` for OpenPose).

    Raises
    ------
    MotionFormatError
        If the path is missing, of unknown format, or malformed (names the file).
    """
    path = Path(path)
    if not path.exists():
        raise MotionFormatError(f"motion file not found: {path}")
    if not (path.is_file() or path.is_dir()):  # a named pipe: reading would wait for a writer
        raise MotionFormatError(f"expected a motion file or folder but got a special file (a pipe?): {path}")
    fmt = detect_format(path)
    if fmt == "npz":
        return read_npz(path, **kwargs)
    if fmt == "bvh":
        from dancekit.motion.formats.bvh import read_bvh

        return read_bvh(path, **kwargs)
    if fmt == "glb":
        from dancekit.motion.formats.gltf import read_glb

        return read_glb(path, **kwargs)
    if fmt == "aistpp":
        from dancekit.motion.formats.aistpp import read_aistpp

        return read_aistpp(path, **kwargs)
    if fmt == "openpose":
        from dancekit.motion.formats.openpose import read_openpose

        return read_openpose(path, **kwargs)
    return read_tang2018(path, **kwargs)[0]


def write_motion(path: str | os.PathLike, motion: Motion, **kwargs) -> None:
    """Write ``motion`` by the suffix of ``path``: ``.npz``, ``.bvh``, ``.glb``, ``.pkl`` (AIST++ SMPL, retargeted,
    60 fps), or a folder (OpenPose JSON). Keyword arguments go to the format's writer (e.g.
    ``rig="humanoid"`` for BVH, ``keypoints="coco17"`` for JSON folders).

    Raises
    ------
    MotionFormatError
        For a format that cannot be written (tang2018) or an unknown suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return write_npz(path, motion, **kwargs)
    if suffix == ".bvh":
        from dancekit.motion.formats.bvh import write_bvh

        return write_bvh(path, motion, **kwargs)
    if suffix == ".pkl":
        from dancekit.motion.formats.aistpp import write_aistpp

        write_aistpp(path, motion, **kwargs)
        return None
    if suffix == ".glb":
        from dancekit.motion.formats.gltf import write_glb

        return write_glb(path, motion, **kwargs)
    if suffix == "" or path.is_dir():
        from dancekit.motion.formats.openpose import write_openpose

        return write_openpose(path, motion, **kwargs)
    raise MotionFormatError(f"cannot write motion format {suffix!r} ({path}); use .npz, .bvh, .glb, .pkl or a folder")
