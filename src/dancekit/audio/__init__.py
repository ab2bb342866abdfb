"""dancekit.audio: decode, validate, resample and write audio; tiny synthesisers for tests.

``load(path, *, sr=None, mono=True, start=None, end=None) -> (y float32 (n,), sr)``
is the entry point; :func:`validate_audio` is the one place samples are checked.
"""

from dancekit.audio import synth
from dancekit.audio.io import MIN_DURATION, check_audio_path, load, resample, save_wav, validate_audio

__all__ = ["MIN_DURATION", "check_audio_path", "load", "resample", "save_wav", "synth", "validate_audio"]
