"""How to render a dance (:class:`RenderOptions`) and which song plays with it (:class:`AudioClip`).

Both are frozen dataclasses validated once, when they are made: a bad value raises a one-line
:class:`~dancekit.errors.ParameterError` that names the field and the value. Every renderer
(:func:`~dancekit.render.render_mp4`, :func:`~dancekit.render.render_html` and their ``Motion``
forms) and :func:`dancekit.export.export_motion` take them as ``options=`` and ``audio=``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancekit.errors import ParameterError

__all__ = ["AudioClip", "RenderOptions"]


def _number(value, name: str, problem: str) -> float:
    """``value`` as a finite float; booleans, strings and NaN are refused with ``problem``."""
    if isinstance(value, bool | str | bytes):
        raise ParameterError(f"{name} {problem}, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} {problem}, got {value!r}") from None
    if not math.isfinite(x):
        raise ParameterError(f"{name} {problem}, got {value!r}")
    return x


@dataclass(frozen=True)
class AudioClip:
    """The slice of a song that plays with a dance.

    Parameters
    ----------
    path : path-like
        The song (any format ffmpeg reads). Whether it exists is checked when rendering.
    start : float or None
        Second of the song at which frame 0 of the dance plays (None: 0).
    end : float or None
        Second of the song at which the video ends (None: ``start`` plus the dance's length).
        Both are clipped to the song when rendering.

    Raises
    ------
    ParameterError
        If ``path`` is not a path, or ``start`` / ``end`` are negative, not finite, or ``end <= start``.

    Examples
    --------
    >>> AudioClip("song.mp3", start=12.0)  # doctest: +SKIP
    """

    path: Path
    start: float | None = None
    end: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.path, str | os.PathLike) or not os.fspath(self.path):
            raise ParameterError(f"audio path must be a file path, got {self.path!r}")
        object.__setattr__(self, "path", Path(self.path))
        start = (
            None if self.start is None else _number(self.start, "audio start", "must be a finite time >= 0 s")
        )
        if start is not None and start < 0:
            raise ParameterError(f"audio start must be a finite time >= 0 s, got {self.start!r}")
        after = f"must be a finite time after the start ({start or 0.0:.3f} s)"
        end = None if self.end is None else _number(self.end, "audio end", after)
        if end is not None and end <= (start or 0.0):
            raise ParameterError(f"audio end {after}, got {self.end!r}")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)

    @classmethod
    def of(cls, audio: AudioClip | str | os.PathLike | None) -> AudioClip | None:
        """``audio`` as an :class:`AudioClip`: a plain path means the song from its start."""
        if audio is None or isinstance(audio, AudioClip):
            return audio
        if isinstance(audio, str | os.PathLike):
            return cls(audio)
        raise ParameterError(f"audio must be an AudioClip, a path or None, got {type(audio).__name__}")


FIGURES = ("stick", "body")


@dataclass(frozen=True)
class RenderOptions:
    """How a dance is drawn: image size, camera, quality, page title.

    Parameters
    ----------
    width, height : int
        Video size in pixels, even numbers in 16..4096 (mp4 only; the html player fills its window).
    azimuth : float or None
        Camera azimuth in degrees (None: a three-quarter view of the dancer's front).
    elevation : float
        Camera elevation in degrees, in -80..80 (the html player's initial view too).
    crf : int
        x264 quality in 0..51, lower is better and larger (mp4 only).
    title : str or None
        Page title (html only; None: the output file's stem).
    figure : {"stick", "body"}
        How the dancer is drawn in the mp4 and the html player: ``stick`` (thin bones and joint dots, the default) or
        ``body`` (a mannequin: shaded volumetric limbs, a torso that turns with the body, a head).
    workers : int or None
        Processes drawing the mp4's frames, 1..64 (None: one per core but one, at most 4, when the video is longer
        than 10 s; 1 on 2 cores, where drawing and ffmpeg's encoding already keep both busy). The video is the
        same, byte for byte, whatever the count (mp4 only).

    Raises
    ------
    ParameterError
        On a value out of range (the message names the field and the value).

    Examples
    --------
    >>> RenderOptions(width=320, height=240, elevation=20.0)  # doctest: +SKIP
    """

    width: int = 640
    height: int = 480
    azimuth: float | None = None
    elevation: float = 12.0
    crf: int = 23
    title: str | None = None
    figure: str = "stick"
    workers: int | None = None

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if not isinstance(v, int | np.integer) or isinstance(v, bool) or not 16 <= v <= 4096 or v % 2:
                raise ParameterError(f"{name} must be an even number of pixels in 16..4096, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.azimuth is not None:
            object.__setattr__(
                self, "azimuth", _number(self.azimuth, "azimuth", "must be a finite angle in degrees")
            )
        el = _number(self.elevation, "elevation", "must be in -80..80 degrees")
        if not -80.0 <= el <= 80.0:
            raise ParameterError(f"elevation must be in -80..80 degrees, got {self.elevation!r}")
        object.__setattr__(self, "elevation", el)
        crf = self.crf
        if not isinstance(crf, int | np.integer) or isinstance(crf, bool) or not 0 <= crf <= 51:
            raise ParameterError(f"crf must be an integer in 0..51, got {crf!r}")
        object.__setattr__(self, "crf", int(crf))
        if self.title is not None and not isinstance(self.title, str):
            raise ParameterError(f"title must be a string or None, got {self.title!r}")
        if self.figure not in FIGURES:
            raise ParameterError(f"figure must be one of {', '.join(FIGURES)}, got {self.figure!r}")
        w = self.workers
        if w is not None and (not isinstance(w, int | np.integer) or isinstance(w, bool) or not 1 <= w <= 64):
            raise ParameterError(f"workers must be None or an integer in 1..64, got {w!r}")


# ---------------------------------------------------------------------- the keywords of release 0.1
_AUDIO_KEYWORDS = ("audio_path", "audio_start", "audio_end")


def resolve(
    func: str,
    options: RenderOptions | None,
    audio: AudioClip | str | os.PathLike | None,
    legacy: dict,
    *,
    accepted: tuple[str, ...],
) -> tuple[RenderOptions, AudioClip | None]:
    """Check ``options`` / ``audio``, folding in the deprecated keywords ``legacy`` of ``func``.

    ``accepted`` names the old keywords ``func`` took (besides ``audio_path`` / ``audio_start`` /
    ``audio_end``); any other keyword is a ``TypeError``, as Python would raise.
    """
    if options is None:
        options = RenderOptions()
    elif not isinstance(options, RenderOptions):
        raise ParameterError(f"options must be a RenderOptions or None, got {type(options).__name__}")
    audio = AudioClip.of(audio)
    if not legacy:
        return options, audio
    unknown = sorted(set(legacy) - set(accepted) - set(_AUDIO_KEYWORDS))
    if unknown:
        raise TypeError(f"{func}() got an unexpected keyword argument {unknown[0]!r}")
    message = (
        f"{func}({', '.join(f'{k}=' for k in legacy)}) is deprecated and will be removed in the next "
        "release: pass options=RenderOptions(...) and audio=AudioClip(path, start, end)"
    )
    legacy = dict(legacy)
    path, start, end = (legacy.pop(k, None) for k in _AUDIO_KEYWORDS)
    if path is not None or start is not None or end is not None:
        if audio is not None:
            raise TypeError(f"{func}() got both audio= and audio_path / audio_start / audio_end")
        if path is None:
            raise ParameterError("audio_start / audio_end need an audio_path")
        audio = AudioClip(path, start, end)
    options = dataclasses.replace(options, **legacy)
    warnings.warn(message, DeprecationWarning, stacklevel=3)  # after the checks: an error comes first
    return options, audio
