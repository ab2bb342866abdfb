"""Frame-level spectral features: pure NumPy in, NumPy out, keyword-only arguments.

Every function here works on audio ``y`` (float, shape ``(n,)``) at sample
rate ``sr`` and returns arrays with the frame axis last and
``1 + n // hop_length`` frames (centred frames, the librosa convention).
When ``sr = fps * hop_length`` (see :func:`dancekit.features.feature_sr`),
frame ``i`` is motion frame ``i``, i.e. the frame centred at ``i / fps``
seconds.

The FFT size defaults to ``4 * hop_length`` (2048 for the default hop of
512), so a frame's window spans four motion frames at any frame rate.
"""

from __future__ import annotations

import numpy as np

from dancekit.errors import ParameterError
from dancekit.features import dsp as _dsp

__all__ = [
    "CQT_FMIN",
    "chroma_cqt",
    "hpss",
    "log_melspectrogram",
    "mfcc",
    "mfcc_delta",
    "n_frames",
    "onset_strength",
    "tempogram",
]

#: Lowest constant-Q bin (C1, Hz) used by :func:`chroma_cqt`.
CQT_FMIN = 32.703195662574764
_CQT_MAX_OCTAVES = 7


def n_frames(*, n_samples: int, hop_length: int = 512) -> int:
    """Number of centred frames of a signal: ``1 + n_samples // hop_length``."""
    return 1 + int(n_samples) // int(hop_length)


def default_n_fft(n_fft: int | None, hop_length: int) -> int:
    return 4 * int(hop_length) if n_fft is None else int(n_fft)


def fit_frames(x: np.ndarray, size: int) -> np.ndarray:
    """Pad (edge) or trim the last axis to ``size`` frames (guards off-by-one framing)."""
    if x.shape[-1] == size:
        return x
    assert abs(x.shape[-1] - size) <= 2, (x.shape, size)
    if x.shape[-1] > size:
        return x[..., :size]
    return np.pad(x, [(0, 0)] * (x.ndim - 1) + [(0, size - x.shape[-1])], mode="edge")


#: STFT frames computed at a time by :func:`mel_power`: bounds the transient complex spectrogram
#: (n_fft 2048: 1025 bins x 4096 frames x 8 bytes = 34 MB) whatever the song's length.
_MEL_CHUNK = 4096


def mel_power(*, y: np.ndarray, sr: int, n_fft: int, hop_length: int, n_mels: int = 128) -> np.ndarray:
    """Mel power spectrogram, ``librosa.feature.melspectrogram(y=y, sr=sr, n_fft=n_fft, hop_length=hop_length,
    n_mels=n_mels)`` (centred Hann frames, zero padding, power 2, Slaney mel filters) computed a few
    thousand frames at a time: memory is bounded by the output, not by the song's full complex STFT.

    Returns
    -------
    np.ndarray, float32, shape (n_mels, 1 + len(y) // hop_length)
    """
    y = np.asarray(y, dtype=np.float32)
    pad = n_fft // 2
    yp = np.pad(y, pad, mode="constant")
    total = 1 + (len(yp) - n_fft) // hop_length if len(yp) >= n_fft else 0
    basis = _dsp.mel_filters(sr=sr, n_fft=n_fft, n_mels=n_mels)
    out = np.empty((n_mels, total), dtype=np.float32)
    for f0 in range(0, total, _MEL_CHUNK):
        f1 = min(total, f0 + _MEL_CHUNK)
        D = _dsp.stft(yp[f0 * hop_length:(f1 - 1) * hop_length + n_fft], n_fft=n_fft, hop_length=hop_length,
                      center=False)
        out[:, f0:f1] = basis @ (D.real**2 + D.imag**2)
    return out


def log_melspectrogram(
    *, y: np.ndarray, sr: int, hop_length: int = 512, n_fft: int | None = None, n_mels: int = 128
) -> np.ndarray:
    """Log-power mel spectrogram in dB (``power_to_db``, ref 1.0, top_db 80).

    Returns
    -------
    np.ndarray, float32, shape (n_mels, 1 + len(y) // hop_length)
    """
    n_fft = default_n_fft(n_fft, hop_length)
    M = mel_power(y=y, sr=sr, n_fft=n_fft, hop_length=hop_length, n_mels=n_mels)
    S = _dsp.power_to_db(M).astype(np.float32)
    return fit_frames(S, n_frames(n_samples=len(y), hop_length=hop_length))


def mfcc(
    *,
    y: np.ndarray | None = None,
    sr: int,
    S: np.ndarray | None = None,
    hop_length: int = 512,
    n_fft: int | None = None,
    n_mfcc: int = 20,
) -> np.ndarray:
    """Mel-frequency cepstral coefficients (DCT-II of the log-mel spectrogram).

    Parameters
    ----------
    y : np.ndarray, shape (n,), optional
        Audio; ignored when ``S`` is given.
    sr : int
        Sample rate of ``y`` in Hz.
    S : np.ndarray, shape (n_mels, T), optional
        A precomputed :func:`log_melspectrogram` (dB).

    Returns
    -------
    np.ndarray, float32, shape (n_mfcc, T)
    """
    if S is None:
        if y is None:
            raise ParameterError("mfcc needs y or S")
        S = log_melspectrogram(y=y, sr=sr, hop_length=hop_length, n_fft=n_fft)
    return _dsp.dct_ortho(S, n=n_mfcc)


def mfcc_delta(*, mfcc: np.ndarray, width: int = 9) -> np.ndarray:
    """First-order delta (Savitzky-Golay derivative over ``width`` frames) along time.

    ``width`` shrinks to the largest odd value that fits very short inputs;
    with fewer than 3 frames the result is all zeros.

    Returns
    -------
    np.ndarray, float32, same shape as ``mfcc`` (units: coefficient per frame)
    """
    T = mfcc.shape[-1]
    w = min(int(width), T if T % 2 else T - 1)
    if w < 3:
        return np.zeros_like(mfcc, dtype=np.float32)
    return _dsp.delta(np.asarray(mfcc, dtype=np.float32), width=w)


def onset_strength(
    *,
    y: np.ndarray | None = None,
    sr: int,
    S: np.ndarray | None = None,
    hop_length: int = 512,
    n_fft: int | None = None,
    aggregate=np.mean,
) -> np.ndarray:
    """Spectral-flux onset strength (librosa's envelope: positive log-mel flux, lag 1).

    Parameters
    ----------
    y : np.ndarray, shape (n,), optional
        Audio; ignored when ``S`` is given.
    S : np.ndarray, shape (n_mels, T), optional
        A precomputed :func:`log_melspectrogram` (dB) made with the same
        ``hop_length`` and ``n_fft`` (the FFT size sets the centring shift).
    aggregate : callable
        How the per-band flux is combined (``np.mean``; ``np.median`` for beat tracking).

    Returns
    -------
    np.ndarray, float32, shape (T,), >= 0 (dB per frame)
    """
    n_fft = default_n_fft(n_fft, hop_length)
    if S is None:
        if y is None:
            raise ParameterError("onset_strength needs y or S")
        S = log_melspectrogram(y=y, sr=sr, hop_length=hop_length, n_fft=n_fft)
    env = _dsp.onset_strength(S, n_fft=n_fft, hop_length=hop_length, aggregate=aggregate)
    return np.maximum(env, 0.0).astype(np.float32)


def tempogram(
    *, onset_envelope: np.ndarray, sr: int, hop_length: int = 512, win_length: int = 384
) -> np.ndarray:
    """Autocorrelation tempogram of an onset envelope.

    Row ``k`` is the windowed autocorrelation at a lag of ``k`` frames
    (a tempo of ``60 * sr / (hop_length * k)`` BPM), each column scaled to a
    maximum of 1 (all-zero for silence).

    Returns
    -------
    np.ndarray, float32, shape (win_length, T)
    """
    env = np.asarray(onset_envelope, dtype=np.float32)
    tg = _dsp.tempogram(env, win_length=win_length)
    return np.nan_to_num(fit_frames(tg, env.shape[-1]), nan=0.0).astype(np.float32)


def cqt_octaves(sr: int) -> int:
    """Octaves above C1 that fit below Nyquist with a 10 % margin for the filter bandwidth."""
    n = int(np.floor(np.log2(sr / 2 / (CQT_FMIN * 1.1))))
    if n < 1:
        raise ParameterError(f"sample rate {sr} Hz is too low for a constant-Q chromagram (need >= 80 Hz)")
    return min(_CQT_MAX_OCTAVES, n)


def chroma_cqt(
    *, y: np.ndarray, sr: int, hop_length: int = 512, n_chroma: int = 12, bins_per_octave: int = 36
) -> np.ndarray:
    """Constant-Q chromagram: energy per pitch class C, C#, ..., B.

    The constant-Q transform starts at C1 (32.7 Hz) and spans up to 7 octaves,
    fewer at low sample rates so that the top bin stays below Nyquist (6
    octaves at ``sr = 15 * 512``). Tuning is A4 = 440 Hz (``librosa.cqt``'s default ``tuning=0``: none is
    estimated). Each
    column is scaled to a maximum of 1 (all-zero for silence).

    Returns
    -------
    np.ndarray, float32, shape (n_chroma, 1 + len(y) // hop_length), values in [0, 1]
    """
    y = np.asarray(y, dtype=np.float32)
    T = n_frames(n_samples=len(y), hop_length=hop_length)
    if not np.any(y):
        return np.zeros((n_chroma, T), dtype=np.float32)
    n_oct = cqt_octaves(sr)
    if bins_per_octave % n_chroma:
        raise ParameterError(f"bins_per_octave={bins_per_octave} must be a multiple of n_chroma={n_chroma}")
    C = _dsp.cqt_magnitude(y, sr=sr, hop_length=hop_length, fmin=CQT_FMIN, n_bins=n_oct * bins_per_octave,
                           bins_per_octave=bins_per_octave)
    chroma = _dsp.chroma_from_cqt(C, bins_per_octave=bins_per_octave, n_chroma=n_chroma)
    return np.nan_to_num(fit_frames(chroma, T), nan=0.0).astype(np.float32)


def hpss(
    *, y: np.ndarray, hop_length: int = 512, n_fft: int = 1024, kernel_size: int = 31
) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic / percussive source separation (median filtering of the STFT, soft masks).

    Harmonic energy is smooth along time, percussive energy along frequency;
    ``kernel_size`` frames / bins are the median-filter lengths (at 22050 Hz
    with the defaults: 0.74 s and 667 Hz). The defaults halve the cost of
    librosa's (n_fft 2048) at no visible loss for chroma and beats.

    Returns
    -------
    y_harmonic, y_percussive : np.ndarray, float32, shape (n,) each
    """
    import librosa

    y = np.asarray(y, dtype=np.float32)
    D = librosa.stft(y, n_fft=n_fft, hop_length=hop_length)
    H, P = librosa.decompose.hpss(D, kernel_size=kernel_size)
    y_h = librosa.istft(H, hop_length=hop_length, n_fft=n_fft, length=len(y))
    y_p = librosa.istft(P, hop_length=hop_length, n_fft=n_fft, length=len(y))
    return y_h.astype(np.float32), y_p.astype(np.float32)


# ---------------------------------------------------------------------------------------------
# streaming and chunked forms (issue 18): memory bounded by a chunk, the same numbers as the whole-song forms


class MelPowerStream:
    """:func:`mel_power` of a signal that arrives in blocks: ``feed`` each block, then ``finish`` for the
    ``(n_mels, 1 + n // hop_length)`` float32 mel power spectrogram. Frames are computed in the same
    :data:`_MEL_CHUNK`-frame chunks as :func:`mel_power` (the same STFT frames, the same products), so the
    result equals ``mel_power(y=concatenated blocks, ...)`` bit for bit; memory is one chunk of samples plus
    the output. ``expected_samples``: the signal's length if known (the output is allocated once; it grows
    if the signal turns out longer).
    """

    def __init__(self, *, sr: int, n_fft: int, hop_length: int, n_mels: int = 128, expected_samples: int = 0):
        self.n_fft, self.hop = int(n_fft), int(hop_length)
        self.basis = _dsp.mel_filters(sr=sr, n_fft=self.n_fft, n_mels=n_mels)
        self.buf = np.zeros(self.n_fft // 2, np.float32)  # the centring pad of mel_power
        self.done = 0  # frames computed
        self.out = np.empty((n_mels, 1 + max(0, int(expected_samples)) // self.hop), np.float32)
        self.n = 0  # samples fed

    def _need(self, frames: int) -> int:
        return (frames - 1) * self.hop + self.n_fft

    def _compute(self, frames: int) -> None:
        D = _dsp.stft(self.buf[: self._need(frames)], n_fft=self.n_fft, hop_length=self.hop, center=False)
        if self.done + frames > self.out.shape[1]:
            grown = np.empty((self.out.shape[0], max(self.done + frames, int(self.out.shape[1] * 1.25) + 1)),
                             np.float32)
            grown[:, : self.done] = self.out[:, : self.done]
            self.out = grown
        self.out[:, self.done: self.done + frames] = self.basis @ (D.real**2 + D.imag**2)
        self.done += frames
        self.buf = self.buf[frames * self.hop:].copy()

    def feed(self, block: np.ndarray) -> None:
        """Add the next samples ``(k,)``."""
        block = np.asarray(block, np.float32)
        self.n += len(block)
        self.buf = np.concatenate([self.buf, block])
        while len(self.buf) >= self._need(_MEL_CHUNK):
            self._compute(_MEL_CHUNK)

    def finish(self) -> np.ndarray:
        """The mel power ``(n_mels, 1 + n // hop_length)`` of everything fed (the end zero-padded as centred)."""
        self.buf = np.concatenate([self.buf, np.zeros(self.n_fft // 2, np.float32)])
        total = 1 + self.n // self.hop
        while self.done < total:
            self._compute(min(_MEL_CHUNK, total - self.done))
        out, self.out = self.out[:, :total], None
        return out


def power_to_db_inplace(M: np.ndarray, *, amin: float = 1e-10, top_db: float = 80.0) -> np.ndarray:
    """``librosa.power_to_db(M)`` (ref 1.0, top_db 80) computed in ``M``'s own memory (float32 ``M`` is
    overwritten and returned): the same numbers, without the two full-size temporaries."""
    np.maximum(M, amin, out=M)
    np.log10(M, out=M)
    M *= 10.0
    np.maximum(M, M.max() - top_db, out=M)
    return M


#: Frames per chunk of :func:`chroma_cqt_chunked` and :func:`tempogram_chunked` (60 s at 25 fps).
CHUNK_FRAMES = 1500
#: Context each side of a constant-Q chunk, seconds: the longest C1 filter spans 1.6 s (36 bins per
#: octave), and the octave resampling adds its own filter's support.
CQT_MARGIN_S = 4.0


def chroma_cqt_chunked(*, y, sr: int, hop_length: int = 512, n_chroma: int = 12, bins_per_octave: int = 36,
                       chunk: int = CHUNK_FRAMES, out: np.ndarray | None = None, n_samples: int | None = None
                       ) -> np.ndarray:
    """:func:`chroma_cqt` computed ``chunk`` frames at a time, each chunk's constant-Q transform taken over
    its frames plus :data:`CQT_MARGIN_S` of audio each side (chunks start on a hop, a multiple of the
    octave decimation, so every chunk's octaves are sampled on the song's grid): equal to the whole-song
    chromagram (librosa 0.11: 0 tuning, no estimate), in memory bounded by the chunk. ``out``: a ``(T, n_chroma)`` array to write into (e.g. columns of a
    feature matrix), else one is allocated. ``y`` may also be a function ``read(a, b)`` returning samples
    ``[a, b)`` of a signal of ``n_samples`` samples that is not all zero (e.g. one kept on disk).

    Returns
    -------
    np.ndarray, float32, shape (1 + len(y) // hop_length, n_chroma) — frames first
    """
    if callable(y):
        read, n = y, int(n_samples)
    else:
        y = np.asarray(y, dtype=np.float32)
        n = len(y)
        read = lambda a, b: y[a:b]  # noqa: E731
    T = n_frames(n_samples=n, hop_length=hop_length)
    out = np.zeros((T, n_chroma), np.float32) if out is None else out
    if not callable(y) and not np.any(y):
        out[:] = 0.0
        return out
    n_oct = cqt_octaves(sr)
    margin = int(np.ceil(CQT_MARGIN_S * sr / hop_length))
    for f0 in range(0, T, int(chunk)):
        f1 = min(T, f0 + int(chunk))
        a = max(0, f0 - margin)
        seg = read(a * hop_length, min(n, (f1 + margin) * hop_length))
        C = _dsp.cqt_magnitude(seg, sr=sr, hop_length=hop_length, fmin=CQT_FMIN, n_bins=n_oct * bins_per_octave,
                               bins_per_octave=bins_per_octave)
        C = fit_frames(C, n_frames(n_samples=len(seg), hop_length=hop_length))[:, f0 - a: f1 - a]
        chroma = _dsp.chroma_from_cqt(C, bins_per_octave=bins_per_octave, n_chroma=n_chroma)
        out[f0:f1] = np.nan_to_num(chroma, nan=0.0).T
    return out


def _tempogram_blocks(env: np.ndarray, *, win_length: int, chunk: int):
    """The autocorrelation tempogram of ``env`` (:func:`dancekit.features.dsp.tempogram`, librosa's: float64,
    each column scaled to a maximum of 1), ``chunk`` frames at a time: yields ``(f0, f1, tg (win_length,
    f1 - f0))``. Every frame is its own window of the (ramp-padded) envelope, so the blocks are the columns
    of ``_dsp.tempogram(env, win_length=win_length)``."""
    env = np.asarray(env)
    n = env.shape[-1]
    ac_window = _dsp.hann(win_length)[:, None]
    half = int(win_length // 2)
    padded = np.pad(env, (half, half), mode="linear_ramp", end_values=[0, 0])
    for f0 in range(0, n, int(chunk)):
        f1 = min(n, f0 + int(chunk))
        frames = _dsp.frame(padded[f0: f1 + win_length - 1], frame_length=win_length, hop_length=1)
        yield f0, f1, _dsp.normalize_max(_dsp.autocorrelate(frames[:, : f1 - f0] * ac_window, axis=-2), axis=-2)


def tempogram_mean(*, onset_envelope: np.ndarray, win_length: int, chunk: int = 4 * CHUNK_FRAMES) -> np.ndarray:
    """The time average ``(win_length, 1)`` float64 of librosa's tempogram of ``onset_envelope`` (what
    ``librosa.feature.tempo`` aggregates; pass it to :func:`dancekit.features.dsp.tempo_from_tempogram`),
    summed ``chunk`` frames at a time instead of a whole-song ``(win_length, T)`` array and its complex FFT.
    One chunk: ``_dsp.tempo``'s mean bit for bit; more: the same sum in another order (float rounding)."""
    env = np.asarray(onset_envelope)
    total = np.zeros((win_length, 1), np.float64)
    for _, _, tg in _tempogram_blocks(env, win_length=win_length, chunk=chunk):
        total += np.sum(tg, axis=-1, keepdims=True)
    return total / max(1, env.shape[-1])


def tempogram_chunked(*, onset_envelope: np.ndarray, win_length: int = 384, chunk: int = CHUNK_FRAMES,
                      out: np.ndarray | None = None) -> np.ndarray:
    """:func:`tempogram` (librosa's autocorrelation tempogram: centred windows, the envelope padded with a
    linear ramp to 0, a Hann window, each frame scaled to a maximum of 1) computed ``chunk`` frames at a
    time — every frame is its own window of the envelope, so the chunks give the same frames — instead of a
    ``(win_length + 1, T)`` complex FFT of the whole song. ``out``: a ``(T, win_length)`` array to write into.

    Returns
    -------
    np.ndarray, float32, shape (T, win_length) — frames first
    """
    env = np.asarray(onset_envelope, dtype=np.float32)
    out = np.zeros((env.shape[-1], win_length), np.float32) if out is None else out
    for f0, f1, tg in _tempogram_blocks(env, win_length=win_length, chunk=chunk):
        out[f0:f1] = np.nan_to_num(tg, nan=0.0).T
    return out
