"""The signal-processing steps of dancekit's features in NumPy: librosa 0.11's algorithms, without its import.

``import librosa.beat`` (and the constant-Q transform's ``librosa.core.constantq``) cost several seconds in
a fresh process: numba compiles librosa's beat-tracking gufuncs at import (one of them is not cached) and
scipy.signal pulls in scipy.stats. A ``dancekit dance`` of a one-minute song spends less than that on the
whole computation, so the steps the presets use are written here in NumPy (plus ``soxr`` for resampling,
as librosa's ``res_type="soxr_hq"``), following librosa 0.11.0 operation by operation
(ISC licence, https://github.com/librosa/librosa) so that the values agree:

- beat frames of :func:`beat_track` are the same frames as ``librosa.beat.beat_track(onset_envelope=...,
  bpm=..., units="frames")`` (tested on real songs in ``tests/features/test_dsp.py``);
- the spectral arrays agree to float32 rounding (sums taken in another order: BLAS instead of numba loops
  or scipy.sparse; a matrix DCT instead of pocketfft's float32 one).

Nothing here is public API; :mod:`dancekit.features.spectral` and :mod:`dancekit.features.rhythm` are.
All arrays have time (frames) on the last axis, as in librosa.
"""

from __future__ import annotations

import math

import numpy as np

#: librosa's table value of ``n * sum(w**2) / sum(w)**2`` for the Hann window (``filters.WINDOW_BANDWIDTHS``).
_HANN_BANDWIDTH = 1.50018310546875


# --------------------------------------------------------------------------------------------------
# windows, framing, STFT


def hann(n: int) -> np.ndarray:
    """Periodic Hann window of ``n`` samples, float64: ``scipy.signal.get_window("hann", n)``, computed the
    way scipy does (``general_cosine`` on ``n + 1`` points, last one dropped)."""
    n = int(n)
    if n <= 1:
        return np.ones(n, dtype=np.float64)
    fac = np.linspace(-np.pi, np.pi, n + 1, dtype=np.float64)
    w = np.zeros(n + 1, dtype=np.float64)
    for k, a in enumerate((0.5, 0.5)):
        w += a * np.cos(k * fac)
    return w[:-1]


def frame(x: np.ndarray, *, frame_length: int, hop_length: int) -> np.ndarray:
    """Overlapping frames of a 1-D array as a strided view, shape ``(frame_length, n_frames)``."""
    x = np.asarray(x)
    n = 1 + (x.shape[-1] - frame_length) // hop_length
    return np.lib.stride_tricks.as_strided(x, shape=(frame_length, n), strides=(x.strides[-1], x.strides[-1] * hop_length),
                                           writeable=False)


def stft(y: np.ndarray, *, n_fft: int, hop_length: int, window: str = "hann", center: bool = True,
         block: int = 4096) -> np.ndarray:
    """Short-time Fourier transform of a 1-D float32 signal: ``librosa.stft(y, n_fft=..., hop_length=...,
    window=..., center=..., pad_mode="constant")``.

    The window (``"hann"`` or ``"ones"``) is float64, so each frame's FFT runs in float64 and is stored as
    complex64 (librosa's ``dtype_r2c(float32)``). ``block`` frames are transformed at a time.

    Returns
    -------
    np.ndarray, complex64, shape (1 + n_fft // 2, n_frames); ``n_frames = 1 + len(y) // hop_length`` when
    ``center``.
    """
    y = np.asarray(y, dtype=np.float32)
    if center:
        y = np.pad(y, (n_fft // 2, n_fft // 2), mode="constant")
    win = hann(n_fft) if window == "hann" else np.ones(n_fft, dtype=np.float64)
    frames = frame(y, frame_length=n_fft, hop_length=hop_length)
    out = np.empty((1 + n_fft // 2, frames.shape[1]), dtype=np.complex64)
    for a in range(0, frames.shape[1], block):
        b = min(frames.shape[1], a + block)
        out[:, a:b] = np.fft.rfft(win[:, None] * frames[:, a:b], axis=0)
    return out


# --------------------------------------------------------------------------------------------------
# mel scale, dB, onset strength


def hz_to_mel(frequencies):
    """Slaney mel scale (``librosa.hz_to_mel(htk=False)``)."""
    frequencies = np.asanyarray(frequencies, dtype=np.float64)
    f_sp = 200.0 / 3
    mels = (frequencies - 0.0) / f_sp
    min_log_hz = 1000.0
    min_log_mel = (min_log_hz - 0.0) / f_sp
    logstep = np.log(6.4) / 27.0
    if frequencies.ndim:
        log_t = frequencies >= min_log_hz
        mels[log_t] = min_log_mel + np.log(frequencies[log_t] / min_log_hz) / logstep
    elif frequencies >= min_log_hz:
        mels = min_log_mel + np.log(frequencies / min_log_hz) / logstep
    return mels


def mel_to_hz(mels):
    """Inverse of :func:`hz_to_mel` (``librosa.mel_to_hz(htk=False)``)."""
    mels = np.asanyarray(mels, dtype=np.float64)
    f_sp = 200.0 / 3
    freqs = 0.0 + f_sp * mels
    min_log_hz = 1000.0
    min_log_mel = (min_log_hz - 0.0) / f_sp
    logstep = np.log(6.4) / 27.0
    if mels.ndim:
        log_t = mels >= min_log_mel
        freqs[log_t] = min_log_hz * np.exp(logstep * (mels[log_t] - min_log_mel))
    elif mels >= min_log_mel:
        freqs = min_log_hz * np.exp(logstep * (mels - min_log_mel))
    return freqs


def mel_frequencies(n_mels: int, *, fmin: float = 0.0, fmax: float) -> np.ndarray:
    """``n_mels`` frequencies (Hz) evenly spaced on the Slaney mel scale (``librosa.mel_frequencies``)."""
    return mel_to_hz(np.linspace(hz_to_mel(fmin), hz_to_mel(fmax), n_mels))


def mel_filters(*, sr: float, n_fft: int, n_mels: int = 128) -> np.ndarray:
    """Slaney-normalised mel filter bank, float32 ``(n_mels, 1 + n_fft // 2)`` (``librosa.filters.mel``)."""
    weights = np.zeros((n_mels, 1 + n_fft // 2), dtype=np.float32)
    fftfreqs = np.fft.rfftfreq(n=n_fft, d=1.0 / sr)
    mel_f = mel_frequencies(n_mels + 2, fmin=0.0, fmax=float(sr) / 2)
    fdiff = np.diff(mel_f)
    ramps = np.subtract.outer(mel_f, fftfreqs)
    for i in range(n_mels):
        lower = -ramps[i] / fdiff[i]
        upper = ramps[i + 2] / fdiff[i + 1]
        weights[i] = np.maximum(0, np.minimum(lower, upper))
    enorm = 2.0 / (mel_f[2:n_mels + 2] - mel_f[:n_mels])
    weights *= enorm[:, np.newaxis]
    return weights


def power_to_db(S: np.ndarray, *, amin: float = 1e-10, top_db: float = 80.0) -> np.ndarray:
    """``librosa.power_to_db(S)`` (ref 1.0): ``10 log10(max(amin, S))``, floored at ``max - top_db``."""
    log_spec = 10.0 * np.log10(np.maximum(amin, S))
    log_spec -= 10.0 * np.log10(np.maximum(amin, 1.0))
    return np.maximum(log_spec, log_spec.max() - top_db)


def onset_strength(S: np.ndarray, *, n_fft: int, hop_length: int, aggregate=np.mean, lag: int = 1,
                   center: bool = True) -> np.ndarray:
    """Spectral-flux onset envelope of a dB spectrogram ``(n_bands, T)``: ``librosa.onset.onset_strength(S=S,
    n_fft=..., hop_length=..., aggregate=..., center=...)`` (lag 1, no max filter, no detrend). ``center``:
    shifted by ``n_fft // (2 * hop_length)`` frames to the frames' centres and cut to ``T``; else value ``j``
    (``j >= lag``) is frame ``j`` against frame ``j - lag`` and the first ``lag`` values are 0.

    Returns
    -------
    np.ndarray, dtype of ``S``, shape (T,)
    """
    S = np.atleast_2d(S)
    env = np.maximum(0.0, S[..., lag:] - S[..., :-lag])
    env = aggregate(env, axis=-2)
    pad = lag + (n_fft // (2 * hop_length) if center else 0)
    env = np.pad(env, (int(pad), 0), mode="constant")
    return env[: S.shape[-1]] if center else env


# --------------------------------------------------------------------------------------------------
# autocorrelation, tempogram, tempo


def next_fast_len_real(n: int) -> int:
    """Smallest 5-smooth integer >= ``n`` (``scipy.fft.next_fast_len(n, real=True)``)."""
    n = int(n)
    if n <= 6:
        return max(n, 1)
    best = 1 << (n - 1).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:  # multiply by 2 until >= n
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def autocorrelate(y: np.ndarray, *, axis: int = -1) -> np.ndarray:
    """Full autocorrelation along ``axis`` by FFT (``librosa.autocorrelate``), lags 0 … n-1."""
    n = y.shape[axis]
    n_pad = next_fast_len_real(2 * n - 1)
    spec = np.fft.rfft(y, n=n_pad, axis=axis)
    ac = np.fft.irfft(spec.real**2 + spec.imag**2, n=n_pad, axis=axis)
    sl = [slice(None)] * ac.ndim
    sl[axis] = slice(n)
    return ac[tuple(sl)]


def normalize_max(S: np.ndarray, *, axis: int) -> np.ndarray:
    """Scale to a maximum magnitude of 1 along ``axis`` (``librosa.util.normalize(norm=np.inf)``; slices
    whose maximum is below the dtype's ``tiny`` are left as they are). Same dtype as ``S``."""
    length = np.max(np.abs(S).astype(float), axis=axis, keepdims=True)
    length[length < np.finfo(S.dtype).tiny] = 1.0
    out = np.empty_like(S)
    out[:] = S / length
    return out


def tempogram(onset_envelope: np.ndarray, *, win_length: int) -> np.ndarray:
    """Autocorrelation tempogram, float64 ``(win_length, T)`` (``librosa.feature.tempogram(onset_envelope=...,
    win_length=...)``: centred with a linear ramp, Hann-windowed, columns scaled to a maximum of 1)."""
    env = np.asarray(onset_envelope)
    n = env.shape[-1]
    half = int(win_length // 2)
    padded = np.pad(env, (half, half), mode="linear_ramp", end_values=[0, 0])
    frames = frame(padded, frame_length=win_length, hop_length=1)[:, :n]
    return normalize_max(autocorrelate(frames * hann(win_length)[:, None], axis=-2), axis=-2)


def tempo_win_length(*, sr: float, hop_length: int, ac_size: float = 8.0) -> int:
    """Frames of :func:`tempo`'s tempogram window: ``ac_size`` seconds (``librosa.time_to_frames``)."""
    return int(np.floor(int(ac_size * sr) // hop_length))


def tempo(onset_envelope: np.ndarray, *, sr: float, hop_length: int, start_bpm: float = 120.0,
          std_bpm: float = 1.0, ac_size: float = 8.0, max_tempo: float = 320.0) -> float:
    """Global tempo in BPM (``librosa.feature.tempo(onset_envelope=..., sr=..., hop_length=...,
    start_bpm=...)``): the mean tempogram over ``ac_size`` s windows weighted by a log-normal prior."""
    win_length = tempo_win_length(sr=sr, hop_length=hop_length, ac_size=ac_size)
    tg = np.mean(tempogram(onset_envelope, win_length=win_length), axis=-1, keepdims=True)
    return tempo_from_tempogram(tg, sr=sr, hop_length=hop_length, start_bpm=start_bpm, std_bpm=std_bpm,
                                max_tempo=max_tempo)


def tempo_from_tempogram(tg: np.ndarray, *, sr: float, hop_length: int, start_bpm: float = 120.0,
                         std_bpm: float = 1.0, max_tempo: float = 320.0) -> float:
    """Global tempo in BPM from a time-averaged tempogram ``tg`` of shape ``(win_length, 1)`` (or
    ``(win_length,)``): ``librosa.feature.tempo(tg=tg, sr=..., hop_length=..., start_bpm=...)``, the lag
    maximising ``log1p(1e6 tg)`` plus a log-normal prior around ``start_bpm`` (``std_bpm`` octaves), lags
    faster than ``max_tempo`` excluded."""
    tg = np.asarray(tg, dtype=np.float64).reshape(-1, 1)
    win_length = tg.shape[0]
    bpms = np.zeros(win_length, dtype=np.float64)
    bpms[0] = np.inf
    bpms[1:] = 60.0 * sr / (hop_length * np.arange(1.0, win_length))
    with np.errstate(invalid="ignore", divide="ignore"):
        logprior = -0.5 * ((np.log2(bpms) - np.log2(start_bpm)) / std_bpm) ** 2
    max_idx = int(np.argmax(bpms < max_tempo))
    logprior[:max_idx] = -np.inf
    best = np.argmax(np.log1p(1e6 * tg) + logprior[:, None], axis=-2)
    return float(bpms[best[0]])


# --------------------------------------------------------------------------------------------------
# the dynamic-programming beat tracker (Ellis 2007; librosa.beat.beat_track with a given tempo)


def _local_score(onsets: np.ndarray, frames_per_beat: float) -> np.ndarray:
    """Onsets smoothed by a Gaussian of one beat's width, summed in librosa's order (which leaves out
    ``onsets[0]``)."""
    n = len(onsets)
    window = np.exp(-0.5 * (np.arange(-frames_per_beat, frames_per_beat + 1) * 32.0 / frames_per_beat) ** 2)
    K = len(window)
    c = K // 2
    score = np.zeros(n, dtype=np.float64)
    for k in range(K):
        # score[i] += window[k] * onsets[i + c - k] for 1 <= i + c - k <= n - 1
        lo, hi = max(0, k - c + 1), min(n, n + k - c)
        if lo < hi:
            score[lo:hi] += window[k] * onsets[lo + c - k:hi + c - k]
    return score


def _beat_dp(score: np.ndarray, frames_per_beat: float, tightness: float) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative score and back-links: each frame's best predecessor ``fpb/2 … 2 fpb`` frames earlier,
    penalised by ``tightness * log(gap / fpb)**2``. Frames are filled a block of ``round(fpb/2)`` at a time
    (no frame of a block can be a predecessor of another); ties go to the latest predecessor, as in
    librosa's loop."""
    n = len(score)
    near = int(np.round(frames_per_beat / 2))
    far = int(2 * frames_per_beat)
    gaps = np.arange(near, far + 1)
    penalty = np.array([tightness * (math.log(g) - math.log(frames_per_beat)) ** 2 for g in gaps])
    cum = np.zeros(n, dtype=np.float64)
    link = np.full(n, -1, dtype=np.int64)
    step = max(near, 1)
    for a in range(0, n, step):
        i = np.arange(a, min(n, a + step))
        loc = i[:, None] - gaps[None, :]
        valid = loc >= 0
        cand = np.where(valid, cum[np.maximum(loc, 0)] - penalty[None, :], -np.inf)
        best = np.argmax(cand, axis=1)
        has = valid[np.arange(len(i)), best]
        cum[i] = score[i] + np.where(has, cand[np.arange(len(i)), best], 0.0)
        link[i] = np.where(has, loc[np.arange(len(i)), best], -1)
    thresh = 0.01 * score.max()
    above = np.flatnonzero(score >= thresh)
    first = above[0] if above.size else n
    link[:first] = -1
    return link, cum


def _local_max(x: np.ndarray) -> np.ndarray:
    """``librosa.util.localmax`` of a 1-D array: ``x[i] > x[i-1] and x[i] >= x[i+1]``; never the first
    element, the last one when it exceeds its neighbour."""
    out = np.zeros(len(x), dtype=bool)
    if len(x) > 2:
        out[1:-1] = (x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])
    if len(x) > 1:
        out[-1] = x[-1] > x[-2]
    return out


def beat_track(onset_envelope: np.ndarray, *, bpm: float, frame_rate: float, tightness: float = 100.0,
               trim: bool = True) -> np.ndarray:
    """Beat frames of an onset envelope at a given tempo: ``librosa.beat.beat_track(onset_envelope=...,
    bpm=bpm, sr=..., hop_length=..., tightness=..., trim=..., units="frames")``.

    Returns
    -------
    np.ndarray, int64, shape (n_beats,): increasing frame indices (empty for an all-zero envelope)
    """
    env = np.asarray(onset_envelope)
    if not env.any():
        return np.zeros(0, dtype=np.int64)
    if not bpm > 0 or not tightness > 0:
        raise ValueError(f"bpm and tightness must be > 0, got {bpm}, {tightness}")
    fpb = float(np.round(frame_rate * 60.0 / bpm))
    onsets = env / (env.std(ddof=1, axis=-1, keepdims=True) + np.finfo(env.dtype).tiny)
    score = _local_score(onsets.astype(np.float64), fpb)
    link, cum = _beat_dp(score, fpb, float(np.float32(tightness)))
    # the last beat: the last local maximum of the cumulative score above half their median
    peaks = _local_max(cum)
    med = np.median(cum[peaks]) if peaks.any() else np.nan
    tail = len(cum) - 1
    for t in range(len(cum) - 1, -1, -1):
        if peaks[t] and cum[t] >= 0.5 * med:
            tail = t
            break
    beats = np.zeros(len(env), dtype=bool)
    while tail >= 0:
        beats[tail] = True
        tail = link[tail]
    # trim weak leading and trailing beats: local score at most half the RMS of the smoothed beat scores
    w = np.hanning(5)
    smooth = np.convolve(score[beats], w)[len(w) // 2:len(score) + len(w) // 2]
    threshold = 0.5 * ((smooth**2).mean() ** 0.5) if trim else 0.0
    k = 0
    while k < len(score) and score[k] <= threshold:
        beats[k] = False
        k += 1
    k = len(score) - 1
    while k >= 0 and score[k] <= threshold:
        beats[k] = False
        k -= 1
    return np.flatnonzero(beats).astype(np.int64)


# --------------------------------------------------------------------------------------------------
# cepstra and deltas


def dct_ortho(S: np.ndarray, *, n: int) -> np.ndarray:
    """First ``n`` rows of the orthonormal DCT-II along axis -2 (``scipy.fft.dct(S, type=2, norm="ortho",
    axis=-2)[:n]``), as a float64 matrix product; float32 out."""
    m = S.shape[-2]
    k = np.arange(n)[:, None]
    basis = np.cos(np.pi * k * (2 * np.arange(m)[None, :] + 1) / (2 * m)) * np.sqrt(2.0 / m)
    basis[0] /= np.sqrt(2.0)
    return (basis @ np.asarray(S, dtype=np.float64)).astype(np.float32)


def delta(x: np.ndarray, *, width: int) -> np.ndarray:
    """First-order Savitzky-Golay derivative (polynomial order 1) along the last axis with
    ``mode="interp"`` (``librosa.feature.delta(x, width=width, order=1)``): the least-squares slope over
    ``width`` frames; the first and last ``width // 2`` frames take the slope of the first / last window.

    ``width`` odd, >= 3, <= ``x.shape[-1]``. Same dtype as ``x``.
    """
    h = width // 2
    k = np.arange(-h, h + 1, dtype=np.float64)
    x64 = np.asarray(x, dtype=np.float64)
    T = x64.shape[-1]
    out = np.zeros_like(x64)
    for j, c in enumerate(k / np.sum(k**2)):
        out[..., h:T - h] += c * x64[..., j:T - 2 * h + j]
    out[..., :h] = out[..., h:h + 1]
    out[..., T - h:] = out[..., T - h - 1:T - h]
    return out.astype(x.dtype)


# --------------------------------------------------------------------------------------------------
# constant-Q transform and chroma (librosa.cqt with tuning 0, its default; librosa.feature.chroma_cqt)


def relative_bandwidth(freqs: np.ndarray) -> np.ndarray:
    bpo = np.empty_like(freqs)
    logf = np.log2(freqs)
    bpo[0] = 1 / (logf[1] - logf[0])
    bpo[-1] = 1 / (logf[-1] - logf[-2])
    bpo[1:-1] = 2 / (logf[2:] - logf[:-2])
    return (2.0 ** (2 / bpo) - 1) / (2.0 ** (2 / bpo) + 1)


def wavelet_lengths(freqs: np.ndarray, sr: float, alpha: np.ndarray) -> tuple[np.ndarray, float]:
    gamma = 0
    Q = 1.0 / alpha
    cutoff = max(freqs * (1 + 0.5 * _HANN_BANDWIDTH / Q) + 0.5 * gamma)
    return Q * sr / (freqs + gamma / alpha), cutoff


def cqt_basis(sr: float, freqs: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, int]:
    """FFT of one octave's Hann-windowed complex wavelets, sparsified (quantile 0.01), complex64
    ``(n_bins, n_fft // 2 + 1)``."""
    lengths, _ = wavelet_lengths(freqs, sr, alpha)
    filters = []
    for ilen, freq in zip(lengths, freqs):
        angles = np.arange(-ilen // 2, ilen // 2, dtype=float) * 2 * np.pi * freq / sr
        sig = np.cos(angles) + 1j * np.sin(angles)
        sig *= hann(len(sig))
        mag = np.sum(np.abs(sig).astype(float))
        sig = sig / (mag if mag >= np.finfo(sig.dtype).tiny else 1.0)
        filters.append(sig)
    n_fft = int(2.0 ** (np.ceil(np.log2(max(lengths)))))
    basis = np.zeros((len(filters), n_fft), dtype=np.complex128)
    for i, f in enumerate(filters):
        lpad = int((n_fft - len(f)) // 2)
        basis[i, lpad:lpad + len(f)] = f
    basis *= lengths[:, np.newaxis] / float(n_fft)
    fft_basis = np.fft.fft(basis, n=n_fft, axis=1)[:, : (n_fft // 2) + 1]
    # sparsify: keep each row's largest entries holding all but 1 % of its magnitude
    mags = np.abs(fft_basis)
    mag_sort = np.sort(mags, axis=1)
    cumulative = np.cumsum(mag_sort / np.sum(mags, axis=1, keepdims=True), axis=1)
    idx = np.argmin(cumulative < 0.01, axis=1)
    keep = mags >= mag_sort[np.arange(len(idx)), idx][:, None]
    return np.where(keep, fft_basis, 0).astype(np.complex64), n_fft


def halve(y: np.ndarray, factor: int = 2, *, stream=None) -> np.ndarray:
    """Downsample by ``factor`` with soxr (HQ), scaled by ``sqrt(factor)`` as librosa's ``scale=True``
    (``stream``: a reusable resampler, :func:`dancekit.audio.io.resample`'s)."""
    from dancekit.audio.io import resample

    y_hat = resample(y, orig_sr=factor, target_sr=1, stream=stream)
    y_hat /= np.sqrt(1.0 / factor)
    return y_hat


def cqt_magnitude(y: np.ndarray, *, sr: float, hop_length: int, fmin: float, n_bins: int,
                  bins_per_octave: int) -> np.ndarray:
    """Magnitude of the constant-Q transform (``np.abs(librosa.cqt(y, sr=..., hop_length=..., fmin=...,
    n_bins=..., bins_per_octave=...))``: tuning 0, Hann wavelets, L1 norm, sparsity 0.01, scaled by the
    filter lengths, octave by octave with soxr half-band downsampling).

    Returns
    -------
    np.ndarray, float32, shape (n_bins, 1 + len(y) // hop_length)
    """
    y = np.asarray(y, dtype=np.float32)
    n_octaves = int(np.ceil(float(n_bins) / bins_per_octave))
    n_filters = min(bins_per_octave, n_bins)
    ratios = 2.0 ** ((0.0 + np.arange(0, bins_per_octave, dtype=float)) / bins_per_octave)
    octaves = 2.0 ** np.arange(np.ceil(n_bins / bins_per_octave))
    freqs = np.sort(np.multiply.outer(octaves, ratios).flatten()[:n_bins]) * (fmin * 2.0 ** (0.0 / bins_per_octave))
    alpha = relative_bandwidth(freqs)
    lengths, cutoff = wavelet_lengths(freqs, sr, alpha)
    nyquist = sr / 2.0
    if cutoff > nyquist:
        raise ValueError(f"constant-Q bins up to {cutoff:.0f} Hz exceed the Nyquist frequency {nyquist:.0f} Hz")
    # early downsampling while the top octave stays well below Nyquist (librosa's __early_downsample)
    count1 = max(0, int(np.ceil(np.log2(nyquist / cutoff)) - 1) - 1)
    twos, h = 0, hop_length
    while h > 0 and h % 2 == 0:
        twos, h = twos + 1, h // 2
    count = min(count1, max(0, twos - n_octaves + 1))
    my_y, my_sr, my_hop = y, float(sr), int(hop_length)
    if count > 0:
        factor = 2**count
        my_hop //= factor
        my_y = halve(y, factor)
        my_sr = sr / float(factor)
    sr0 = my_sr
    responses = []
    for i in range(n_octaves):
        sl = slice(-n_filters, None) if i == 0 else slice(-n_filters * (i + 1), -n_filters * i)
        basis, n_fft = cqt_basis(my_sr, freqs[sl], alpha[sl])
        basis *= np.sqrt(sr0 / my_sr)
        D = stft(my_y, n_fft=n_fft, hop_length=my_hop, window="ones")
        responses.append(basis @ D)
        if my_hop % 2 == 0:
            my_hop //= 2
            my_sr /= 2.0
            my_y = halve(my_y)
    n_cols = min(r.shape[-1] for r in responses)
    V = np.empty((n_bins, n_cols), dtype=np.complex64, order="F")
    end = n_bins
    for r in responses:
        k = r.shape[0]
        if end < k:
            V[:end] = r[-end:, :n_cols]
        else:
            V[end - k:end] = r[:, :n_cols]
        end -= k
    lengths, _ = wavelet_lengths(freqs, sr0, alpha)
    V /= np.sqrt(lengths)[:, None]
    return np.abs(V)


def chroma_from_cqt(C: np.ndarray, *, bins_per_octave: int, n_chroma: int = 12) -> np.ndarray:
    """Fold a constant-Q magnitude starting at C (``(n_bins, T)``) into pitch classes C … B, each column
    scaled to a maximum of 1 (``librosa.feature.chroma_cqt(C=C, bins_per_octave=..., n_chroma=...)``)."""
    n_merge = bins_per_octave // n_chroma
    fold = np.repeat(np.eye(n_chroma), n_merge, axis=1)
    fold = np.roll(fold, -(n_merge // 2), axis=1)
    fold = np.tile(fold, int(np.ceil(C.shape[0] / bins_per_octave)))[:, : C.shape[0]].astype(np.float32)
    chroma = fold @ C
    chroma[chroma < 0] = 0.0
    return normalize_max(chroma, axis=-2)
