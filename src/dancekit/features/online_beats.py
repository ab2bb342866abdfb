"""A causal beat and tempo tracker (:class:`BeatTracker`): a phase-locked estimate that updates every beat.

It reads an onset envelope as it arrives (spectral flux at ``rate`` Hz, :class:`dancekit.live.OnlineFeatures`
makes one at 100 Hz) and keeps ``window_s`` of it:

* **tempo**: the autocorrelation of the window over lags of 60-200 BPM (plus half of it at twice the lag: a
  beat's period repeats at two beats), weighted by a log-normal prior around 120 BPM (0.7 octave wide), refined
  to a fraction of a frame by a parabola through the peak; re-estimated at every beat, kept unless another
  tempo scores clearly better (hysteresis) and smoothed over the last few (a median);
* **phase**: a comb of the estimated period over the window (the envelope summed at ``t - φ - k·P``, the
  recent teeth weighted more): the beat nearest the predicted one is placed where the comb peaks;
* each beat is placed ``delay_s`` after its predicted time (the lookahead it may see) and the next one is
  predicted one period later — a phase-locked loop whose correction is the comb's.

Before ``warmup_s`` of envelope, or once the pulse has been too weak for 3 s (the autocorrelation peak under
``min_clarity``: silence, speech), no beat is placed and :attr:`clarity` says so; a weaker moment within a
song keeps the beat going.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["Beat", "BeatTracker"]


@dataclass(frozen=True)
class Beat:
    """A beat placed by the tracker: ``time`` (s from the stream's start), ``bpm`` the tempo then,
    ``downbeat`` whether it starts a bar (4 beats, the bar phase of the strongest accents)."""

    time: float
    bpm: float
    downbeat: bool = False


class BeatTracker:
    """Causal beat tracker over an onset envelope at ``rate`` Hz (see the module's description).

    Parameters
    ----------
    rate : envelope frames per second
    delay_s : how long after a beat's time the tracker decides where it was (s, ≥ 0)
    window_s : envelope history for the tempo and the phase (s)
    warmup_s : envelope needed before the first beat (s)
    min_bpm, max_bpm : the tempo range
    min_clarity : the normalised autocorrelation peak under which no beat is placed
    offset_s : added to every beat time (s): the envelope's own delay (a spectral flux peaks before the onset
        reaches its window's centre)
    """

    def __init__(self, *, rate: float, delay_s: float = 0.1, window_s: float = 6.0, warmup_s: float = 3.0,
                 min_bpm: float = 60.0, max_bpm: float = 200.0, min_clarity: float = 0.1, offset_s: float = 0.0):
        self.rate = float(rate)
        self.offset = float(offset_s)
        self.delay = int(round(delay_s * rate))
        self.window = int(round(window_s * rate))
        self.warmup = int(round(warmup_s * rate))
        self.min_lag = int(np.floor(60.0 * rate / max_bpm))
        self.max_lag = int(np.ceil(60.0 * rate / min_bpm))
        self.min_clarity = float(min_clarity)
        lags = np.arange(self.min_lag, self.max_lag + 1, dtype=np.float64)
        bpms = 60.0 * rate / lags
        self.prior = np.exp(-0.5 * (np.log2(bpms / 120.0) / 0.7) ** 2)  # around 120 BPM, 0.7 octave wide
        self.keep = 0.75  # the current tempo stays while its score is at least this share of the best
        self.env: deque[float] = deque(maxlen=self.window)
        self.n = 0  # envelope frames received
        self.next_beat: float | None = None  # predicted time of the next beat (frames)
        self.periods: deque[float] = deque(maxlen=5)
        self.period: float | None = None
        self.clarity = 0.0
        self.beats: list[Beat] = []  # every beat placed (times in s)
        self._accents = np.zeros(4)  # envelope at the beats, per bar position
        self._count = 0
        self._weak = 0  # beats in a row with a weak pulse
        self.lose = 3.0  # s of weak pulse after which the tracker lets go of the beat

    @property
    def bpm(self) -> float | None:
        """The current tempo estimate (BPM), None before the first."""
        return None if self.period is None else 60.0 * self.rate / self.period

    @property
    def warming_up(self) -> bool:
        """True before ``warmup_s`` of envelope: the tracker cannot tell a pulse yet (:attr:`clarity` is 0)."""
        return self.n < self.warmup

    @property
    def pulse(self) -> bool:
        """Whether the sound may have a pulse: while warming up (not known yet), or a clear one
        (:attr:`clarity` at least ``min_clarity``)."""
        return self.warming_up or self.clarity >= self.min_clarity

    @property
    def next_time(self) -> float | None:
        """The predicted time (s) of the next beat, None while the tracker has no beat."""
        return None if self.next_beat is None else self.next_beat / self.rate + self.offset

    def feed(self, env: np.ndarray) -> list[Beat]:
        """Append envelope frames; returns the beats placed meanwhile."""
        out = []
        for v in np.asarray(env, np.float64).reshape(-1):
            self.env.append(float(v))
            self.n += 1
            if self.n < self.warmup:
                continue
            if self.next_beat is None:
                if self._estimate():
                    phase_beat = self._comb(self.n - 1)
                    self.next_beat = phase_beat + self.period
                    while self.next_beat < self.n - 1 - self.delay:
                        self.next_beat += self.period
                continue
            if self.n - 1 >= self.next_beat + self.delay:
                beat = self._place()
                if beat is not None:
                    out.append(beat)
        return out

    def _estimate(self) -> bool:
        """Re-estimate the period from the window's autocorrelation; False when the pulse is too weak."""
        x = np.asarray(self.env, np.float64)
        x = x - x.mean()
        denom = float(np.dot(x, x))
        if denom <= 1e-12:
            self.clarity = 0.0
            return False
        n = len(x)
        f = np.fft.rfft(x, n=2 * n)
        ac = np.fft.irfft(f * np.conj(f))[: 2 * self.max_lag + 3] / denom
        lags = np.arange(self.min_lag, self.max_lag + 1)
        seg = ac[lags]
        # the lag and its double (a beat's period also repeats at two beats): the slower octave loses to it
        score = (np.maximum(seg, 0.0) + 0.5 * np.maximum(ac[2 * lags], 0.0)) * self.prior
        k = int(np.argmax(score))
        if self.period is not None:  # hysteresis: keep the current tempo unless another is clearly better
            near = np.abs(lags - self.period) <= max(2.0, 0.04 * self.period)
            kc = int(np.flatnonzero(near)[np.argmax(score[near])]) if near.any() else k
            if score[kc] >= self.keep * score[k]:
                k = kc
        self.clarity = float(seg[k])
        if self.clarity < self.min_clarity:
            return False
        lag = float(self.min_lag + k)
        if 0 < k < len(seg) - 1:  # a parabola through the peak
            a, b, c = seg[k - 1], seg[k], seg[k + 1]
            d = a - 2 * b + c
            if d < 0:
                lag += 0.5 * (a - c) / d
        self.periods.append(lag)
        self.period = float(np.median(self.periods))
        return True

    def _comb(self, now: int) -> float:
        """The time (frames) of the most recent beat of the comb of period :attr:`period` that best fits the
        envelope up to frame ``now``."""
        x = np.asarray(self.env, np.float64)
        start = self.n - len(x)  # frame index of x[0]
        P = self.period
        phases = np.arange(0, int(np.ceil(P)))
        teeth = int((len(x) - 1) // P)
        best, best_score = 0.0, -np.inf
        k = np.arange(teeth + 1)
        weights = 0.85 ** k
        for phi in phases:
            pos = now - phi - k * P - start
            ok = pos >= 0
            idx = np.round(pos[ok]).astype(int)
            s = float(np.dot(x[idx], weights[ok]))
            if s > best_score:
                best, best_score = float(phi), s
        return float(now - best)

    def _place(self) -> Beat | None:
        """Place the beat predicted at :attr:`next_beat` (now ``delay`` frames after it) where the comb puts
        it, then predict the next one a period later."""
        if not self._estimate():  # a weak pulse for a moment: keep the beat; for a few seconds: let go
            self._weak += 1
            if self._weak * self.period > self.lose * self.rate:
                self.next_beat, self._weak = None, 0
                self.periods.clear()
                return None
        else:
            self._weak = 0
        now = self.n - 1
        last = self._comb(now)
        P = self.period
        m = np.round((self.next_beat - last) / P)
        t = last + m * P
        if abs(t - self.next_beat) > 0.5 * P:  # pragma: no cover - the rounding keeps it within half a period
            t = self.next_beat
        self.next_beat = t + P
        x = np.asarray(self.env)
        i = int(round(t)) - (self.n - len(x))
        accent = float(x[i]) if 0 <= i < len(x) else 0.0
        pos = self._count % 4
        self._accents[pos] = 0.8 * self._accents[pos] + accent
        self._count += 1
        downbeat = pos == int(np.argmax(self._accents))
        beat = Beat(time=t / self.rate + self.offset, bpm=60.0 * self.rate / P, downbeat=bool(downbeat))
        self.beats.append(beat)
        if len(self.beats) > 64:
            del self.beats[:-64]
        return beat
