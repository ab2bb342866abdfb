"""Reader for one dance folder of Tang et al. 2018 ("Dance with Melody").

A folder ``DANCE_<G>_<n>/`` holds ``skeletons.json`` (``length`` T,
``skeletons`` (T, 23, 3) relative to the body centre, ``center`` (T, 3)),
``config.json`` (``start_position``, ``end_position`` in 25 fps frames of the
song) and ``audio.mp3``. World positions are ``skeletons + center``, in cm,
y up, at 25 fps; frame ``i`` plays at ``start_position / 25 + i / 25`` s of the song.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancekit.errors import MotionFormatError
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import get_skeleton

__all__ = ["AudioSlice", "TANG2018_FPS", "read_tang2018"]

TANG2018_FPS = 25.0


@dataclass(frozen=True)
class AudioSlice:
    """A span of an audio file: ``path``, ``start`` and ``end`` in seconds."""

    path: Path
    start: float
    end: float

    @property
    def duration(self) -> float:
        """``end - start`` in seconds."""
        return self.end - self.start

    def __iter__(self):  # allows ``path, start, end = audio_slice``
        return iter((self.path, self.start, self.end))


def _load_json(path: Path) -> object:
    if not path.is_file():
        raise MotionFormatError(f"tang2018 file not found: {path}")
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MotionFormatError(f"cannot parse {path}: {exc}") from exc


def read_tang2018(folder: str | os.PathLike) -> tuple[Motion, AudioSlice]:
    """Read a tang2018 dance folder.

    Parameters
    ----------
    folder : path
        A ``DANCE_<G>_<n>`` folder.

    Returns
    -------
    motion : Motion
        World positions ``(T, 23, 3)`` float32 in cm on the ``tang2018`` skeleton, 25 fps.
    audio : AudioSlice
        ``(folder/audio.mp3, start_position / 25, start_position / 25 + T / 25)``: the
        span of the song the motion covers (``end`` follows T, which can be a few frames
        shorter or longer than ``end_position - start_position``).

    Raises
    ------
    MotionFormatError
        If a file is missing, truncated or holds arrays of the wrong shape or
        non-finite values (the message names the file).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MotionFormatError(f"tang2018 dance folder not found: {folder}")
    skel_path = folder / "skeletons.json"
    cfg_path = folder / "config.json"
    data = _load_json(skel_path)
    cfg = _load_json(cfg_path)
    if not isinstance(data, dict) or "skeletons" not in data or "center" not in data:
        raise MotionFormatError(f"{skel_path}: expected keys 'skeletons' and 'center'")
    if not isinstance(cfg, dict) or "start_position" not in cfg:
        raise MotionFormatError(f"{cfg_path}: expected key 'start_position'")
    try:
        sk = np.asarray(data["skeletons"], dtype=np.float64)
        center = np.asarray(data["center"], dtype=np.float64)
        start_frame = float(cfg["start_position"])
    except (ValueError, TypeError) as exc:
        raise MotionFormatError(f"{skel_path}: not numeric arrays ({exc})") from exc
    if sk.ndim != 3 or sk.shape[1:] != (23, 3) or sk.shape[0] == 0:
        raise MotionFormatError(f"{skel_path}: 'skeletons' must be (T, 23, 3), got {sk.shape}")
    if center.shape != (sk.shape[0], 3):
        raise MotionFormatError(f"{skel_path}: 'center' must be ({sk.shape[0]}, 3), got {center.shape}")
    if "length" in data and int(data["length"]) != sk.shape[0]:
        raise MotionFormatError(f"{skel_path}: 'length' is {data['length']} but there are {sk.shape[0]} frames")
    positions = sk + center[:, None, :]
    if not np.all(np.isfinite(positions)):
        raise MotionFormatError(f"{skel_path}: positions contain NaN/inf")
    motion = Motion(skeleton=get_skeleton("tang2018"), fps=TANG2018_FPS, positions=positions.astype(np.float32))
    start = start_frame / TANG2018_FPS
    return motion, AudioSlice(folder / "audio.mp3", start, start + motion.num_frames / TANG2018_FPS)
