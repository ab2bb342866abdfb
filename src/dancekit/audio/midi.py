"""Chroma + beats → a MIDI arrangement (chords, bass, drums) → audio.

The dual-learning model's G_D→M composes a 12-d chroma and a beat activation per frame (MM 2021, §3.4);
:func:`arrange` makes music of them with ``pretty_midi``:

* beats: the peaks of the beat activation at or above ``threshold`` (at least ``min_gap`` s apart) with
  ``tempo="auto"``, or a regular grid at a given BPM phased on the first composed beat;
* chords: on every beat, the major or minor triad whose template best matches the mean chroma until the
  next beat (cosine similarity over the 24 triads), played by a piano (GM program 0) in octave 4;
* bass: the chord's root on every beat (GM program 33, electric bass, octave 2);
* drums (GM channel 10): kick on even beats, snare on odd beats, closed hi-hat on every beat.

:func:`render` turns the MIDI into audio with FluidSynth and a General MIDI soundfont when both are
installed (Debian: ``apt-get install fluidsynth fluid-soundfont-gm``; Python: ``pip install pyfluidsynth``,
the ``dancekit[fluidsynth]`` extra), otherwise with :func:`synthesize`, a small built-in additive
synthesiser whose piano, bass and drum voices have decaying harmonics and noise bursts (not sine tones).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancekit.errors import ParameterError

PITCH_CLASSES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
PIANO, BASS = 0, 33  # General MIDI programs: acoustic grand piano, electric bass (finger)
KICK, SNARE, HIHAT = 36, 38, 42  # General MIDI percussion keys


@dataclass
class Arrangement:
    """What :func:`arrange` made: ``beat_times`` (s), ``chords`` [(root 0..11, minor)] one per beat, ``tempo``
    (BPM), ``duration`` (s) and ``midi`` (a ``pretty_midi.PrettyMIDI`` with piano, bass and drum tracks)."""

    beat_times: np.ndarray
    chords: list[tuple[int, bool]]
    tempo: float
    duration: float
    midi: object

    def chord_names(self) -> list[str]:
        """E.g. ``["C", "Am", ...]``."""
        return [PITCH_CLASSES[r] + ("m" if minor else "") for r, minor in self.chords]


def triad_templates() -> np.ndarray:
    """(24, 12) unit-norm chroma templates: C, C#, ..., B major, then C minor ... B minor."""
    t = np.zeros((24, 12))
    for root in range(12):
        for k, third in enumerate((4, 3)):
            t[12 * k + root, [root, (root + third) % 12, (root + 7) % 12]] = 1.0
    return t / np.sqrt(3.0)


def best_triad(chroma: np.ndarray) -> tuple[int, bool]:
    """The (root, minor) of the triad template nearest a 12-d chroma (cosine similarity)."""
    chroma = np.asarray(chroma, np.float64).reshape(12)
    k = int(np.argmax(triad_templates() @ chroma))
    return k % 12, k >= 12


def pick_beats(beat: np.ndarray, *, fps: float, threshold: float = 0.5, min_gap: float = 0.25) -> np.ndarray:
    """Times (s) of the local maxima of a beat activation ``(T,)`` at or above ``threshold``, ``min_gap`` s apart
    (the stronger one wins)."""
    b = np.asarray(beat, np.float64).reshape(-1)
    left = np.concatenate([[-np.inf], b[:-1]])
    right = np.concatenate([b[1:], [-np.inf]])
    peaks = np.flatnonzero((b >= threshold) & (b >= left) & (b > right))
    kept: list[int] = []
    for i in sorted(peaks, key=lambda i: -b[i]):
        if all(abs(i - j) / fps >= min_gap for j in kept):
            kept.append(int(i))
    return np.sort(np.asarray(kept, np.float64)) / fps


def periodic_beats(beat: np.ndarray, *, fps: float, min_bpm: float = 60.0, max_bpm: float = 180.0,
                   prior_bpm: float = 120.0, snap: int = 3, step: float = 0.002) -> tuple[np.ndarray, float]:
    """Beats on the metrical level of a beat activation's periodicity, not on its thresholded peaks.

    The metrical level is the highest local maximum of the autocorrelation of the activation's half-wave
    rectified frame difference (its rises: an activation that stays above a threshold on most frames still
    rises periodically), at lags between ``60 / max_bpm`` and ``60 / min_bpm`` s, weighted by a log-normal
    tempo prior (``prior_bpm``, one octave standard deviation, as librosa's tempo estimator). The period is then
    refined to ``step`` s within ±4 % of that lag, and the phase chosen (half-frame steps), by the grid whose
    mean activation over the whole piece is highest (a comb over all beats, finer than a frame); each grid time
    is finally moved to the activation's maximum within ``snap`` frames.

    Parameters
    ----------
    beat : (T,) beat activation per frame
    fps : frames per second of ``beat``
    min_bpm, max_bpm : the tempo range searched (BPM)
    prior_bpm : centre of the tempo prior (BPM)
    snap : frames a grid beat may move to the activation's local maximum (0: the plain grid)
    step : period resolution of the refinement, seconds

    Returns
    -------
    (beat times (s), tempo in BPM of the grid); (empty, NaN) for a flat activation or one shorter than two
    periods of ``min_bpm``
    """
    b = np.asarray(beat, np.float64).reshape(-1)
    if not 0 < min_bpm < max_bpm or fps <= 0 or snap < 0 or prior_bpm <= 0:
        raise ParameterError(f"periodic_beats needs 0 < min_bpm < max_bpm, fps > 0, prior_bpm > 0, snap >= 0; got "
                             f"{min_bpm}, {max_bpm}, {fps}, {prior_bpm}, {snap}")
    n = len(b)
    x = np.maximum(np.diff(b, prepend=b[:1]), 0.0)
    x = x - x.mean()
    if n < 2 * 60.0 / min_bpm * fps or not np.any(np.abs(x) > 1e-12):
        return np.zeros(0), float("nan")
    acf = np.correlate(x, x, "full")[n - 1:] / np.arange(n, 0, -1)  # unbiased
    lags = np.arange(int(np.floor(60.0 / max_bpm * fps)), int(np.ceil(60.0 / min_bpm * fps)) + 1)
    a = acf[lags] * np.exp(-0.5 * np.log2(60.0 * fps / lags / prior_bpm) ** 2)
    peaks = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:])) + 1
    lag = float(lags[peaks[np.argmax(a[peaks])]] if len(peaks) else lags[int(np.argmax(a))])
    t, duration = np.arange(n) / fps, n / fps

    def comb(period: float) -> tuple[float, float]:  # (best mean activation over phases, that phase)
        phases = np.arange(0.0, period, 0.5 / fps)
        means = [np.interp(np.arange(ph, duration, period), t, b).mean() for ph in phases]
        k = int(np.argmax(means))
        return float(means[k]), float(phases[k])

    periods = np.arange(0.96 * lag / fps, 1.04 * lag / fps, step)
    scores = [comb(p) for p in periods]
    k = int(np.argmax([s[0] for s in scores]))
    period, phase = float(periods[k]), scores[k][1]
    grid = np.arange(phase, duration, period)
    if snap:
        idx = np.clip(np.round(grid * fps).astype(int), 0, n - 1)
        grid = np.unique([(max(0, i - snap) + int(np.argmax(b[max(0, i - snap): i + snap + 1]))) / fps
                          for i in idx])
    return grid, 60.0 / period


#: The tempo range (BPM) of a written MIDI file's header: :func:`midi_file_tempo`.
MIDI_TEMPO_RANGE = (20.0, 400.0)


def midi_file_tempo(bpm: float) -> float:
    """The tempo written in the MIDI header for composed beats ``bpm`` BPM apart: ``bpm`` doubled or halved
    until it lies in :data:`MIDI_TEMPO_RANGE`, so that every composed beat stays on a MIDI beat. A MIDI
    file stores microseconds per beat in 24 bits (at most 16.8 s: below 3.6 BPM pretty_midi cannot write the
    file), and it stores the note times in ticks of 1/220 beat (at 20 BPM, 14 ms). The notes keep their times
    in seconds; :attr:`Arrangement.tempo` stays the composed tempo."""
    lo, hi = MIDI_TEMPO_RANGE
    if not (np.isfinite(bpm) and bpm > 0):
        raise ParameterError(f"tempo must be a positive number of BPM, got {bpm!r}")
    while bpm < lo:
        bpm *= 2.0
    while bpm > hi:
        bpm /= 2.0
    return float(bpm)


def arrange(chroma: np.ndarray, beat: np.ndarray, *, fps: float, tempo: str | float = "auto",
            threshold: float = 0.5, min_gap: float = 0.25, default_bpm: float = 120.0) -> Arrangement:
    """Chords on the beats, a bass line on the chord roots and a drum track on the beats.

    Parameters
    ----------
    chroma : (T, 12) chroma per frame (any non-negative scale)
    beat : (T,) beat activation per frame in [0, 1]
    fps : frames per second of both
    tempo : ``"auto"`` (the picked beats; a ``default_bpm`` grid when fewer than two are found),
        ``"periodic"`` (:func:`periodic_beats`: the activation's own period; the ``default_bpm`` grid when it
        has none) or a BPM (a regular grid phased on the first picked beat)
    threshold : beat activation that counts as a beat
    min_gap : shortest time between two picked beats, seconds (:func:`pick_beats`)

    Returns
    -------
    :class:`Arrangement`
    """
    import pretty_midi

    chroma = np.asarray(chroma, np.float64)
    beat = np.asarray(beat, np.float64).reshape(-1)
    if chroma.ndim != 2 or chroma.shape[1] != 12 or len(chroma) != len(beat) or len(beat) == 0:
        raise ParameterError(f"need chroma (T, 12) and beat (T,) with T > 0, got {chroma.shape} and {beat.shape}")
    duration = len(beat) / float(fps)
    picked = pick_beats(beat, fps=fps, threshold=threshold, min_gap=min_gap)
    if tempo in ("auto", "periodic"):
        if tempo == "periodic":
            picked = periodic_beats(beat, fps=fps)[0]
        if len(picked) >= 2:
            times = picked
        else:
            times = np.arange(0.0, duration, 60.0 / default_bpm)
    else:
        try:
            bpm = float(tempo)
        except (TypeError, ValueError):
            raise ParameterError(f"tempo must be 'auto', 'periodic' or a number of BPM, got {tempo!r}") from None
        if not 20.0 <= bpm <= 400.0:
            raise ParameterError(f"tempo must be between 20 and 400 BPM, got {bpm}")
        period = 60.0 / bpm
        phase = (picked[0] % period) if len(picked) else 0.0
        times = np.arange(phase, duration, period)
    period = float(np.median(np.diff(times))) if len(times) >= 2 else 60.0 / default_bpm
    bpm_out = 60.0 / period
    ends = np.append(times[1:], min(duration, times[-1] + period)) if len(times) else times

    pm = pretty_midi.PrettyMIDI(initial_tempo=midi_file_tempo(bpm_out))
    piano = pretty_midi.Instrument(program=PIANO, name="chords")
    bass = pretty_midi.Instrument(program=BASS, name="bass")
    drums = pretty_midi.Instrument(program=0, is_drum=True, name="drums")
    chords: list[tuple[int, bool]] = []
    for i, (t0, t1) in enumerate(zip(times, ends)):
        a, b = int(np.floor(t0 * fps)), max(int(np.floor(t0 * fps)) + 1, int(np.ceil(t1 * fps)))
        root, minor = best_triad(chroma[a:b].mean(0))
        chords.append((root, minor))
        for interval in (0, 3 if minor else 4, 7):
            piano.notes.append(pretty_midi.Note(velocity=72, pitch=60 + root + interval, start=t0, end=t1))
        bass.notes.append(pretty_midi.Note(velocity=90, pitch=36 + root, start=t0, end=t0 + 0.9 * (t1 - t0)))
        drum = KICK if i % 2 == 0 else SNARE
        drums.notes.append(pretty_midi.Note(velocity=100, pitch=drum, start=t0, end=t0 + 0.1))
        drums.notes.append(pretty_midi.Note(velocity=70, pitch=HIHAT, start=t0, end=t0 + 0.05))
    pm.instruments.extend([piano, bass, drums])
    return Arrangement(beat_times=np.asarray(times, np.float64), chords=chords, tempo=bpm_out, duration=duration,
                       midi=pm)


# ------------------------------------------------------------------------------------------ synthesis


def _midi_hz(pitch: int) -> float:
    return 440.0 * 2.0 ** ((pitch - 69) / 12.0)


def _envelope(n: int, sr: int, *, attack: float, release_at: int, release: float) -> np.ndarray:
    env = np.ones(n)
    a = max(1, int(attack * sr))
    env[:a] = np.linspace(0.0, 1.0, a, endpoint=False)
    if release_at < n:
        r = np.arange(n - release_at) / sr
        env[release_at:] *= np.exp(-r / max(release, 1e-3))
    return env


def _partials(pitch: int, n: int, sr: int, *, bass: bool) -> np.ndarray:
    """The undamped-by-envelope sum of :func:`_tone`'s decaying partials over ``n`` samples."""
    t = np.arange(n) / sr
    f0 = _midi_hz(pitch)
    out = np.zeros(n)
    partials = 5 if bass else 10
    for k in range(1, partials + 1):
        fk = k * f0 * np.sqrt(1.0 + 2e-4 * k * k)
        if fk > 0.45 * sr:
            break
        amp = (1.0 / k**2) if bass else (1.0 / k**1.3)
        decay = (1.2 + 1.5 * k) if bass else (0.8 + 0.9 * k)
        out += amp * np.exp(-decay * t) * np.sin(2 * np.pi * fk * t + 0.3 * k)
    return out


def _tone(pitch: int, velocity: int, length: float, sr: int, *, bass: bool,
          cache: dict | None = None) -> np.ndarray:
    """A plucked / struck voice: decaying, slightly inharmonic partials (piano-like, or bass-like).

    ``cache``: a dict kept across the notes of one piece; the partials of a (pitch, voice) are computed once,
    for the longest note asked so far, and sliced (the same samples as computing them for each note)."""
    tail = 0.3
    n = int((length + tail) * sr)
    if cache is None:
        out = _partials(pitch, n, sr, bass=bass)
    else:
        key = (int(pitch), bool(bass), int(sr))
        if key not in cache or len(cache[key]) < n:
            cache[key] = _partials(pitch, max(n, int(2.0 * sr)), sr, bass=bass)
        out = cache[key][:n]
    env = _envelope(n, sr, attack=0.004 if not bass else 0.008, release_at=int(length * sr), release=0.06)
    return out * env * (velocity / 127.0)


def _drum(pitch: int, velocity: int, sr: int, rng: np.random.Generator) -> np.ndarray:
    """Kick (a pitch sweep with a click), snare (noise + tone) or hi-hat (high-passed noise)."""
    n = int(0.4 * sr)
    t = np.arange(n) / sr
    if pitch in (35, 36):
        freq = 45.0 + 80.0 * np.exp(-t * 30.0)
        y = np.sin(2 * np.pi * np.cumsum(freq) / sr) * np.exp(-t * 9.0)
        y[: int(0.003 * sr)] += rng.normal(0, 0.4, int(0.003 * sr))
    elif pitch in (38, 40):
        noise = rng.normal(0, 1, n)
        y = 0.6 * noise * np.exp(-t * 20.0) + 0.5 * np.sin(2 * np.pi * 190.0 * t) * np.exp(-t * 25.0)
    else:
        noise = rng.normal(0, 1, n)
        y = np.diff(noise, prepend=0.0) * 0.4 * np.exp(-t * 45.0)
    return y * (velocity / 127.0)


def synthesize(midi, *, sr: int = 22050, seed: int = 0) -> np.ndarray:
    """A ``pretty_midi.PrettyMIDI`` → mono float32 audio with the built-in voices, peak-normalised to 0.89."""
    rng = np.random.default_rng(seed)
    end = float(midi.get_end_time()) + 0.5
    out = np.zeros(int(end * sr) + 1)
    cache: dict = {}
    for inst in midi.instruments:
        bass = 32 <= inst.program <= 39
        for note in inst.notes:
            if inst.is_drum:
                y = _drum(note.pitch, note.velocity, sr, rng)
            else:
                y = _tone(note.pitch, note.velocity, note.end - note.start, sr, bass=bass, cache=cache) * (
                    1.4 if bass else 0.5)
            a = int(note.start * sr)
            m = min(len(y), len(out) - a)
            out[a: a + m] += y[:m]
    peak = np.abs(out).max()
    return (out * (0.89 / peak) if peak > 0 else out).astype(np.float32)


def fluidsynth_available() -> bool:
    """Whether ``pretty_midi``'s FluidSynth rendering can run (the ``pyfluidsynth`` module and its library)."""
    try:
        import fluidsynth  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


def render(midi, *, sr: int = 22050, backend: str = "auto") -> tuple[np.ndarray, str]:
    """MIDI → mono float32 audio and the backend used: ``"fluidsynth"`` (General MIDI soundfont) or ``"builtin"``.

    ``backend="auto"`` picks FluidSynth when :func:`fluidsynth_available`, else the built-in synthesiser.
    """
    if backend not in ("auto", "fluidsynth", "builtin"):
        raise ParameterError(f"backend must be auto, fluidsynth or builtin, got {backend!r}")
    if backend == "fluidsynth" or (backend == "auto" and fluidsynth_available()):
        if not fluidsynth_available():
            raise ParameterError("FluidSynth is not installed (apt-get install fluidsynth; pip install pyfluidsynth)")
        y = np.asarray(midi.fluidsynth(fs=sr), np.float64)
        peak = np.abs(y).max()
        return (y * (0.89 / peak) if peak > 0 else y).astype(np.float32), "fluidsynth"
    return synthesize(midi, sr=sr), "builtin"


def write_arrangement(arrangement: Arrangement, out_dir: str | os.PathLike, *, stem: str = "music",
                      sr: int = 22050, backend: str = "auto") -> dict[str, Path]:
    """Write ``stem.mid`` and ``stem.wav`` (rendered with :func:`render`) into ``out_dir``; returns their paths."""
    from dancekit._io import atomic_path
    from dancekit.audio.io import save_wav

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mid = out / f"{stem}.mid"
    with atomic_path(mid) as tmp:
        arrangement.midi.write(str(tmp))
    y, _ = render(arrangement.midi, sr=sr, backend=backend)
    wav = save_wav(out / f"{stem}.wav", y, sr=sr)
    return {"midi": mid, "wav": Path(wav)}

