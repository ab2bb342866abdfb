"""dancekit: music to dance and dance to music.

Data flows one way: ``audio`` → ``features`` → ``models`` → ``motion`` →
``render`` / ``metrics`` / export. Lower layers never import higher ones.
"""

from dancekit.errors import (
    AudioError,
    CheckpointError,
    DancekitError,
    DatasetError,
    ExternalToolError,
    MotionFormatError,
    ParameterError,
)

__version__ = "0.1.0"

__all__ = [
    "AudioError",
    "CheckpointError",
    "DatasetError",
    "ExternalToolError",
    "DancekitError",
    "MotionFormatError",
    "ParameterError",
    "__version__",
]
