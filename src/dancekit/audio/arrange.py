"""Music that follows a dance: a pulse at the dance's tempo, chords of one key changing on bars, bass and drums.

:func:`follow_dance` is the arranger of ``dancekit compose``. It takes the dance as a *pulse curve* (a
per-frame strength that peaks where the dancer's body slows down: the dance's kinematic beats, computed by
the caller from the motion, :func:`dance_pulse`) and, optionally, what the dual model's G_D→M composed for
the dance (chroma and beat activation per frame), and writes a ``pretty_midi`` arrangement:

* **tempo** (:func:`pulse_tempo`): the autocorrelation of the pulse curve (the steps: the ankles' speed
  dips), weighted by a broad log-normal tempo prior; the period of that peak is then refined by a comb, the
  mean autocorrelation over all its multiples up to 8 s (an uneven step pattern, slow-quick-quick or a
  waltz's long first step, biases the single peak; the bars' repeats do not), and the tempo is doubled or
  halved into ``[86, 172)`` BPM (the octave rule; it and every other setting here were chosen on the
  tang2018 validation dances, with the training dances as a second check, docs/DUAL.md, "Music that
  follows the dance");
* **phase** (:func:`track_beats`, :func:`smooth_beats`): a dynamic-programming beat tracker (Ellis 2007)
  at that tempo on a second curve, ``phase_pulse`` (the caller passes the dance's kinematic beats as a train
  of bumps, :func:`beat_curve`), so the beats fall on the kinematic beats where the tempo allows; the
  tracked beats are then locked to the tempo (:func:`lock_beats`: every beat one period after the last, its
  phase the median of the tracked beats' phases over ±1 beat, held until it moves by more than a frame), so
  the pulse keeps the dance's tempo and follows its kinematic beats;
* **metre**: ``beats_per_bar`` beats to a bar (3 or 4; :func:`pulse_metre` compares the periodicity of a
  third curve, ``metre_pulse``, at 3 and 4 beats: the caller passes the whole body's speed dips, deeper on
  the strong beats);
* **key and chords**: every chord is a major or minor triad of the printed key's (natural) scale (I ii iii
  IV V vi in major, i III iv v VI VII in minor); one chord per bar, changing only on the bars' downbeats;
  which chord a bar gets is G_D→M's: the triad of the scale nearest (cosine) the composed chroma of the
  bar, with the tonic on the first and the last bar (a cadence);
* **accents and density** from G_D→M's beat activation: the drums' and the piano's velocities follow the
  activation at each beat; a bar whose mean activation is below the piece's median gets the piano on its
  downbeat only (else on every beat);
* **bass and drums on the pulse**: the bass plays the chord's root on every beat (the fifth on the
  middle beat of a 4-beat bar); the kick on the downbeat (and beat 3 of 4), the snare on the other beats,
  a closed hi-hat on every beat.

The triads are voiced as :func:`dancekit.audio.midi.arrange` voices them (root position from middle C, the
bass two octaves below the root): the notes accuracy of the dual paper compares the highest sounding note
(docs/METRICS.md), and the real music's reference is written by that arranger.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancekit.errors import ParameterError

PITCH_CLASSES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
MAJOR_SCALE = (0, 2, 4, 5, 7, 9, 11)
MINOR_SCALE = (0, 2, 3, 5, 7, 8, 10)  # natural minor
#: the consonant triads (degree offset from the tonic, minor?) of a key's scale, tonic first
DIATONIC_TRIADS = {
    False: ((0, False), (2, True), (4, True), (5, False), (7, False), (9, True)),  # I ii iii IV V vi
    True: ((0, True), (3, False), (5, True), (7, True), (8, False), (10, False)),  # i III iv v VI VII
}
PIANO, BASS = 0, 33
KICK, SNARE, HIHAT = 36, 38, 42

#: Chosen on the validation dances (docs/DUAL.md): a broad prior (the dance's strongest periodicity wins), its
#: period refined by the comb over multiples up to 8 s within ±8 %, then folded into [86, 172) BPM; beats tracked
#: with tightness 30 on the kinematic beats (bumps of σ 0.04 s) and locked to the tempo, their phase the median over
#: ±1 beat (LOCK_BEATS).
PRIOR_BPM = 90.0
PRIOR_OCTAVES = 2.0
FOLD_FROM: float | None = 86.0
COMB_SECONDS = 8.0
COMB_SPAN = 0.08
TIGHTNESS = 30.0
LOCK_BEATS = 1
LOCK_SHIFT: float | None = None
BEAT_WIDTH = 0.04


@dataclass
class DanceArrangement:
    """What :func:`follow_dance` made.

    Attributes
    ----------
    beat_times : (B,) beat times, s
    chords : [(root 0..11, minor)] one per beat (the bar's chord on each of its beats)
    tempo : BPM of the pulse (60 / median beat interval)
    duration : s
    midi : ``pretty_midi.PrettyMIDI`` with piano, bass and drum tracks
    key : (tonic 0..11, minor)
    beats_per_bar : 3 or 4
    bar_chords : [(root, minor)] one per bar
    """

    beat_times: np.ndarray
    chords: list[tuple[int, bool]]
    tempo: float
    duration: float
    midi: object
    key: tuple[int, bool]
    beats_per_bar: int
    bar_chords: list[tuple[int, bool]]

    def chord_names(self) -> list[str]:
        """One per beat, e.g. ``["C", "C", "C", "C", "Am", ...]``."""
        return [PITCH_CLASSES[r] + ("m" if m else "") for r, m in self.chords]

    def bar_chord_names(self) -> list[str]:
        """One per bar, e.g. ``["C", "F", "G", "C"]``."""
        return [PITCH_CLASSES[r] + ("m" if m else "") for r, m in self.bar_chords]

    def key_name(self) -> str:
        """E.g. ``"A minor"``."""
        return f"{PITCH_CLASSES[self.key[0]]} {'minor' if self.key[1] else 'major'}"


def key_scale(tonic: int, minor: bool) -> frozenset[int]:
    """The pitch classes of a key's scale (natural minor for a minor key)."""
    return frozenset((int(tonic) + s) % 12 for s in (MINOR_SCALE if minor else MAJOR_SCALE))


def key_triads(tonic: int, minor: bool) -> list[tuple[int, bool]]:
    """The six consonant triads (root, minor) of the key, tonic first (:data:`DIATONIC_TRIADS`)."""
    return [((int(tonic) + d) % 12, m) for d, m in DIATONIC_TRIADS[bool(minor)]]


def triad_pitches(root: int, minor: bool) -> tuple[int, int, int]:
    """MIDI pitches of a root-position triad from middle C (as :func:`dancekit.audio.midi.arrange` voices)."""
    return 60 + root, 60 + root + (3 if minor else 4), 60 + root + 7


# ---------------------------------------------------------------------------------------------- the pulse


def dance_pulse(speed: np.ndarray, *, fps: float, window: float = 1.0) -> np.ndarray:
    """The dance's pulse curve ``(T,)`` from its mean joint speed ``(T,)`` (any units): how far the speed dips
    below its local mean (a centred moving average over ``window`` s), relative to that mean, ≥ 0. It peaks at
    the kinematic beats (the speed's local minima), more for deeper dips."""
    s = np.asarray(speed, np.float64).reshape(-1)
    if fps <= 0 or window <= 0:
        raise ParameterError(f"dance_pulse needs fps > 0 and window > 0, got {fps}, {window}")
    if len(s) == 0:
        return s
    w = max(1, int(round(window * fps)))
    c = np.cumsum(np.pad(s, (1, 0)))
    i = np.arange(len(s))
    lo, hi = np.clip(i - w // 2, 0, len(s)), np.clip(i + (w - w // 2), 0, len(s))
    mean = (c[hi] - c[lo]) / (hi - lo)
    return np.maximum(mean - s, 0.0) / np.maximum(mean, 1e-9)


def beat_curve(times: np.ndarray, *, num_frames: int, fps: float, width: float = BEAT_WIDTH) -> np.ndarray:
    """A curve ``(num_frames,)`` at ``fps`` with a Gaussian bump of height 1 and standard deviation ``width`` s at
    each of ``times`` (s), summed: every beat counts the same, however deep the dip that made it."""
    t = np.arange(int(num_frames)) / float(fps)
    b = np.asarray(times, np.float64).reshape(-1)
    if fps <= 0 or width <= 0:
        raise ParameterError(f"beat_curve needs fps > 0 and width > 0, got {fps}, {width}")
    out = np.zeros(len(t))
    reach = 5.0 * width
    for x in b:  # each bump touches ±5σ only
        a, z = np.searchsorted(t, [x - reach, x + reach])
        out[a:z] += np.exp(-0.5 * ((t[a:z] - x) / width) ** 2)
    return out


def comb_period(acf: np.ndarray, lag: float, *, span: float, max_lag: float, step: float = 0.02) -> float:
    """The period (frames) within ``lag × (1 ± span)`` whose multiples ``k × period ≤ max_lag`` (``k ≥ 1``) have the
    highest mean autocorrelation ``acf`` (lags 0..n-1, read by linear interpolation), searched in ``step``-frame
    steps; ``lag`` itself when no multiple fits."""
    a = np.asarray(acf, np.float64)
    n = len(a)
    grid = np.arange(lag * (1.0 - span), lag * (1.0 + span) + step / 2, step)
    best, best_score = float(lag), -np.inf
    for period in grid:
        k = np.arange(1, int(min(max_lag, n - 2) // period) + 1)
        if not len(k):
            continue
        score = float(np.interp(k * period, np.arange(n), a).mean())
        if score > best_score:
            best, best_score = float(period), score
    return best


def _acf(x: np.ndarray) -> np.ndarray:
    """Unbiased autocorrelation of a centred signal (lags 0..n-1), by FFT."""
    n = len(x)
    x = x - x.mean()
    f = np.fft.rfft(x, 2 * n)
    return np.fft.irfft(f * np.conj(f))[:n] / np.arange(n, 0, -1)


def pulse_tempo(pulse: np.ndarray, *, fps: float, min_bpm: float = 40.0, max_bpm: float = 240.0,
                prior_bpm: float = PRIOR_BPM, prior_octaves: float = PRIOR_OCTAVES,
                fold_from: float | None = FOLD_FROM, comb_seconds: float = COMB_SECONDS,
                comb_span: float = COMB_SPAN) -> float:
    """The tempo (BPM) of a pulse curve: the autocorrelation peak (lags of ``60 / max_bpm`` to ``60 / min_bpm``
    s) weighted by a log-normal prior centred on ``prior_bpm`` with ``prior_octaves`` standard deviation
    (the rule that picks the metrical level, i.e. doubled or halved tempi), refined to a sub-frame lag by a
    parabola through the peak and its neighbours; then, with ``comb_seconds > 0``, refined again by
    :func:`comb_period` (within ±``comb_span`` of that lag, all its multiples up to ``comb_seconds`` s: a
    pattern of uneven steps moves the single peak, not the repeats of the whole pattern); then, unless
    ``fold_from`` is None, doubled or halved into ``[fold_from, 2 * fold_from)`` BPM. NaN for a flat curve or
    one shorter than two periods of ``min_bpm``."""
    x = np.asarray(pulse, np.float64).reshape(-1)
    if not 0 < min_bpm < max_bpm or fps <= 0 or prior_bpm <= 0 or prior_octaves <= 0:
        raise ParameterError(f"pulse_tempo needs 0 < min_bpm < max_bpm, fps > 0 and a positive prior; got "
                             f"{min_bpm}, {max_bpm}, {fps}, {prior_bpm}, {prior_octaves}")
    n = len(x)
    if n < 2 * 60.0 / min_bpm * fps or np.ptp(x) <= 1e-12:
        return float("nan")
    acf = _acf(x)
    lo, hi = max(1, int(np.floor(60.0 * fps / max_bpm))), min(n - 2, int(np.ceil(60.0 * fps / min_bpm)))
    lags = np.arange(lo, hi + 1)
    weight = np.exp(-0.5 * (np.log2(60.0 * fps / lags / prior_bpm) / prior_octaves) ** 2)
    a = acf[lags]
    peaks = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:])) + 1
    if not len(peaks):
        return float("nan")
    k = int(peaks[np.argmax(a[peaks] * weight[peaks])])
    lag = float(lags[k])
    y0, y1, y2 = acf[lags[k] - 1], acf[lags[k]], acf[lags[k] + 1]
    den = y0 - 2 * y1 + y2
    if den < 0:
        lag += float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
    if comb_seconds > 0:
        if not 0 < comb_span < 0.5:
            raise ParameterError(f"comb_span must be between 0 and 0.5, got {comb_span}")
        lag = comb_period(acf, lag, span=comb_span, max_lag=comb_seconds * fps)
    bpm = 60.0 * fps / lag
    if fold_from is not None:
        if not fold_from > 0:
            raise ParameterError(f"fold_from must be a positive BPM, got {fold_from}")
        while bpm < fold_from:
            bpm *= 2.0
        while bpm >= 2.0 * fold_from:
            bpm /= 2.0
    return float(bpm)


def pulse_metre(pulse: np.ndarray, *, fps: float, bpm: float) -> int:
    """3 or 4 beats to a bar: the pulse's autocorrelation at 3 beats against 4 beats (the larger wins; 4
    on a tie or a curve too short to tell)."""
    x = np.asarray(pulse, np.float64).reshape(-1)
    period = 60.0 * fps / float(bpm)
    if not np.isfinite(period) or len(x) < 8 * period + 2:
        return 4
    acf = _acf(x)
    at = {m: float(np.interp(m * period, np.arange(len(acf)), acf)) for m in (3, 4)}
    return 3 if at[3] > at[4] else 4


def track_beats(pulse: np.ndarray, *, fps: float, bpm: float, tightness: float = 100.0) -> np.ndarray:
    """Beat frames ``(B,)`` of a pulse curve at a given tempo: the dynamic programme of Ellis (2007) (the
    one librosa's beat tracker runs): each beat maximises the pulse at it plus ``-tightness *
    log(interval / period) ** 2`` over the best previous beat 0.5-2 periods before, back-traced from the
    best-scoring frame of the last period."""
    o = np.asarray(pulse, np.float64).reshape(-1)
    if not (np.isfinite(bpm) and bpm > 0) or fps <= 0:
        raise ParameterError(f"track_beats needs a positive tempo and fps, got {bpm}, {fps}")
    n = len(o)
    if n == 0:
        return np.zeros(0, np.int64)
    o = o / (o.std() + 1e-12)
    period = 60.0 * fps / float(bpm)
    offsets = np.arange(-int(round(2 * period)), -max(1, int(round(period / 2))) + 1)  # previous beat, frames back
    penalty = -float(tightness) * np.log(-offsets / period) ** 2
    score = o.copy()
    back = np.full(n, -1, np.int64)
    for i in range(n):
        z = i + offsets
        ok = z >= 0
        if not ok.any():
            continue
        cand = penalty[ok] + score[z[ok]]
        k = int(np.argmax(cand))
        score[i] = o[i] + cand[k]
        back[i] = z[ok][k]
    tail = max(0, n - int(np.ceil(period)))
    i = tail + int(np.argmax(score[tail:]))
    beats = []
    while i >= 0:
        beats.append(i)
        i = int(back[i])
    return np.asarray(beats[::-1], np.int64)


def lock_beats(frames: np.ndarray, *, fps: float, period: float, half_width: int = LOCK_BEATS,
               max_shift: float | None = LOCK_SHIFT) -> np.ndarray:
    """Beat times (s) exactly one ``period`` (s) apart, phased on tracked beat frames: beat ``k`` is at
    ``k × period + φ_k``. The tracked beats are numbered by their distance from the first in periods (a tracked
    beat on the number of the one before it is dropped, a skipped number filled); their phase is
    ``time - number × period``. ``φ_k`` is the median phase of the tracked beats numbered within ``half_width``
    of ``k``, but it moves only when that median is more than a frame (``1 / fps``) from ``φ_{k-1}``: the
    tracked beats lie on whole frames, so their phase wanders within a frame at any tempo that is not a whole
    number of frames, and following that would make the intervals whole frames (a tempo up to half a frame
    per beat off). So the intervals are the period except where the dance's phase really moves; there, with
    ``max_shift``, the phase moves by at most ``max_shift`` periods per beat (every interval within that share
    of the period: the pulse stays clear, and catches up with the dance over a few beats)."""
    f = np.asarray(frames, np.float64).reshape(-1) / float(fps)
    if not (np.isfinite(period) and period > 0) or fps <= 0 or half_width < 0:
        raise ParameterError(f"lock_beats needs period > 0, fps > 0 and half_width >= 0, got {period}, {fps}, "
                             f"{half_width}")
    if max_shift is not None and not 0 < max_shift < 0.5:
        raise ParameterError(f"lock_beats' max_shift must be between 0 and 0.5 periods, got {max_shift}")
    if len(f) < 2:
        return f
    number = np.round((f - f[0]) / period).astype(np.int64)
    keep = np.concatenate([[True], np.diff(number) > 0])
    f, number = f[keep], number[keep]
    phase = f - number * period
    k = np.arange(number[0], number[-1] + 1)
    lo = np.searchsorted(number, k - half_width, side="left")
    hi = np.searchsorted(number, k + half_width, side="right")
    have = hi > lo
    target = np.array([np.median(phase[a:b]) if b > a else np.nan for a, b in zip(lo, hi)])
    if not have.all():  # a gap wider than the window: the phase of the nearest numbers on either side, interpolated
        target = np.interp(k, k[have], target[have])
    phi = np.empty(len(k))
    phi[0] = target[0]
    frame = 1.0 / float(fps)
    step = np.inf if max_shift is None else float(max_shift) * period
    for i in range(1, len(k)):
        move = target[i] - phi[i - 1]
        phi[i] = phi[i - 1] + float(np.clip(move, -step, step)) if abs(move) > frame + 1e-9 else phi[i - 1]
    return k * period + phi


# ---------------------------------------------------------------------------------------------- the music


def _bar_chords(bars: list[tuple[int, int]], chroma: np.ndarray | None, key: tuple[int, bool]) -> list[tuple[int, bool]]:
    """One triad of the key per bar (frame spans): nearest (cosine) the bar's mean chroma; tonic first and last."""
    triads = key_triads(*key)
    out = []
    for b, (a, z) in enumerate(bars):
        if b == 0 or b == len(bars) - 1 or chroma is None or z <= a:
            out.append(triads[0])
            continue
        c = np.asarray(chroma[a:z], np.float64).mean(0)
        c = c - c.mean()
        scores = []
        for r, m in triads:
            t = np.zeros(12)
            t[[r, (r + (3 if m else 4)) % 12, (r + 7) % 12]] = 1.0
            t -= t.mean()
            scores.append(float(c @ t) / (np.linalg.norm(c) * np.linalg.norm(t) + 1e-12))
        out.append(triads[int(np.argmax(scores))])
    return out


def follow_dance(pulse: np.ndarray, *, fps: float, key: tuple[int, bool], chroma: np.ndarray | None = None,
                 activation: np.ndarray | None = None, bpm: float | None = None, beats_per_bar: int | None = None,
                 prior_bpm: float = PRIOR_BPM, prior_octaves: float = PRIOR_OCTAVES,
                 fold_from: float | None = FOLD_FROM, phase_pulse: np.ndarray | None = None,
                 metre_pulse: np.ndarray | None = None, tightness: float = TIGHTNESS, lock: int = LOCK_BEATS,
                 lock_shift: float | None = LOCK_SHIFT,
                 fallback_bpm: float = 120.0) -> DanceArrangement:
    """Music for a dance (see the module docstring).

    Parameters
    ----------
    pulse : (T,) the dance's pulse curve at ``fps`` (:func:`dance_pulse`)
    fps : frames per second of ``pulse``, ``chroma`` and ``activation``
    key : (tonic 0..11, minor): the key every chord belongs to
    chroma : (T, 12) composed chroma (G_D→M) choosing each bar's chord, or None (tonic throughout)
    activation : (T,) composed beat activation (G_D→M) setting accents and piano density, or None (even)
    bpm : a tempo kept exactly (a regular grid phased on ``phase_pulse``), or None: :func:`pulse_tempo`'s
        tempo and beats tracked at it
    beats_per_bar : 3 or 4, or None: :func:`pulse_metre`
    prior_bpm, prior_octaves, fold_from : the tempo rule (:func:`pulse_tempo`; its comb at the module's defaults)
    phase_pulse : (T,) the curve the beats are tracked on, or None: ``pulse``
    metre_pulse : (T,) the curve the metre and the bars' downbeats are read from, or None: ``phase_pulse``
    tightness : :func:`track_beats`' penalty on uneven beats
    lock : :func:`lock_beats`' half width, beats (the tracked beats' phase is their median over ±``lock``)
    lock_shift : :func:`lock_beats`' ``max_shift``: the most the phase moves per beat, periods (None: unlimited)
    fallback_bpm : the tempo of a pulse without periodicity (a still or very short dance)

    Returns
    -------
    :class:`DanceArrangement`
    """
    import pretty_midi

    from dancekit.audio.midi import midi_file_tempo

    p = np.asarray(pulse, np.float64).reshape(-1)
    T = len(p)
    if T == 0 or fps <= 0:
        raise ParameterError(f"follow_dance needs a non-empty pulse and fps > 0, got {T} frames at {fps}")
    if chroma is not None and np.shape(chroma) != (T, 12):
        raise ParameterError(f"chroma must be ({T}, 12), got {np.shape(chroma)}")
    if activation is not None and np.shape(activation) != (T,):
        raise ParameterError(f"activation must be ({T},), got {np.shape(activation)}")
    if beats_per_bar not in (None, 3, 4):
        raise ParameterError(f"beats_per_bar must be 3 or 4, got {beats_per_bar!r}")
    q = p if phase_pulse is None else np.asarray(phase_pulse, np.float64).reshape(-1)
    if len(q) != T:
        raise ParameterError(f"phase_pulse must have the pulse's {T} frames, got {len(q)}")
    mq = q if metre_pulse is None else np.asarray(metre_pulse, np.float64).reshape(-1)
    if len(mq) != T:
        raise ParameterError(f"metre_pulse must have the pulse's {T} frames, got {len(mq)}")
    tonic, minor = int(key[0]) % 12, bool(key[1])
    duration = T / float(fps)
    fixed = bpm is not None
    if bpm is None:
        bpm = pulse_tempo(p, fps=fps, prior_bpm=prior_bpm, prior_octaves=prior_octaves, fold_from=fold_from)
    elif not (np.isfinite(bpm) and 20.0 <= float(bpm) <= 400.0):
        raise ParameterError(f"tempo must be between 20 and 400 BPM, got {bpm}")
    if fixed:  # a given tempo is kept exactly: a grid, phased where the phase pulse is strongest on average
        step = 60.0 / float(bpm)
        t = np.arange(T) / float(fps)
        phases = np.arange(0.0, step, 0.5 / fps)
        score = [np.interp(np.arange(ph, duration, step), t, q).mean() if ph < duration else -1.0 for ph in phases]
        times = np.arange(phases[int(np.argmax(score))], duration, step)
        if len(times) == 0:
            times = np.zeros(1)
    elif not np.isfinite(bpm) or np.ptp(p) <= 1e-12:
        bpm = float(fallback_bpm)
        times = np.arange(0.0, duration, 60.0 / bpm)
    else:
        times = lock_beats(track_beats(q, fps=fps, bpm=float(bpm), tightness=tightness), fps=fps,
                           period=60.0 / float(bpm), half_width=int(lock), max_shift=lock_shift)
        times = times[(times >= 0) & (times < duration)]
        if len(times) < 2:
            times = np.arange(0.0, duration, 60.0 / float(bpm))
    period = 60.0 / float(bpm) if fixed else (float(np.median(np.diff(times))) if len(times) >= 2 else 60.0 / float(bpm))
    bpb = beats_per_bar or pulse_metre(mq, fps=fps, bpm=60.0 / period)
    ends = np.append(times[1:], min(duration, times[-1] + period))
    # bars: the first downbeat is the beat where the pulse is strongest over the bar phases
    frame = np.clip(np.round(times * fps).astype(int), 0, T - 1)
    first = int(np.argmax([mq[frame[ph::bpb]].mean() if len(frame[ph::bpb]) else -1.0 for ph in range(bpb)]))
    starts = sorted(set([0] + list(range(first, len(times), bpb))))
    bar_of_beat = np.searchsorted(starts, np.arange(len(times)), side="right") - 1
    spans = []
    for b, s in enumerate(starts):
        e = starts[b + 1] if b + 1 < len(starts) else len(times)
        spans.append((int(frame[s]), int(min(T, np.ceil(ends[e - 1] * fps)))))
    bar_chords = _bar_chords(spans, chroma, (tonic, minor))
    act = None if activation is None else np.asarray(activation, np.float64)
    if act is not None:
        at_beat = np.array([act[max(0, f - 2): f + 3].max() for f in frame])
        lo_, hi_ = np.percentile(at_beat, [10, 90]) if len(at_beat) else (0.0, 1.0)
        accent = np.clip((at_beat - lo_) / max(hi_ - lo_, 1e-9), 0.0, 1.0)
        bar_act = np.array([at_beat[bar_of_beat == b].mean() for b in range(len(starts))])
        sparse_bar = bar_act < np.median(bar_act)
    else:
        accent = np.full(len(times), 0.5)
        sparse_bar = np.zeros(len(starts), bool)

    pm = pretty_midi.PrettyMIDI(initial_tempo=midi_file_tempo(60.0 / period))
    piano = pretty_midi.Instrument(program=PIANO, name="chords")
    bass = pretty_midi.Instrument(program=BASS, name="bass")
    drums = pretty_midi.Instrument(program=0, is_drum=True, name="drums")
    chords: list[tuple[int, bool]] = []
    for i, (t0, t1) in enumerate(zip(times, ends)):
        b = int(bar_of_beat[i])
        pos = i - starts[b]  # beat of the bar
        root, m = bar_chords[b]
        chords.append((root, m))
        v = float(accent[i])
        downbeat = pos == 0
        if not sparse_bar[b] or downbeat:
            bar_end = ends[(starts[b + 1] if b + 1 < len(starts) else len(times)) - 1]
            end = t1 if not sparse_bar[b] else bar_end
            for pitch in triad_pitches(root, m):
                piano.notes.append(pretty_midi.Note(velocity=int(round((74 if downbeat else 62) + 16 * v)),
                                                    pitch=pitch, start=float(t0), end=float(end)))
        fifth = bpb == 4 and pos == 2
        bass.notes.append(pretty_midi.Note(velocity=int(round(84 + 20 * v)), pitch=36 + root + (7 if fifth else 0),
                                           start=float(t0), end=float(t0 + 0.9 * (t1 - t0))))
        drum = KICK if downbeat or (bpb == 4 and pos == 2) else SNARE
        drums.notes.append(pretty_midi.Note(velocity=int(round((100 if downbeat else 84) + 20 * v)), pitch=drum,
                                            start=float(t0), end=float(t0 + 0.1)))
        drums.notes.append(pretty_midi.Note(velocity=int(round(60 + 20 * v)), pitch=HIHAT, start=float(t0),
                                            end=float(t0 + 0.05)))
    pm.instruments.extend([piano, bass, drums])
    return DanceArrangement(beat_times=np.asarray(times, np.float64), chords=chords, tempo=60.0 / period,
                            duration=duration, midi=pm, key=(tonic, minor), beats_per_bar=int(bpb),
                            bar_chords=bar_chords)
