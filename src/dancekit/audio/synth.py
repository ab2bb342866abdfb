"""Tiny deterministic synthesisers for tests and the demo tune.

Nothing here reads a file: the repository ships no third-party audio, so
tests build their signals from these functions (a click track at a known
tempo, an additive-synthesis rendering of a public-domain melody).

A note list is a sequence of ``(pitch, beats)`` pairs: ``pitch`` is a MIDI
note number (60 = middle C, 69 = A4 = 440 Hz) or ``None`` for a rest, and
``beats`` its duration in beats (quarter notes).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dancekit.errors import ParameterError

__all__ = [
    "ODE_TO_JOY_BASS",
    "ODE_TO_JOY_MELODY",
    "beat_times",
    "click_track",
    "midi_to_hz",
    "ode_to_joy",
    "render_melody",
]

Note = tuple[int | None, float]


def _check_positive(name: str, value: float) -> None:
    if not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} must be a positive number, got {value!r}")


def midi_to_hz(pitch: float) -> float:
    """Frequency in Hz of a MIDI note number (A4 = 69 = 440 Hz)."""
    return 440.0 * 2.0 ** ((pitch - 69) / 12.0)


def beat_times(*, bpm: float, duration: float, offset: float = 0.0) -> np.ndarray:
    """Times in seconds (float64) of the beats of :func:`click_track`: ``offset + k * 60 / bpm < duration``."""
    _check_positive("bpm", bpm)
    _check_positive("duration", duration)
    period = 60.0 / bpm
    n = int(np.floor((duration - offset) / period - 1e-9)) + 1 if duration > offset else 0
    return offset + period * np.arange(max(n, 0), dtype=np.float64)


def _click(sr: int, *, accent: bool) -> np.ndarray:
    """One click: a 1.5 kHz + 3.1 kHz tone burst (25 ms decay); an accent adds a 70 Hz thump."""
    n = int(0.12 * sr)
    t = np.arange(n) / sr
    env = np.exp(-t / 0.025)
    x = env * (0.6 * np.sin(2 * np.pi * 1500.0 * t) + 0.4 * np.sin(2 * np.pi * 3100.0 * t))
    if accent:
        x = 1.5 * x + 1.2 * np.exp(-t / 0.06) * np.sin(2 * np.pi * 70.0 * t)
    return x


def click_track(
    *,
    bpm: float,
    duration: float,
    sr: int,
    offset: float = 0.0,
    meter: int | None = None,
    amplitude: float = 0.5,
) -> np.ndarray:
    """A click on every beat.

    Parameters
    ----------
    bpm : float
        Tempo in beats per minute.
    duration : float
        Length of the result in seconds.
    sr : int
        Sample rate in Hz.
    offset : float
        Time of the first click in seconds; the clicks are at :func:`beat_times`.
    meter : int, optional
        Accent every ``meter``-th click, starting with the first (louder, plus
        a low 70 Hz thump), so the downbeats are at ``beat_times(...)[::meter]``.
    amplitude : float
        Peak scale of an unaccented click.

    Returns
    -------
    np.ndarray, float32, shape (round(duration * sr),)
    """
    _check_positive("sr", sr)
    if meter is not None and (int(meter) != meter or meter < 1):
        raise ParameterError(f"meter must be a positive integer, got {meter!r}")
    n = int(round(duration * sr))
    y = np.zeros(n, dtype=np.float64)
    plain, accented = _click(sr, accent=False), _click(sr, accent=True)
    for k, t in enumerate(beat_times(bpm=bpm, duration=duration, offset=offset)):
        c = accented if meter is not None and k % meter == 0 else plain
        a = int(round(t * sr))
        m = min(len(c), n - a)
        if m > 0:
            y[a : a + m] += c[:m]
    return (amplitude * y).astype(np.float32)


def render_melody(
    notes: Sequence[Note],
    *,
    sr: int,
    bpm: float,
    amplitude: float = 0.3,
    harmonics: Sequence[float] = (1.0, 0.5, 0.3, 0.15, 0.08),
    decay: float = 0.6,
) -> np.ndarray:
    """Render a monophonic note list by additive synthesis.

    Each note is a sum of harmonics (``harmonics[k]`` is the amplitude of
    harmonic ``k + 1``) under a 10 ms attack, an exponential decay with time
    constant ``decay`` seconds and a 30 ms release at the note's end.

    Parameters
    ----------
    notes : sequence of (pitch, beats)
        MIDI pitch (or ``None`` for a rest) and duration in beats.
    sr : int
        Sample rate in Hz.
    bpm : float
        Tempo in beats per minute.

    Returns
    -------
    np.ndarray, float32, shape (round(total_beats * 60 / bpm * sr),)
    """
    _check_positive("sr", sr)
    _check_positive("bpm", bpm)
    spb = 60.0 / bpm
    total = sum(float(b) for _, b in notes)
    y = np.zeros(int(round(total * spb * sr)), dtype=np.float64)
    nyquist = sr / 2
    t0 = 0.0
    for pitch, beats in notes:
        _check_positive("note duration (beats)", beats)
        a = int(round(t0 * spb * sr))
        t0 += float(beats)
        if pitch is None:
            continue
        b = min(len(y), int(round(t0 * spb * sr)))
        t = np.arange(b - a) / sr
        f0 = midi_to_hz(pitch)
        tone = sum(
            h * np.sin(2 * np.pi * f0 * (k + 1) * t)
            for k, h in enumerate(harmonics)
            if f0 * (k + 1) < nyquist
        )
        env = np.minimum(1.0, t / 0.01) * np.exp(-t / decay) * np.clip((t[-1] - t) / 0.03, 0.0, 1.0)
        y[a:b] += env * tone
    peak = float(np.max(np.abs(y))) if y.size else 0.0
    return (amplitude * y / peak if peak > 0 else y).astype(np.float32)


# "Ode to Joy" (Beethoven, Symphony No. 9, public domain), in C major, 4/4, 16 bars.
_A = [64, 64, 65, 67, 67, 65, 64, 62, 60, 60, 62, 64]
ODE_TO_JOY_MELODY: list[Note] = (
    [(p, 1.0) for p in _A]
    + [(64, 1.5), (62, 0.5), (62, 2.0)]
    + [(p, 1.0) for p in _A]
    + [(62, 1.5), (60, 0.5), (60, 2.0)]
    + [(62, 1.0), (62, 1.0), (64, 1.0), (60, 1.0)]
    + [(62, 1.0), (64, 0.5), (65, 0.5), (64, 1.0), (60, 1.0)]
    + [(62, 1.0), (64, 0.5), (65, 0.5), (64, 1.0), (62, 1.0)]
    + [(60, 1.0), (62, 1.0), (55, 2.0)]
    + [(p, 1.0) for p in _A]
    + [(62, 1.5), (60, 0.5), (60, 2.0)]
)
# one bass note per half bar: root then fifth of C (48/55) or G (43/50) major
_C, _G = [(48, 2.0), (55, 2.0)], [(43, 2.0), (50, 2.0)]
ODE_TO_JOY_BASS: list[Note] = (
    _C
    + _G
    + _C
    + _G
    + _C
    + _G
    + _C
    + [(43, 2.0), (48, 2.0)]
    + _G
    + _G
    + _G
    + [(48, 2.0), (43, 2.0)]
    + _C
    + _G
    + _C
) + [(43, 2.0), (48, 2.0)]


def ode_to_joy(*, sr: int, bpm: float = 120.0, repeats: int = 1) -> np.ndarray:
    """Melody + bass + a click on every beat (accented on each bar) of "Ode to Joy".

    16 bars of 4/4 per repeat (32 s at 120 BPM). The beats are at
    ``k * 60 / bpm`` and the downbeats at every fourth beat from 0.

    Returns
    -------
    np.ndarray, float32, shape (round(64 * repeats * 60 / bpm * sr),), peak <= 0.9
    """
    if int(repeats) != repeats or repeats < 1:
        raise ParameterError(f"repeats must be a positive integer, got {repeats!r}")
    melody = render_melody(ODE_TO_JOY_MELODY * repeats, sr=sr, bpm=bpm, amplitude=0.35)
    bass = render_melody(ODE_TO_JOY_BASS * repeats, sr=sr, bpm=bpm, amplitude=0.3, decay=1.2)
    n = len(melody)
    clicks = click_track(bpm=bpm, duration=n / sr, sr=sr, meter=4, amplitude=0.25)
    y = melody + bass[:n] + clicks[:n]
    peak = float(np.max(np.abs(y)))
    return (0.9 * y / peak).astype(np.float32) if peak > 0.9 else y
