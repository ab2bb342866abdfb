"""Dance-to-music metrics (dual-learning paper §4.4 and its music loss, eq. 9).

Notes accuracy
    Both pieces are transposed to C major or A minor (whichever the estimated mode is), then
    compared frame by frame: on a grid of ``fps`` frames per second, each piece's *melody
    note* is the highest pitch sounding at that instant (notes are half-open
    ``[start, end)``). The accuracy is the share of frames where the reference sounds whose
    generated melody note equals the reference's (``pitch_class=True`` compares pitch
    classes, i.e. ignores octaves). The key is estimated with the Krumhansl–Schmuckler
    algorithm: the duration-weighted pitch-class histogram is correlated (Pearson) with the
    24 rotations of the Krumhansl–Kessler major and minor profiles. The transposition is
    the shift in ``[-6, +5]`` semitones that moves the tonic to C (major) or A (minor), so a
    copy transposed by up to ±5 semitones maps back onto the original; a copy transposed by
    6 or more semitones lands an octave away and needs ``pitch_class=True``.

Chroma L1 and beat L1
    The two terms of the dual-learning music distance: per frame, the L1 distance of the
    12-bin chroma vectors, and the absolute difference of the beat (one-hot or strength)
    tracks, averaged over frames. Sequences of different lengths are compared over the
    shorter one.

Notes are given as a :class:`pretty_midi.PrettyMIDI` (drum tracks are ignored) or an array
``(N, 3+)`` with columns ``start`` (s), ``end`` (s), ``pitch`` (MIDI number) [, velocity].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError

__all__ = [
    "KK_MAJOR",
    "KK_MINOR",
    "beat_l1",
    "chroma_l1",
    "estimate_key",
    "melody_track",
    "note_array",
    "notes_accuracy",
    "transpose_to_c",
]

#: Krumhansl–Kessler probe-tone profiles (Krumhansl 1990), tonic first.
KK_MAJOR = np.array([6.35, 2.23, 3.48, 2.33, 4.38, 4.09, 2.52, 5.19, 2.39, 3.66, 2.29, 2.88])
KK_MINOR = np.array([6.33, 2.68, 3.52, 5.38, 2.60, 3.53, 2.54, 4.75, 3.98, 2.69, 3.34, 3.17])
PITCH_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")


def note_array(notes: Any) -> np.ndarray:
    """Notes as an ``(N, 3)`` float64 array ``[start, end, pitch]`` sorted by start.

    Accepts a :class:`pretty_midi.PrettyMIDI` (non-drum instruments) or an ``(N, 3+)`` array.
    """
    if hasattr(notes, "instruments"):
        rows = [
            (n.start, n.end, n.pitch)
            for inst in notes.instruments
            if not getattr(inst, "is_drum", False)
            for n in inst.notes
        ]
        arr = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    else:
        arr = np.asarray(notes, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] < 3:
            raise ParameterError(f"notes must be a PrettyMIDI or an (N, 3+) array [start, end, pitch], got {arr.shape}")
        arr = arr[:, :3].copy()
    if not np.isfinite(arr).all():
        raise ParameterError("notes contain NaN or inf")
    if (arr[:, 1] < arr[:, 0]).any():
        raise ParameterError("notes must end after they start")
    return arr[np.argsort(arr[:, 0], kind="stable")]


def _pitch_class_histogram(notes: np.ndarray) -> np.ndarray:
    hist = np.zeros(12)
    np.add.at(hist, notes[:, 2].astype(int) % 12, notes[:, 1] - notes[:, 0])
    return hist


def estimate_key(notes: Any) -> tuple[int, str, float]:
    """Krumhansl–Schmuckler key estimate.

    Returns
    -------
    ``(tonic, mode, r)``: tonic pitch class (0 = C .. 11 = B), ``"major"`` or ``"minor"``,
    and the winning correlation.

    Raises
    ------
    ParameterError
        If the piece has no note of positive duration.
    """
    arr = note_array(notes)
    hist = _pitch_class_histogram(arr)
    if hist.sum() <= 0:
        raise ParameterError("cannot estimate the key of a piece without notes")
    best = (-2.0, 0, "major")
    for mode, profile in (("major", KK_MAJOR), ("minor", KK_MINOR)):
        for tonic in range(12):
            r = np.corrcoef(hist, np.roll(profile, tonic))[0, 1]
            r = -1.0 if not np.isfinite(r) else float(r)
            if r > best[0] + 1e-12:
                best = (r, tonic, mode)
    r, tonic, mode = best
    return tonic, mode, r


def transpose_to_c(notes: Any) -> tuple[np.ndarray, int]:
    """Transpose a piece to C major / A minor; returns ``(notes (N, 3), shift in semitones)``."""
    arr = note_array(notes)
    tonic, mode, _ = estimate_key(arr)
    target = 0 if mode == "major" else 9
    shift = (target - tonic) % 12
    if shift > 5:
        shift -= 12
    out = arr.copy()
    out[:, 2] += shift
    return out, int(shift)


def melody_track(notes: Any, *, fps: float, num_frames: int | None = None) -> np.ndarray:
    """Highest sounding MIDI pitch per frame ``(num_frames,)``, -1 where silent."""
    fps = check_fps(fps)
    arr = note_array(notes)
    if num_frames is None:
        num_frames = int(np.ceil(arr[:, 1].max() * fps)) if len(arr) else 0
    track = np.full(num_frames, -1, dtype=np.int64)
    t = np.arange(num_frames) / fps
    for start, end, pitch in arr:
        on = (t >= start) & (t < end)
        track[on] = np.maximum(track[on], int(pitch))
    return track


def notes_accuracy(
    pred: Any, ref: Any, *, fps: float = 25.0, transpose: bool = True, pitch_class: bool = False
) -> float:
    """Notes accuracy of generated music against the reference (see the module docstring).

    Parameters
    ----------
    pred, ref : PrettyMIDI or note arrays ``(N, 3+)``
    fps : frame rate of the comparison grid
    transpose : transpose both to C major / A minor first (the paper's protocol)
    pitch_class : compare pitch classes instead of MIDI pitches

    Returns
    -------
    float in [0, 1]; NaN if the reference never sounds.
    """
    p, r = note_array(pred), note_array(ref)
    if transpose:
        if len(p):
            p, _ = transpose_to_c(p)
        r, _ = transpose_to_c(r)
    end = max(p[:, 1].max() if len(p) else 0.0, r[:, 1].max() if len(r) else 0.0)
    n = int(np.ceil(end * fps))
    mp = melody_track(p, fps=fps, num_frames=n)
    mr = melody_track(r, fps=fps, num_frames=n)
    sounding = mr >= 0
    if not sounding.any():
        return float("nan")
    if pitch_class:
        same = (mp[sounding] >= 0) & (mp[sounding] % 12 == mr[sounding] % 12)
    else:
        same = mp[sounding] == mr[sounding]
    return float(np.mean(same))


def _pair(a: np.ndarray, b: np.ndarray, name: str, width: int | None) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if width is not None:
        if a.ndim != 2 or b.ndim != 2 or a.shape[1] != width or b.shape[1] != width:
            raise ParameterError(f"{name} must be (T, {width}) arrays, got {a.shape} and {b.shape}")
    else:
        a, b = a.reshape(len(a), -1), b.reshape(len(b), -1)
        if a.shape[1] != b.shape[1]:
            raise ParameterError(f"{name} tracks have different widths: {a.shape} and {b.shape}")
    n = min(len(a), len(b))
    if n == 0:
        raise ParameterError(f"{name}: empty sequence")
    return a[:n], b[:n]


def chroma_l1(pred: np.ndarray, ref: np.ndarray) -> float:
    """Mean over frames of the L1 distance between chroma vectors ``(T, 12)``."""
    a, b = _pair(pred, ref, "chroma", 12)
    return float(np.abs(a - b).sum(axis=1).mean())


def beat_l1(pred: np.ndarray, ref: np.ndarray) -> float:
    """Mean over frames of the absolute difference of two beat tracks ``(T,)`` (or ``(T, 1)``)."""
    a, b = _pair(pred, ref, "beat", None)
    return float(np.abs(a - b).sum(axis=1).mean())
