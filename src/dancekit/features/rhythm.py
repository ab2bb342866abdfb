"""Beats, downbeats and their one-hot frame encodings.

Beat tracking runs on a fine grid, independent of the motion frame rate:
the audio is resampled to :data:`BEAT_SR` (22050 Hz) and the onset envelope
uses a hop of :data:`BEAT_HOP` (256 samples, ~86 envelope frames per
second). Running librosa's tracker directly on the motion-rate grid
(e.g. ``sr = 15 * 512``, 15 envelope frames per second) halves or skews the
tempo (a 120 BPM click track reads as ~60 or ~128 BPM). Beat *times* in
seconds are then mapped onto any frame grid with ``round(t * fps)``
(:func:`beat_onehot`).

Downbeats (librosa backend) are estimated from the beats by folding a
beat-synchronous accent over candidate meters; see :func:`downbeats`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dancekit.audio.io import resample
from dancekit.errors import ParameterError
from dancekit.features import dsp as _dsp

__all__ = ["BEAT_HOP", "BEAT_SR", "MUSIC_BEAT_STRENGTH", "beat_onehot", "beat_strength", "beat_track", "downbeats",
           "fold_meter"]

#: Sample rate (Hz) of the fine grid used for beat tracking.
BEAT_SR = 22050
#: Hop (samples at :data:`BEAT_SR`) of the onset envelope used for beat tracking.
BEAT_HOP = 256
BEAT_NFFT = 2048
_EDGE_PAD_S = 2.0

#: Beat strength (:func:`beat_strength`) below which audio "does not look like music": chosen between the
#: real songs of ../shared/music (lowest: 0.215, Brahms' Hungarian dance, string orchestra) and the
#: non-music inputs (highest: 0.157, synthetic speech-like babble; robin 0.152, humpback 0.101, white
#: noise 0.099-0.109, silence 0); see docs/FEATURES.md.
MUSIC_BEAT_STRENGTH = 0.19


def to_beat_sr(y: np.ndarray, sr: int) -> np.ndarray:
    return resample(np.asarray(y, dtype=np.float32), orig_sr=int(sr), target_sr=BEAT_SR)


def fine_log_mel(y_fine: np.ndarray, n_mels: int = 128) -> np.ndarray:
    from dancekit.features.spectral import mel_power

    # a few thousand frames at a time: no full-song complex STFT in memory
    M = mel_power(y=y_fine, sr=BEAT_SR, n_fft=BEAT_NFFT, hop_length=BEAT_HOP, n_mels=n_mels)
    return _dsp.power_to_db(M).astype(np.float32)


def _onset_chunked(S_db: np.ndarray, *, hop_length: int, aggregate, chunk: int = 8192) -> np.ndarray:
    """``_dsp.onset_strength(S_db, n_fft=BEAT_NFFT, hop_length=hop_length, aggregate=aggregate)`` (librosa's
    centred envelope, lag 1) computed ``chunk`` frames at a time: each value is the aggregated positive
    difference of two neighbouring frames, so chunks overlapping by one frame (``center=False``) give the
    same values without the two full-size difference arrays (2 x 160 MB for an hour at the beat grid).
    float32 (T,)."""
    T = S_db.shape[-1]
    raw = np.zeros(T, np.float32)  # raw[j]: frame j against frame j - 1
    for a in range(1, T, int(chunk)):
        b = min(T, a + int(chunk))
        o = _dsp.onset_strength(S_db[:, a - 1: b], n_fft=BEAT_NFFT, hop_length=hop_length, aggregate=aggregate,
                                center=False)
        raw[a:b] = o[1:]
    pad = 1 + BEAT_NFFT // (2 * hop_length)  # the centring shift
    env = np.zeros(T, np.float32)
    env[pad:] = raw[1: T - pad + 1]
    return env


def fine_onset_chunked(S_db: np.ndarray, aggregate=np.median) -> np.ndarray:
    """:func:`fine_onset` in chunks (:func:`_onset_chunked`): the same envelope."""
    return _onset_chunked(S_db, hop_length=BEAT_HOP, aggregate=aggregate)


def fine_onset(S_db: np.ndarray, aggregate=np.median) -> np.ndarray:
    return _dsp.onset_strength(S_db, n_fft=BEAT_NFFT, hop_length=BEAT_HOP, aggregate=aggregate).astype(np.float32)


def beat_track(
    *, y: np.ndarray, sr: int, start_bpm: float = 120.0, tightness: float = 100.0
) -> tuple[float, np.ndarray]:
    """Track beats on the fine grid (22050 Hz, hop 256) with librosa's dynamic-programming tracker
    (re-implemented in NumPy: :func:`dancekit.features.dsp.beat_track`).

    Parameters
    ----------
    y : np.ndarray, shape (n,)
        Audio at ``sr``; it is resampled to :data:`BEAT_SR` internally.
    sr : int
        Sample rate of ``y`` in Hz.
    start_bpm : float
        Centre of librosa's log-normal tempo prior in BPM (one octave wide):
        tempos far from it may be read at half or double speed.
    tightness : float
        How strictly the tracker keeps to the estimated tempo.

    Returns
    -------
    tempo : float
        Global tempo estimate in BPM (0.0 when no beat is found, e.g. silence).
    beat_times : np.ndarray, float64, shape (n_beats,)
        Beat times in seconds from the start of ``y``, increasing.
    """
    S_db = fine_log_mel(to_beat_sr(y, sr))
    return beat_track_fine(S_db, fine_onset(S_db), start_bpm=start_bpm, tightness=tightness)


def _estimate_tempo(S_db: np.ndarray, env: np.ndarray, *, start_bpm: float) -> float:
    """Global tempo in BPM from the fine-grid log-mel spectrogram and onset envelope.

    Two steps: librosa's default estimator (mean-aggregated onset envelope
    at 22050 Hz / hop 512, the setting its tempo prior was tuned for; the
    hop-512 spectrogram is every other frame of the hop-256 one) picks the
    metrical level; the global autocorrelation of the hop-256 envelope,
    weighted by a narrow log-normal prior (0.1 octave) around that value,
    refines it to twice the lag resolution (a 120 BPM click reads 120.2
    instead of 117.5 BPM).
    """
    env512 = _onset_chunked(S_db[:, ::2], hop_length=2 * BEAT_HOP, aggregate=np.mean)  # in chunks
    if not np.any(env512 > 0):
        env512 = env[::2]
    from dancekit.features.spectral import tempogram_mean

    # librosa.feature.tempo(onset_envelope=env512, ...) (_dsp.tempo), its mean tempogram summed in chunks (a
    # whole-song tempogram at this rate is ~1 GB for an hour of music)
    win = _dsp.tempo_win_length(sr=BEAT_SR, hop_length=2 * BEAT_HOP)  # librosa's ac_size 8 s
    coarse = _dsp.tempo_from_tempogram(tempogram_mean(onset_envelope=env512, win_length=win), sr=BEAT_SR,
                                       hop_length=2 * BEAT_HOP, start_bpm=start_bpm)
    frame_rate = BEAT_SR / BEAT_HOP
    ac = _dsp.autocorrelate(env.astype(np.float64))
    lags = np.arange(1, ac.size)
    bpm = 60.0 * frame_rate / lags
    prior = np.exp(-0.5 * ((np.log2(bpm) - np.log2(coarse)) / 0.1) ** 2)
    return float(bpm[np.argmax(ac[1:] * prior)])


def beat_track_fine(
    S_db: np.ndarray, env: np.ndarray, *, start_bpm: float = 120.0, tightness: float = 100.0
) -> tuple[float, np.ndarray]:
    """Beat tracking on the fine grid (log-mel spectrogram and onset envelope at hop 256).

    The tracker runs on the envelope padded with 2 s of zeros on both sides,
    which removes librosa's edge effect (a first or last beat up to ~0.1 s
    early when a beat falls within a few tenths of a second of either end).
    """
    if not np.any(env > 0):
        return 0.0, np.zeros(0, dtype=np.float64)
    tempo = _estimate_tempo(S_db, env, start_bpm=start_bpm)
    pad = int(round(_EDGE_PAD_S * BEAT_SR / BEAT_HOP))
    frames = _dsp.beat_track(np.pad(env, (pad, pad)), bpm=tempo, frame_rate=float(BEAT_SR) / BEAT_HOP,
                             tightness=tightness) - pad
    frames = frames[(frames >= 0) & (frames < env.shape[-1])]
    times = (frames * BEAT_HOP).astype(int) / float(BEAT_SR)
    return tempo, times


def beat_strength(
    *, onset_envelope: np.ndarray, rate: float, window_s: float = 8.0, min_bpm: float = 60.0,
    max_bpm: float = 200.0
) -> float:
    """How strongly an onset envelope pulses at a danceable tempo: 0 (no beat) … 1 (a metronome).

    The envelope is cut into windows of ``window_s`` seconds (half-overlapping); in each, the peak of the
    normalised autocorrelation of the mean-removed envelope over lags of one beat at ``max_bpm`` … ``min_bpm``
    is taken (negative peaks count as 0); the result is the median over windows. A clip shorter than one
    window is scored on its whole length and scaled by ``sqrt(duration / window_s)``: the autocorrelation of
    an unstructured envelope fluctuates as ``1 / sqrt(length)``, so a short clip must pulse more clearly.

    Parameters
    ----------
    onset_envelope : np.ndarray, float, shape (n,)
        Onset strength, e.g. ``librosa.onset.onset_strength`` on the beat-tracking grid
        (:data:`BEAT_SR` / :data:`BEAT_HOP` ≈ 86.1 frames per second).
    rate : float
        Envelope frames per second (> 0).
    window_s, min_bpm, max_bpm : float
        Window length in seconds and the tempo range in beats per minute.

    Returns
    -------
    float
        In [0, 1] (up to rounding); 0 for silence or a constant envelope. Music scores about 0.2–0.6,
        a click track about 0.9; white noise about 0.1. :data:`MUSIC_BEAT_STRENGTH` is the threshold
        dancekit uses.
    """
    env = np.asarray(onset_envelope, dtype=np.float64).reshape(-1)
    if not rate > 0 or not 0 < min_bpm < max_bpm or not window_s > 0:
        raise ParameterError(f"need rate > 0, 0 < min_bpm < max_bpm and window_s > 0; got rate={rate}, "
                             f"min_bpm={min_bpm}, max_bpm={max_bpm}, window_s={window_s}")
    n, w = env.size, max(2, int(round(window_s * rate)))
    lo, hi = max(1, int(round(60.0 / max_bpm * rate))), int(round(60.0 / min_bpm * rate))
    if n < lo + 2:
        return 0.0
    starts = [0] if n <= w else range(0, n - w + 1, max(1, w // 2))
    width = min(w, n)
    peaks = []
    for a in starts:
        x = env[a:a + width] - env[a:a + width].mean()
        spec = np.fft.rfft(x, 2 * width)
        ac = np.fft.irfft(spec.real**2 + spec.imag**2)[:width]
        if not ac[0] > 1e-12 * width:
            peaks.append(0.0)
            continue
        peaks.append(max(0.0, float(ac[lo:hi + 1].max() / ac[0])))
    return float(np.median(peaks)) * float(np.sqrt(min(1.0, n / w)))


def beat_onehot(*, beat_times: np.ndarray, fps: float, n_frames: int) -> np.ndarray:
    """Mark beats on a frame grid: frame ``round(t * fps)`` is 1, all others 0.

    Beats that land outside ``[0, n_frames)`` are dropped.

    Returns
    -------
    np.ndarray, float32, shape (n_frames,)
    """
    out = np.zeros(int(n_frames), dtype=np.float32)
    t = np.asarray(beat_times, dtype=np.float64)
    if t.size:
        idx = np.round(t * float(fps)).astype(np.int64)
        idx = idx[(idx >= 0) & (idx < n_frames)]
        out[idx] = 1.0
    return out


def fold_meter(
    accent: np.ndarray, *, meters: Sequence[int] = (2, 3, 4)
) -> tuple[int, int, dict[tuple[int, int], float]]:
    """Choose the meter and phase whose every-``m``-th beat is most accented.

    For each meter ``m`` and phase ``p < m``, the score is
    ``mean(accent[p::m]) - mean(accent[other beats])``. The best-scoring
    ``(m, p)`` wins; meter 4 is preferred over meter 2 when its best score is
    within 10 % of meter 2's (a strong third beat in 4/4 otherwise reads as
    2/4). Meters need at least ``2 * m`` beats to compete.

    Parameters
    ----------
    accent : np.ndarray, shape (n_beats,)
        Accent strength of each beat (any scale).

    Returns
    -------
    meter, phase : int
        Downbeats are beats ``phase, phase + meter, ...``. ``(1, 0)`` if there
        are too few beats for any meter.
    scores : dict
        ``{(m, p): score}`` for every candidate tried.
    """
    a = np.asarray(accent, dtype=np.float64)
    scores: dict[tuple[int, int], float] = {}
    for m in meters:
        if int(m) != m or m < 2:
            raise ParameterError(f"meters must be integers >= 2, got {m!r}")
        if a.size < 2 * m:
            continue
        for p in range(m):
            mask = np.zeros(a.size, dtype=bool)
            mask[p::m] = True
            scores[(int(m), p)] = float(a[mask].mean() - a[~mask].mean())
    if not scores:
        return 1, 0, scores
    best = max(scores, key=lambda k: (scores[k], k[0]))
    if best[0] == 2 and any(k[0] == 4 for k in scores):
        best4 = max((k for k in scores if k[0] == 4), key=lambda k: scores[k])
        if scores[best4] >= 0.9 * scores[best]:
            best = best4
    return best[0], best[1], scores


def _zscore(x: np.ndarray) -> np.ndarray:
    sd = float(x.std())
    return (x - x.mean()) / sd if sd > 1e-8 * max(1.0, float(np.abs(x).max())) else np.zeros_like(x)


def _beat_accents(S_db: np.ndarray, env: np.ndarray, beat_frames: np.ndarray) -> np.ndarray:
    """Accent per beat on the fine grid: z-scored onset, low-band onset, low-band energy and harmonic change."""
    T = S_db.shape[1]
    freqs = _dsp.mel_frequencies(S_db.shape[0], fmax=BEAT_SR / 2)
    low = freqs < 200.0
    env_low = _dsp.onset_strength(S_db[low], n_fft=BEAT_NFFT, hop_length=BEAT_HOP, aggregate=np.mean)
    # window around each beat: 2 frames before to 4 after (about -23 ms .. +46 ms)
    win = np.arange(-2, 5)
    idx = np.clip(beat_frames[:, None] + win[None, :], 0, T - 1)
    onset = env[idx].max(axis=1)
    onset_low = env_low[idx].max(axis=1)
    # beat-synchronous spans [b_k, b_{k+1}) for energy and harmonic content
    bounds = np.concatenate([beat_frames, [T]])
    low_energy = np.array([S_db[low, a : max(b, a + 1)].mean() for a, b in zip(bounds[:-1], bounds[1:])])
    spec = np.stack(
        [S_db[~low, a : max(b, a + 1)].mean(axis=1) for a, b in zip(bounds[:-1], bounds[1:])], axis=0
    )
    spec = spec - spec.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(spec, axis=1) + 1e-9
    cos = np.sum(spec[1:] * spec[:-1], axis=1) / (norm[1:] * norm[:-1])
    change = np.concatenate([[np.nan], 1.0 - cos])
    change[0] = np.nanmax(change) if change.size > 1 else 0.0
    return _zscore(onset) + _zscore(onset_low) + _zscore(low_energy) + _zscore(change)


def downbeats(
    *, y: np.ndarray, sr: int, beat_times: np.ndarray, meters: Sequence[int] = (2, 3, 4)
) -> np.ndarray:
    """Estimate which beats are downbeats (first beat of a bar) from a beat sequence.

    Method: on the fine grid (22050 Hz, hop 256) each beat gets an accent
    that sums four z-scored cues, all standard downbeat correlates:
    the onset strength around the beat, the onset strength of the bands
    below 200 Hz (kick drum, bass), the mean low-band energy over the
    beat's span, and the spectral change from the previous beat's span
    (chords change on bar lines). The accent sequence is folded over the
    candidate ``meters`` and phases by :func:`fold_meter`, and the beats at
    the winning phase and period are the downbeats. The meter is assumed
    constant over the excerpt.

    Parameters
    ----------
    y : np.ndarray, shape (n,)
        Audio at ``sr`` (resampled to :data:`BEAT_SR` internally).
    sr : int
        Sample rate of ``y`` in Hz.
    beat_times : np.ndarray, shape (n_beats,)
        Beat times in seconds (e.g. from :func:`beat_track`).
    meters : sequence of int
        Candidate beats per bar.

    Returns
    -------
    np.ndarray, float64, shape (n_downbeats,)
        Downbeat times in seconds, a subset of ``beat_times``. With fewer
        than 4 beats only the first beat is returned; with none, none.
    """
    y_fine = to_beat_sr(y, sr)
    S_db = fine_log_mel(y_fine)
    return downbeats_fine(S_db, fine_onset(S_db), np.asarray(beat_times, dtype=np.float64), meters=meters)


def downbeats_fine(
    S_db: np.ndarray, env: np.ndarray, beat_times: np.ndarray, *, meters: Sequence[int] = (2, 3, 4)
) -> np.ndarray:
    if beat_times.size == 0:
        return np.zeros(0, dtype=np.float64)
    if beat_times.size < 4:
        return beat_times[:1].copy()
    frames = np.clip(np.round(beat_times * BEAT_SR / BEAT_HOP).astype(np.int64), 0, S_db.shape[1] - 1)
    accent = _beat_accents(S_db, env, frames)
    meter, phase, _ = fold_meter(accent, meters=meters)
    return beat_times[phase::meter].copy()
