"""Named exceptions for bad input.

Every error a user can cause (a missing file, a corrupt song, a bad flag)
raises a subclass of :class:`DancekitError` whose message names the problem
and, where there is one, the file. The CLI prints such errors as one line on
stderr and exits non-zero. ``assert`` is kept for internal invariants only.
"""

from __future__ import annotations


class DancekitError(Exception):
    """Base class of every error dancekit raises for bad input."""


class ParameterError(DancekitError, ValueError):
    """A bad argument value (names the argument and the value)."""


class AudioError(DancekitError):
    """An audio file that is missing, unreadable, corrupt, empty or too short."""


class MotionFormatError(DancekitError):
    """A motion file (BVH, npz, JSON, pkl, tang2018 folder) that is missing or malformed."""


class CheckpointError(DancekitError):
    """A checkpoint folder that is missing files or does not match the code."""


class DatasetError(DancekitError):
    """A dataset folder that is missing files or is inconsistent."""


class ExternalToolError(DancekitError):
    """An external program (ffmpeg) that is missing or failed."""
