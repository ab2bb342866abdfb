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
from dancekit.features import _dsp

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


def _n_fft(n_fft: int | None, hop_length: int) -> int:
    return 4 * int(hop_length) if n_fft is None else int(n_fft)


def _fit(x: np.ndarray, size: int) -> np.ndarray:
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
    n_fft = _n_fft(n_fft, hop_length)
    M = mel_power(y=y, sr=sr, n_fft=n_fft, hop_length=hop_length, n_mels=n_mels)
    S = _dsp.power_to_db(M).astype(np.float32)
    return _fit(S, n_frames(n_samples=len(y), hop_length=hop_length))


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
    n_fft = _n_fft(n_fft, hop_length)
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
    return np.nan_to_num(_fit(tg, env.shape[-1]), nan=0.0).astype(np.float32)


def _cqt_octaves(sr: int) -> int:
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
    octaves at ``sr = 15 * 512``). Tuning is A4 = 440 Hz (``librosa.cqt``'s default ``tuning=0``). Each
    column is scaled to a maximum of 1 (all-zero for silence).

    Returns
    -------
    np.ndarray, float32, shape (n_chroma, 1 + len(y) // hop_length), values in [0, 1]
    """
    y = np.asarray(y, dtype=np.float32)
    T = n_frames(n_samples=len(y), hop_length=hop_length)
    if not np.any(y):
        return np.zeros((n_chroma, T), dtype=np.float32)
    n_oct = _cqt_octaves(sr)
    if bins_per_octave % n_chroma:
        raise ParameterError(f"bins_per_octave={bins_per_octave} must be a multiple of n_chroma={n_chroma}")
    C = _dsp.cqt_magnitude(y, sr=sr, hop_length=hop_length, fmin=CQT_FMIN, n_bins=n_oct * bins_per_octave,
                           bins_per_octave=bins_per_octave)
    chroma = _dsp.chroma_from_cqt(C, bins_per_octave=bins_per_octave, n_chroma=n_chroma)
    return np.nan_to_num(_fit(chroma, T), nan=0.0).astype(np.float32)


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
