"""Music features computed as the audio arrives (:class:`OnlineFeatures`), one row per motion frame.

The rows are those of the offline extractor (:func:`dancekit.features.extract`, the same presets and
columns) computed on the audio received so far, a frame at a time:

* the mel spectrogram, MFCCs, their delta, the onset envelope and the constant-Q chromagram of frame ``f``
  are computed once ``lookahead_s`` of audio after the frame has arrived, on the last few seconds of audio
  (the same code paths and constants as the offline extractor). They equal the offline values on the same
  samples once the lookahead covers their support (:data:`EXACT_LOOKAHEAD_S`: the lowest constant-Q filter,
  the delta's ±4 frames); a shorter lookahead zero-pads the frames' right edge as the offline extractor does at
  a song's end (what the test measures: ``tests/live/test_live.py``). The dB floor (80 dB under the loudest frame)
  is the loudest frame *so far*.
* the tempogram (384 frames, ±7.7 s at 25 fps) cannot wait for its centred window. With
  ``tempogram_future="bar"`` (the default) row ``f`` is the tempogram of the window centred on ``f`` whose future
  half is predicted: the onset envelope's last bar repeated (the bar: the strongest lag between 1.2 and 4 s of
  the autocorrelation of the last 384 frames, Hann-windowed). The frames before the song are the offline
  padding (the linear ramp to the first envelope value over 192 frames). With ``"none"`` row ``f`` holds the
  offline tempogram of frame ``f - 192`` (the window that ends at ``f``): the same values, delayed by half the
  window, the first 192 rows' windows seeing zeros before the padding. The model sees a tempogram up to date
  with ``"bar"``; the delayed one is 7.7 s late (docs/research/live.md).
* the beat (and downbeat) columns come from the causal beat tracker (:class:`dancekit.features.online_beats.BeatTracker`),
  which runs on a 100-Hz onset envelope of its own; a beat is marked on frame ``round(t · fps)``.
"""

from __future__ import annotations

import numpy as np

from dancekit.errors import ParameterError
from dancekit.features import dsp as _dsp
from dancekit.features import spectral
from dancekit.features.online_beats import BeatTracker
from dancekit.features.presets import PRESET_DIMS, PRESETS, feature_sr

__all__ = ["EXACT_LOOKAHEAD_S", "OnlineChroma", "OnlineFeatures", "TEMPOGRAM_FUTURES", "TEMPOGRAM_WINDOW",
           "online_rows"]

#: lookahead (s) from which every column but the tempogram and the beats equals the offline extractor's
EXACT_LOOKAHEAD_S = 1.0
#: the shortest audio history (s) the features are recomputed over: the constant-Q chromagram's margin fits
MIN_CONTEXT_S = 5.0
#: the offline tempogram's window (frames)
TEMPOGRAM_WINDOW = 384
#: how the online tempogram fills its window's future half: the last bar repeated, or nothing (delayed rows)
TEMPOGRAM_FUTURES = ("bar", "none")
#: the bar's range (s): the lag of the envelope's strongest autocorrelation in it is repeated
BAR_RANGE_S = (1.2, 4.0)
#: audio before the first new frame that each block's analysis re-reads (s): the chromagram's lowest
#: octaves and the resampler's support
LEFT_CONTEXT_S = 1.2
#: the beat tracker's onset envelope: STFT size and hop at the feature rate (hop 128 at 12.8 kHz: 100 Hz)
FINE_NFFT, FINE_HOP, FINE_MELS = 1024, 128, 40
#: the flux of a click peaks 3/8 of a window before the click reaches the window's centre: the beat times
#: are moved by that (0.03 s at 12.8 kHz; measured on the click tracks of tests/live/test_live.py)
FINE_SHIFT = 3 * FINE_NFFT // 8


class OnlineChroma:
    """The constant-Q chromagram of :func:`dancekit.features.spectral.chroma_cqt` for a few frames at a time:
    the same wavelet bases (built once), octave decimation and folding, but each octave's STFT only at the
    frames asked for."""

    def __init__(self, *, sr: int, hop_length: int, bins_per_octave: int = 36, n_chroma: int = 12):
        self.sr, self.hop, self.bpo, self.n_chroma = int(sr), int(hop_length), bins_per_octave, n_chroma
        n_oct = spectral.cqt_octaves(self.sr)
        n_bins = self.n_bins = n_oct * bins_per_octave
        fmin = spectral.CQT_FMIN
        ratios = 2.0 ** (np.arange(0, bins_per_octave, dtype=float) / bins_per_octave)
        octaves = 2.0 ** np.arange(np.ceil(n_bins / bins_per_octave))
        freqs = np.sort(np.multiply.outer(octaves, ratios).flatten()[:n_bins]) * fmin
        alpha = _dsp.relative_bandwidth(freqs)
        _, cutoff = _dsp.wavelet_lengths(freqs, self.sr, alpha)
        nyquist = self.sr / 2.0
        count1 = max(0, int(np.ceil(np.log2(nyquist / cutoff)) - 1) - 1)
        twos, h = 0, self.hop
        while h > 0 and h % 2 == 0:
            twos, h = twos + 1, h // 2
        self.count = min(count1, max(0, twos - n_oct + 1))
        my_sr, my_hop = float(self.sr), self.hop
        if self.count > 0:
            my_sr /= 2**self.count
            my_hop //= 2**self.count
        sr0 = my_sr
        self.octaves = []  # (basis (bins, n_fft//2+1), n_fft, hop at that octave's rate)
        for i in range(n_oct):
            sl = slice(-bins_per_octave, None) if i == 0 else slice(-bins_per_octave * (i + 1), -bins_per_octave * i)
            basis, n_fft = _dsp.cqt_basis(my_sr, freqs[sl], alpha[sl])
            basis = basis * np.sqrt(sr0 / my_sr)
            self.octaves.append((basis, n_fft, my_hop))
            if my_hop % 2 == 0:
                my_hop //= 2
                my_sr /= 2.0
        lengths, _ = _dsp.wavelet_lengths(freqs, sr0, alpha)
        self.scale = 1.0 / np.sqrt(lengths)[:, None]
        self._halver = None  # the octave decimation's resampler, built once

    def _halve(self, y: np.ndarray) -> np.ndarray:
        """:func:`dancekit.features.dsp.halve` (the same samples) with one soxr resampler, built once and cleared
        between calls, instead of one built per call."""
        import soxr

        if self._halver is None:
            self._halver = soxr.ResampleStream(2, 1, 1, dtype="float32", quality="soxr_hq")
        return _dsp.halve(y, stream=self._halver)

    def frames(self, seg: np.ndarray, rel_frames: np.ndarray) -> np.ndarray:
        """Chroma ``(len(rel_frames), n_chroma)`` float32 of frames ``rel_frames`` of ``seg`` (frame ``j`` centred
        on sample ``j · hop`` of ``seg``; ``seg`` starts on a multiple of the octave decimation)."""
        y = np.asarray(seg, np.float32)
        if not np.any(y):
            return np.zeros((len(rel_frames), self.n_chroma), np.float32)
        if self.count > 0:
            y = _dsp.halve(y, 2**self.count)
        V = np.empty((self.n_bins, len(rel_frames)), np.complex64)
        end = self.n_bins
        for i, (basis, n_fft, hop) in enumerate(self.octaves):
            cols = np.zeros((n_fft, len(rel_frames)))  # frame j: samples j·hop ± n_fft / 2, zeros beyond y's ends
            for c, j in enumerate(rel_frames):
                a = j * hop - n_fft // 2
                if a + n_fft > len(y) + n_fft // 2:  # pragma: no cover - frames are within seg by construction
                    raise AssertionError("frame beyond the segment")
                lo, hi = max(0, a), min(len(y), a + n_fft)
                if hi > lo:
                    cols[lo - a : hi - a, c] = y[lo:hi]
            D = np.fft.rfft(cols, axis=0).astype(np.complex64)
            r = basis @ D
            k = r.shape[0]
            if end < k:
                V[:end] = r[-end:]
            else:
                V[end - k : end] = r
            end -= k
            if i < len(self.octaves) - 1 and hop % 2 == 0:
                y = self._halve(y)
        C = np.abs(V) * self.scale
        chroma = _dsp.chroma_from_cqt(C.astype(np.float32), bins_per_octave=self.bpo, n_chroma=self.n_chroma)
        return np.nan_to_num(chroma, nan=0.0).T.astype(np.float32)


class OnlineFeatures:
    """A preset's feature rows ``(k, D)`` for the audio fed so far (:meth:`feed`), at ``fps`` (one row per
    motion frame, ``sr = fps · hop_length``).

    Parameters
    ----------
    preset : ``"revolution"`` or ``"music2dance"`` (``"dual"``'s harmonic / percussive separation needs the
        whole song)
    fps, hop_length : as the offline extractor
    lookahead_s : audio after a frame awaited before its row is computed (s)
    context_s : audio kept (s, ≥ 5)
    beat_delay_s : how long after a beat the tracker places it (s; default ``min(lookahead_s, 0.1)``)
    beat_window_s : onset history the beat tracker estimates its tempo and phase over (s)
    tempogram_future : ``"bar"`` (the tempogram's window centred, its future half the envelope's last bar
        repeated) or ``"none"`` (the rows delayed by half the window); see the module's description

    Examples
    --------
    >>> import numpy as np
    >>> f = OnlineFeatures(preset="music2dance", fps=25, lookahead_s=0.12)
    >>> rows = f.feed(np.zeros(f.sr, np.float32))   # one second of silence
    >>> rows.shape
    (23, 15)
    """

    def __init__(self, *, preset: str, fps: float, hop_length: int = 512, lookahead_s: float = 0.12,
                 context_s: float = 6.0, beat_delay_s: float | None = None, beat_window_s: float = 6.0,
                 tempogram_future: str = "bar"):
        if preset not in PRESETS or preset == "dual":
            raise ParameterError(f"live features support the presets revolution and music2dance, not {preset!r}")
        if tempogram_future not in TEMPOGRAM_FUTURES:
            raise ParameterError(f"tempogram_future must be one of {TEMPOGRAM_FUTURES}, got {tempogram_future!r}")
        for name, value, low in (("lookahead_s", lookahead_s, 0.0), ("context_s", context_s, MIN_CONTEXT_S),
                                 ("beat_window_s", beat_window_s, 2.0)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= 60.0:
                raise ParameterError(f"{name} must be a number of seconds in [{low:g}, 60], got {value!r}")
        self.tempogram_future = tempogram_future
        self._bar_lags = (max(1, int(round(BAR_RANGE_S[0] * fps))), int(round(BAR_RANGE_S[1] * fps)))
        self._future = np.arange(TEMPOGRAM_WINDOW // 2 + 1, TEMPOGRAM_WINDOW)  # the window's future half
        self.preset, self.fps, self.hop = preset, float(fps), int(hop_length)
        self.sr = feature_sr(fps=fps, hop_length=hop_length)
        self.n_fft = spectral.default_n_fft(None, self.hop)
        self.dim = PRESET_DIMS[preset]
        self.names = tuple(f"{n}:{d}" for n, d in PRESETS[preset])
        self.cols, c = {}, 0
        for name, d in PRESETS[preset]:
            self.cols[name] = slice(c, c + d)
            c += d
        self.la = int(round(float(lookahead_s) * self.sr))
        self.cqt_left = int(np.ceil(LEFT_CONTEXT_S * self.sr / self.hop))  # frames re-read before the first new one
        self._win = _dsp.hann(self.n_fft)
        self._fine_win = _dsp.hann(FINE_NFFT)
        self._tempo_win = _dsp.hann(TEMPOGRAM_WINDOW)
        self._mel_cache = np.zeros((128, 0))
        self._mel_lo = 0
        keep = max(float(context_s), LEFT_CONTEXT_S + float(lookahead_s) + 1.0)
        self.keep = int(keep * self.sr)
        self.buf = np.zeros(0, np.float32)
        self.buf_start = 0  # sample index of buf[0]
        self.n_in = 0  # samples received
        self.next = 0  # next frame to emit
        self.db_max = -np.inf
        self.mel_basis = _dsp.mel_filters(sr=self.sr, n_fft=self.n_fft, n_mels=128)
        self.chroma = OnlineChroma(sr=self.sr, hop_length=self.hop)
        self.hold_chroma = False  # the lighter path: the last chroma row repeated
        self._last_chroma = np.zeros(12, np.float32)
        self.env_hist = np.zeros(0, np.float32)  # onset envelope of the frames emitted (last TEMPOGRAM_WINDOW)
        self.env_first: float | None = None  # env[0]: the offline tempogram's ramp padding
        self.env_offset = 0  # frame index of env_hist[0]
        # the beat tracker's own onset envelope (100 Hz)
        self.fine_rate = self.sr / FINE_HOP
        self.fine_basis = _dsp.mel_filters(sr=self.sr, n_fft=FINE_NFFT, n_mels=FINE_MELS)
        self.fine_next = 0  # next fine frame
        self.fine_prev: np.ndarray | None = None
        delay = min(float(lookahead_s), 0.1) if beat_delay_s is None else float(beat_delay_s)
        self.tracker = BeatTracker(rate=self.fine_rate, delay_s=delay, window_s=beat_window_s,
                                   offset_s=FINE_SHIFT / self.sr)
        self.beat_frames: set[int] = set()
        self.downbeat_frames: set[int] = set()

    # ------------------------------------------------------------------ input
    def feed(self, y: np.ndarray) -> np.ndarray:
        """Append mono samples at :attr:`sr`; returns the rows ``(k, D)`` float32 of the frames now ready."""
        y = np.asarray(y, np.float32).reshape(-1)
        self.buf = np.concatenate([self.buf, y])
        self.n_in += len(y)
        self._run_tracker()
        ready = 0 if self.n_in < self.la else 1 + (self.n_in - self.la) // self.hop
        ready = min(ready, 1 + self.n_in // self.hop)
        rows = self._rows(self.next, ready)
        self._trim()
        return rows

    def finish(self) -> np.ndarray:
        """The rows of the frames still waiting for their lookahead: the stream has ended (as the offline
        extractor at a song's end: ``1 + n_samples // hop_length`` frames in all)."""
        return self._rows(self.next, 1 + self.n_in // self.hop)

    @property
    def frames_out(self) -> int:
        """Frames emitted so far."""
        return self.next

    # ------------------------------------------------------------------ internals
    def _trim(self) -> None:
        """Keep the last :attr:`keep` samples, cut on a multiple of the hop (the chromagram's decimation)."""
        excess = len(self.buf) - self.keep
        if excess > 0:
            cut = (excess // self.hop) * self.hop
            self.buf = self.buf[cut:]
            self.buf_start += cut

    def _run_tracker(self) -> None:
        """The 100-Hz onset envelope of the frames whose window has arrived, into the beat tracker."""
        half = FINE_NFFT // 2
        last = (self.n_in - half) // FINE_HOP  # last fine frame whose window is complete
        if last < self.fine_next:
            return
        idx = np.arange(self.fine_next, last + 1)
        yp_start = self.fine_next * FINE_HOP - half  # absolute sample of the first window's start
        seg = self._read(yp_start, last * FINE_HOP + half)
        frames = _dsp.frame(seg, frame_length=FINE_NFFT, hop_length=FINE_HOP)[:, : len(idx)]
        spec = np.fft.rfft(self._fine_win[:, None] * frames, axis=0)
        S = 10.0 * np.log10(np.maximum(1e-10, self.fine_basis @ (spec.real**2 + spec.imag**2)))  # (mels, k)
        prev = S[:, :1] if self.fine_prev is None else self.fine_prev
        flux = np.maximum(0.0, np.diff(np.concatenate([prev, S], axis=1), axis=1)).mean(axis=0)
        self.fine_prev = S[:, -1:]
        self.fine_next = last + 1
        for b in self.tracker.feed(flux):
            f = int(round(b.time * self.fps))
            self.beat_frames.add(f)
            if b.downbeat:
                self.downbeat_frames.add(f)

    def _read(self, a: int, b: int) -> np.ndarray:
        """Absolute samples ``[a, b)``, zeros outside what was received (the centred frames' padding)."""
        out = np.zeros(max(0, b - a), np.float32)
        lo, hi = max(a, self.buf_start), min(b, self.n_in)
        if hi > lo:
            out[lo - a : hi - a] = self.buf[lo - self.buf_start : hi - self.buf_start]
        return out

    def _power(self, g0: int, g1: int) -> np.ndarray:
        """Mel power ``(128, g1 - g0)`` of frames ``[g0, g1)``: the frames whose window has fully arrived are
        computed once and kept (:attr:`_mel_cache`), the later ones (zero-padded at the right, as at a song's
        end) are recomputed at each block."""
        hop, half = self.hop, self.n_fft // 2
        final = (self.n_in - half) // hop  # frames <= final have their whole window
        cache, lo = self._mel_cache, self._mel_lo
        todo = [g for g in range(g0, g1) if not (lo <= g < lo + cache.shape[1] and g <= final)]
        cols = {}
        if todo:
            a, b = todo[0], todo[-1] + 1
            seg = self._read(a * hop - half, (b - 1) * hop + half)
            frames = _dsp.frame(seg, frame_length=self.n_fft, hop_length=hop)[:, : b - a]
            spec = np.fft.rfft(self._win[:, None] * frames, axis=0)
            P = self.mel_basis @ (spec.real**2 + spec.imag**2)  # (128, b - a)
            for g in todo:
                cols[g] = P[:, g - a]
            new_final = [g for g in todo if g <= final and g == lo + cache.shape[1]]
            if new_final:
                cache = np.concatenate([cache, P[:, [g - a for g in new_final]]], axis=1)
        out = np.stack([cols[g] if g in cols else cache[:, g - lo] for g in range(g0, g1)], axis=1)
        keep = 16  # the frames a later block may still need (delta and onset context)
        if cache.shape[1] > keep:
            drop = cache.shape[1] - keep
            cache = cache[:, drop:]
            lo += drop
        self._mel_cache, self._mel_lo = cache, lo
        return out

    def _rows(self, f0: int, f1: int) -> np.ndarray:
        if f1 <= f0:
            return np.zeros((0, self.dim), np.float32)
        hop = self.hop
        end = 1 + self.n_in // hop  # the frames of the audio so far (the song "ends" here)
        # the delta's ±4 frames and the onset's 3 before; at least the delta's 9 frames before the stream's end
        # (fewer: a delta of zeros), so that near the end it is the offline delta at a song's end
        g0, g1 = max(0, min(f0 - 4, end - 9)), min(end, f1 + 4)
        M = self._power(g0, g1)
        S = 10.0 * np.log10(np.maximum(1e-10, M))
        self.db_max = max(self.db_max, float(S[:, : f1 - g0].max()))
        S = np.maximum(S, self.db_max - 80.0).astype(np.float32)  # (128, g1 - g0) dB
        j = np.arange(f0 - g0, f1 - g0)
        out = np.zeros((f1 - f0, self.dim), np.float32)
        env = spectral.onset_strength(S=S, sr=self.sr, hop_length=hop)  # value i: S[i - 2] against S[i - 3] (i ≥ 4 here)
        env_new = env[j]
        if self.preset == "revolution":
            m = spectral.mfcc(S=S, sr=self.sr, hop_length=hop)
            out[:, self.cols["mfcc"]] = m[:, j].T
            delta = spectral.mfcc_delta(mfcc=m) if g0 == 0 or m.shape[1] >= 9 else np.zeros_like(m)
            out[:, self.cols["mfcc_delta"]] = delta.T[j]
            out[:, self.cols["tempogram"]] = self._tempogram(env_new, f0)
        out[:, self.cols["onset_strength"]] = env_new[:, None]
        if self.hold_chroma:
            out[:, self.cols["chroma_cqt"]] = self._last_chroma
        else:
            a_frame = max(0, f0 - self.cqt_left)
            seg = self._read(a_frame * hop, self.n_in)
            out[:, self.cols["chroma_cqt"]] = self.chroma.frames(seg, np.arange(f0 - a_frame, f1 - a_frame))
            self._last_chroma = out[-1, self.cols["chroma_cqt"]].copy()
        for k, f in enumerate(range(f0, f1)):
            out[k, self.cols["beat"]] = float(f in self.beat_frames)
            if self.preset == "music2dance":
                out[k, self.cols["downbeat"]] = float(f in self.downbeat_frames)
        self.beat_frames = {f for f in self.beat_frames if f >= f1}
        self.downbeat_frames = {f for f in self.downbeat_frames if f >= f1}
        self.next = f1
        return out

    def _tempogram(self, env_new: np.ndarray, f0: int) -> np.ndarray:
        """Rows ``f0 …`` of the online tempogram (see the module's description). ``env_hist`` holds the envelope
        of the frames before ``f0`` (the last ``TEMPOGRAM_WINDOW``), preceded at the stream's start by the offline
        padding (the linear ramp to ``env[0]`` over ``half`` frames) and zeros.

        ``"none"``: row ``f`` is the tempogram of the envelope of frames ``[f - 2·half, f)``, the offline
        tempogram's frame ``f - half``. ``"bar"``: row ``f`` is that of frames ``[f - half, f + half)``, those
        after ``f`` the envelope's last ``P`` frames repeated (``P``: the lag of the strongest autocorrelation of
        frames ``(f - 2·half, f]`` within :data:`BAR_RANGE_S`)."""
        win, half = TEMPOGRAM_WINDOW, TEMPOGRAM_WINDOW // 2
        if self.env_first is None and len(env_new):
            self.env_first = float(env_new[0])
            ramp = np.linspace(0.0, self.env_first, half + 1)[:-1].astype(np.float32)  # np.pad's linear_ramp
            self.env_hist = np.concatenate([np.zeros(win - half, np.float32), ramp])  # zeros before the ramp
            self.env_offset = -win
        rows = np.zeros((len(env_new), win), np.float32)
        hann = self._tempo_win
        bar = self.tempogram_future == "bar"
        lo_lag, hi_lag = self._bar_lags
        for k, e in enumerate(env_new):
            f = f0 + k
            self.env_hist = np.append(self.env_hist, np.float32(e))  # env_hist[: f + 1 - env_offset]: frames up to f
            if not bar:
                lo = f - win - self.env_offset  # the window of frames [f - win, f)
                frame = self.env_hist[lo : lo + win].astype(np.float64)
            else:
                end = f + 1 - self.env_offset
                past = self.env_hist[end - win : end].astype(np.float64)  # frames (f - win, f]
                ac = _dsp.autocorrelate(past * hann, axis=-1)
                P = lo_lag + int(np.argmax(ac[lo_lag : hi_lag + 1]))
                frame = np.empty(win)
                frame[: half + 1] = past[win - half - 1 :]  # frames [f - half, f]
                i = self._future  # frame f - half + i (i > half): the known frame P (or 2P, ...) before it
                frame[half + 1 :] = frame[i - P * ((i - half - 1) // P + 1)]
            ac = _dsp.autocorrelate(frame * hann, axis=-1)
            rows[k] = np.nan_to_num(_dsp.normalize_max(ac[:, None], axis=0)[:, 0], nan=0.0)
        excess = len(self.env_hist) - win
        if excess > 0:
            self.env_hist = self.env_hist[excess:]
            self.env_offset += excess
        return rows


def online_rows(y: np.ndarray, *, preset: str, fps: float, hop_length: int = 512, block_s: float = 0.04,
                lookahead_s: float = 0.08, context_s: float = 6.0, beat_window_s: float = 6.0,
                tempogram_future: str = "bar") -> tuple[np.ndarray, np.ndarray]:
    """The rows a live session computes for a whole recording: ``y`` (mono samples at ``fps · hop_length`` Hz)
    fed to :class:`OnlineFeatures` in blocks of ``block_s`` seconds, then :meth:`~OnlineFeatures.finish`.

    Returns ``(rows (1 + len(y) // hop_length, D) float32, beat_times (s) float64)`` — the same frame count as the
    offline extractor on the same samples; the beats are the causal tracker's.

    Examples
    --------
    >>> rows, beats = online_rows(np.zeros(12800, np.float32), preset="music2dance", fps=25)
    >>> rows.shape, len(beats)
    ((26, 15), 0)
    """
    if not block_s > 0:
        raise ParameterError(f"block_s must be > 0 s, got {block_s!r}")
    f = OnlineFeatures(preset=preset, fps=fps, hop_length=hop_length, lookahead_s=lookahead_s, context_s=context_s,
                       beat_window_s=beat_window_s, tempogram_future=tempogram_future)
    y = np.asarray(y, np.float32).reshape(-1)
    n = max(1, int(round(block_s * f.sr)))
    rows = [f.feed(y[a : a + n]) for a in range(0, len(y), n)]
    rows.append(f.finish())
    return np.concatenate(rows).astype(np.float32), np.array([b.time for b in f.tracker.beats], np.float64)
