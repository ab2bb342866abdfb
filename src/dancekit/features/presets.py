"""The three feature presets and :func:`extract`.

=============  =====  =================================================================
preset         D      column blocks (in order)
=============  =====  =================================================================
revolution     438    mfcc:20, mfcc_delta:20, chroma_cqt:12, tempogram:384,
                      onset_strength:1, beat:1   (Dance Revolution, ICLR 2021, Table 4)
music2dance    15     onset_strength:1, beat:1, downbeat:1, chroma_cqt:12
                      (Music2Dance, §4.2)
dual           53     mfcc:20, mfcc_delta:20, chroma_harmonic:12, beat_percussive:1
                      (dual learning music/dance, MM 2021, §3.1)
=============  =====  =================================================================

Frame alignment: the audio is resampled to ``sr = fps * hop_length`` (see
:func:`feature_sr`), so feature frame ``i`` is motion frame ``i`` and every
preset has ``1 + n_samples // hop_length`` frames, ``n_samples`` counted at
that rate. Beats are tracked on a finer grid (22050 Hz, hop 256) and placed
on frame ``round(t * fps)``. See ``docs/FEATURES.md``.
"""

from __future__ import annotations

import functools
import numbers
import warnings

import numpy as np

from dancekit._checks import check_fps
from dancekit.audio.io import resample, validate_audio
from dancekit.errors import ParameterError
from dancekit.features import rhythm, spectral
from dancekit.features.featureset import FeatureSet

__all__ = ["BACKENDS", "PRESETS", "PRESET_DIMS", "extract", "extract_path", "feature_sr"]

#: Column blocks of each preset: (block name, width).
PRESETS: dict[str, tuple[tuple[str, int], ...]] = {
    "revolution": (
        ("mfcc", 20),
        ("mfcc_delta", 20),
        ("chroma_cqt", 12),
        ("tempogram", 384),
        ("onset_strength", 1),
        ("beat", 1),
    ),
    "music2dance": (("onset_strength", 1), ("beat", 1), ("downbeat", 1), ("chroma_cqt", 12)),
    "dual": (("mfcc", 20), ("mfcc_delta", 20), ("chroma_harmonic", 12), ("beat_percussive", 1)),
}
#: Feature dimension D of each preset.
PRESET_DIMS: dict[str, int] = {name: sum(d for _, d in blocks) for name, blocks in PRESETS.items()}
#: Beat / downbeat trackers.
BACKENDS = ("librosa", "madmom")

_MIN_FEATURE_SR = 2000
_MAX_FEATURE_SR = 192000


def feature_sr(*, fps: float, hop_length: int = 512) -> int:
    """Sample rate that makes feature frames motion frames: ``fps * hop_length``.

    Raises
    ------
    ParameterError
        If ``fps`` is not a positive number, ``hop_length`` not a positive
        integer, their product not a whole number of Hz, or outside
        2 kHz .. 192 kHz.
    """
    if isinstance(hop_length, bool) or not isinstance(hop_length, numbers.Integral) or hop_length < 16:
        raise ParameterError(f"hop_length must be an integer >= 16 samples, got {hop_length!r}")
    sr = check_fps(fps) * int(hop_length)
    if abs(sr - round(sr)) > 1e-6:
        raise ParameterError(
            f"fps * hop_length must be a whole number of Hz, got fps={fps!r} * {hop_length} = {sr}"
        )
    sr = int(round(sr))
    if not _MIN_FEATURE_SR <= sr <= _MAX_FEATURE_SR:
        raise ParameterError(
            f"fps={fps!r} with hop_length={hop_length} gives a feature sample rate of {sr} Hz; "
            f"it must be between {_MIN_FEATURE_SR} and {_MAX_FEATURE_SR} Hz"
        )
    return sr


def check_choice(name: str, value: str, choices) -> None:
    if value not in choices:
        raise ParameterError(f"unknown {name} {value!r}; choose one of {sorted(choices)}")


def _quiet_short_input(fn):
    """Run ``fn`` without librosa's "n_fft=... is too large for input signal" warnings: a 1-2 s clip is
    valid input (its first and last frames are zero-padded), not something to warn a user about."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=r"n_fft=\d+ is too large", category=UserWarning)
            return fn(*args, **kwargs)

    return wrapper


def extract(
    y: np.ndarray, *, sr: int, fps: float, preset: str, hop_length: int = 512, backend: str = "librosa"
) -> FeatureSet:
    """Compute one preset's music features, one row per motion frame.

    Parameters
    ----------
    y : np.ndarray, float, shape (n,)
        Mono audio at any sample rate (validated by
        :func:`dancekit.audio.validate_audio`: at least 1 s, finite).
    sr : int
        Sample rate of ``y`` in Hz.
    fps : float
        Motion frame rate; features are computed at ``sr = fps * hop_length``.
    preset : str
        ``"revolution"`` (438 columns), ``"music2dance"`` (15) or ``"dual"`` (53);
        see :data:`PRESETS` and ``docs/FEATURES.md``.
    hop_length : int
        Hop in samples at the feature rate (512).
    backend : str
        Beat / downbeat tracker: ``"librosa"`` (default) or ``"madmom"``
        (optional extra; ``RNNDownBeatProcessor`` + ``DBNDownBeatTrackingProcessor``).

    Returns
    -------
    FeatureSet
        ``features`` float32 of shape ``(1 + m // hop_length, PRESET_DIMS[preset])``
        where ``m = ceil(n * fps * hop_length / sr)`` (the length after resampling),
        plus ``names``, ``beat_times`` (s), ``tempo`` (BPM), ``fps``, ``preset``.

    Raises
    ------
    ParameterError
        Unknown preset or backend, bad ``fps`` / ``hop_length``, madmom missing.
    AudioError
        Audio that fails validation (too short, non-finite samples, ...).

    Examples
    --------
    >>> from dancekit.audio.synth import click_track
    >>> y = click_track(bpm=120, duration=10.0, sr=22050)
    >>> fs = extract(y, sr=22050, fps=25, preset="music2dance")
    >>> fs.features.shape
    (251, 15)
    """
    return _extract(y, sr=sr, fps=fps, preset=preset, hop_length=hop_length, backend=backend)[0]


@_quiet_short_input
def _extract(
    y: np.ndarray, *, sr: int, fps: float, preset: str, hop_length: int = 512, backend: str = "librosa"
) -> tuple[FeatureSet, np.ndarray | None]:
    """:func:`extract`, and the fine-grid onset envelope the beats were tracked on when that is the full mix's
    (the ``librosa`` backend, presets other than ``dual``; else None): with the features' tempo and beats it
    is the song's :class:`~dancekit.features.pulse.SongBeats`, which :func:`extract_file` caches too."""
    check_choice("preset", preset, PRESETS)
    check_choice("backend", backend, BACKENDS)
    fsr = feature_sr(fps=fps, hop_length=hop_length)
    y = np.asarray(y)
    validate_audio(y, sr=sr)
    if y.ndim != 1:
        raise ParameterError(f"extract needs mono audio of shape (n,), got {y.shape}; load it with mono=True")

    y_feat = resample(y, orig_sr=sr, target_sr=fsr)
    T = spectral.n_frames(n_samples=len(y_feat), hop_length=hop_length)
    y_fine = resample(y, orig_sr=sr, target_sr=rhythm.BEAT_SR)

    cols: dict[str, np.ndarray] = {}  # block -> (T, d)
    downbeat_times = None

    S = spectral.log_melspectrogram(y=y_feat, sr=fsr, hop_length=hop_length)  # (128, T) dB
    if preset in ("revolution", "dual"):
        m = spectral.mfcc(S=S, sr=fsr, hop_length=hop_length)
        cols["mfcc"] = m.T
        cols["mfcc_delta"] = spectral.mfcc_delta(mfcc=m).T
    if preset in ("revolution", "music2dance"):
        env = spectral.onset_strength(S=S, sr=fsr, hop_length=hop_length)
        cols["chroma_cqt"] = spectral.chroma_cqt(y=y_feat, sr=fsr, hop_length=hop_length).T
        cols["onset_strength"] = env[:, None]
        if preset == "revolution":
            cols["tempogram"] = spectral.tempogram(onset_envelope=env, sr=fsr, hop_length=hop_length).T

    if preset == "dual":
        y_h, y_p = spectral.hpss(y=y_fine)
        cols["chroma_harmonic"] = spectral.chroma_cqt(
            y=resample(y_h, orig_sr=rhythm.BEAT_SR, target_sr=fsr), sr=fsr, hop_length=hop_length
        ).T
        beat_source = y_p
    else:
        beat_source = y_fine

    fine_rate = rhythm.BEAT_SR / rhythm.BEAT_HOP
    if backend == "madmom":
        from dancekit.features.madmom_backend import madmom_downbeat_track

        tempo, beat_times, down = madmom_downbeat_track(y=y, sr=sr)  # full mix, original rate
        if preset == "music2dance":
            downbeat_times = down
    else:
        S_fine = rhythm.fine_log_mel(beat_source)
        env_fine = rhythm.fine_onset(S_fine)
        tempo, beat_times = rhythm.beat_track_fine(S_fine, env_fine)
        if preset == "music2dance":
            downbeat_times = rhythm.downbeats_fine(S_fine, env_fine, beat_times)
        del S_fine
    if backend == "madmom" or preset == "dual":  # the strength is measured on the full mix's envelope
        env_fine = rhythm.fine_onset(rhythm.fine_log_mel(y_fine))
    strength = rhythm.beat_strength(onset_envelope=env_fine, rate=fine_rate)

    onehot = rhythm.beat_onehot(beat_times=beat_times, fps=fps, n_frames=T)
    if preset == "dual":
        cols["beat_percussive"] = onehot[:, None]
    else:
        cols["beat"] = onehot[:, None]
    if preset == "music2dance":
        assert downbeat_times is not None
        cols["downbeat"] = rhythm.beat_onehot(beat_times=downbeat_times, fps=fps, n_frames=T)[:, None]

    blocks = PRESETS[preset]
    for name, d in blocks:
        assert cols[name].shape == (T, d), (name, cols[name].shape, (T, d))
    features = np.ascontiguousarray(
        np.concatenate([cols[name] for name, _ in blocks], axis=1), dtype=np.float32
    )
    assert features.shape == (T, PRESET_DIMS[preset])
    assert np.isfinite(features).all(), "non-finite feature values from finite audio"
    fs = _feature_set(features, blocks=blocks, beat_times=beat_times, fps=fps, preset=preset, tempo=tempo,
                      hop_length=hop_length, downbeat_times=downbeat_times, strength=strength)
    return fs, (env_fine if backend == "librosa" and preset != "dual" else None)


def _feature_set(features: np.ndarray, *, blocks, beat_times, fps: float, preset: str, tempo: float,
                 hop_length: int, downbeat_times, strength: float) -> FeatureSet:
    """The :class:`FeatureSet` of a preset's feature matrix (T, D) and its beat grid (times in seconds)."""
    return FeatureSet(
        features=features,
        names=tuple(f"{name}:{d}" for name, d in blocks),
        beat_times=np.asarray(beat_times, dtype=np.float64),
        fps=float(fps),
        preset=preset,
        tempo=float(tempo),
        hop_length=int(hop_length),
        downbeat_times=None if downbeat_times is None else np.asarray(downbeat_times, dtype=np.float64),
        beat_strength=strength,
    )


class _Spool:
    """A float32 signal written block by block to an unnamed temporary file and read back by sample ranges:
    the feature-rate song (184 MB for an hour at 12.8 kHz) stays on disk while the chunks are analysed."""

    def __init__(self):
        import tempfile
        import weakref

        self.fh = tempfile.TemporaryFile(prefix="dancekit-song-")
        # closed (and so deleted) with the spool too, when an error unwinds before close(): no ResourceWarning
        weakref.finalize(self, self.fh.close)
        self.n = 0
        self.nonzero = False

    def add(self, block: np.ndarray) -> None:
        block = np.ascontiguousarray(block, dtype="<f4")
        self.fh.write(block.tobytes())
        self.n += len(block)
        self.nonzero = self.nonzero or bool(np.any(block))

    def read(self, a: int, b: int) -> np.ndarray:
        """Samples ``[a, b)`` (clipped to the signal) as float32."""
        a, b = max(0, int(a)), min(self.n, int(b))
        self.fh.seek(4 * a)
        return np.frombuffer(self.fh.read(4 * max(0, b - a)), dtype="<f4").astype(np.float32)

    def close(self) -> None:
        self.fh.close()


def expected_sample_count(path, start: float | None, end: float | None, rate: int) -> int:
    """The decoded length at ``rate`` that libsndfile's header promises (0 when unknown)."""
    import soundfile as sf

    from dancekit.audio.io import quiet_c_stderr

    try:
        with quiet_c_stderr():  # libsndfile's mpg123 prints notes on a damaged mp3 to fd 2
            info = sf.info(str(path))
    except Exception:  # not a libsndfile format: ffmpeg decodes it in one block
        return 0
    a = 0.0 if start is None else float(start)
    b = info.frames / info.samplerate if end is None else min(float(end), info.frames / info.samplerate)
    return int(np.ceil(max(0.0, b - a) * rate)) + 16


def extract_path(
    path, *, fps: float, preset: str, hop_length: int = 512, backend: str = "librosa",
    start: float | None = None, end: float | None = None, chunk: int | None = None,
) -> FeatureSet:
    """:func:`extract` of an audio file (its excerpt ``[start, end)`` s), in memory bounded by a chunk rather
    than the song: the file is decoded in blocks and resampled on the fly (:func:`dancekit.audio.io.stream`;
    the native-rate song is never held), the fine beat-tracking spectrogram is built from the streamed
    blocks (:class:`~dancekit.features.spectral.MelPowerStream`), and the chromagram and tempogram are
    computed ``chunk`` frames at a time with enough context on both sides
    (:func:`~dancekit.features.spectral.chroma_cqt_chunked`, :func:`~dancekit.features.spectral.tempogram_chunked`).
    What remains in memory is the two mel spectrograms and the output: the song at the feature rate
    (``fps * hop_length`` Hz, float32) waits in a temporary file for the chromagram's chunks.

    The result equals ``extract(*load(path, start=start, end=end), ...)`` to float rounding (the constant-Q
    chunks: ~1e-6; everything else bit for bit); ``tests/features/test_streaming.py`` checks it with a small chunk.
    The ``dual`` preset (harmonic / percussive separation of the whole song) and the madmom backend take
    the whole-song path of :func:`extract`.

    Parameters
    ----------
    path : an audio file :func:`dancekit.audio.load` reads
    fps, preset, hop_length, backend : as :func:`extract`
    start, end : excerpt in seconds
    chunk : frames per chromagram / tempogram chunk (default :data:`dancekit.features.spectral.CHUNK_FRAMES`)
    """
    return extraction_path(path, fps=fps, preset=preset, hop_length=hop_length, backend=backend, start=start,
                         end=end, chunk=chunk)[0]


@_quiet_short_input
def extraction_path(
    path, *, fps: float, preset: str, hop_length: int = 512, backend: str = "librosa",
    start: float | None = None, end: float | None = None, chunk: int | None = None,
) -> tuple[FeatureSet, np.ndarray | None]:
    """:func:`extract_path`, and the fine-grid onset envelope of the beats as :func:`_extract` returns it
    (for :func:`dancekit.features.extract_file`'s cached song beats)."""
    from dancekit.audio.io import load, stream

    check_choice("preset", preset, PRESETS)
    check_choice("backend", backend, BACKENDS)
    fsr = feature_sr(fps=fps, hop_length=hop_length)
    if backend != "librosa" or preset == "dual":
        y, sr = load(path, start=start, end=end)
        return _extract(y, sr=sr, fps=fps, preset=preset, hop_length=hop_length, backend=backend)
    chunk = spectral.CHUNK_FRAMES if chunk is None else int(chunk)
    expected = expected_sample_count(path, start, end, fsr)
    y_feat = _Spool()
    n_fft = spectral.default_n_fft(None, hop_length)
    mel = spectral.MelPowerStream(sr=fsr, n_fft=n_fft, hop_length=hop_length, expected_samples=expected)
    fine = spectral.MelPowerStream(sr=rhythm.BEAT_SR, n_fft=rhythm.BEAT_NFFT, hop_length=rhythm.BEAT_HOP,
                                   expected_samples=expected_sample_count(path, start, end, rhythm.BEAT_SR))
    for block_feat, block_fine in stream(path, rates=[fsr, rhythm.BEAT_SR], start=start, end=end):
        y_feat.add(block_feat)
        mel.feed(block_feat)
        fine.feed(block_fine)
    # the beat grid first: its spectrogram (160 MB per hour) is freed before the feature matrix is filled
    S_fine = spectral.power_to_db_inplace(fine.finish())
    del fine
    env_fine = rhythm.fine_onset_chunked(S_fine)
    tempo, beat_times = rhythm.beat_track_fine(S_fine, env_fine)
    downbeat_times = rhythm.downbeats_fine(S_fine, env_fine, beat_times) if preset == "music2dance" else None
    del S_fine
    strength = rhythm.beat_strength(onset_envelope=env_fine, rate=rhythm.BEAT_SR / rhythm.BEAT_HOP)
    try:
        T = spectral.n_frames(n_samples=y_feat.n, hop_length=hop_length)
        blocks = PRESETS[preset]
        at, col = {}, 0
        for name, d in blocks:
            at[name] = slice(col, col + d)
            col += d
        features = np.zeros((T, PRESET_DIMS[preset]), np.float32)

        # log_melspectrogram(y=y, ...) from the streamed mel power (the same chunks: the same numbers)
        S = spectral.fit_frames(spectral.power_to_db_inplace(mel.finish()), T)  # (128, T) dB
        del mel
        if preset == "revolution":
            m = spectral.mfcc(S=S, sr=fsr, hop_length=hop_length)
            features[:, at["mfcc"]] = m.T
            features[:, at["mfcc_delta"]] = spectral.mfcc_delta(mfcc=m).T
        env = spectral.onset_strength(S=S, sr=fsr, hop_length=hop_length)
        del S
        features[:, at["onset_strength"]] = env[:, None]
        spectral.chroma_cqt_chunked(y=y_feat.read if y_feat.nonzero else np.zeros(y_feat.n, np.float32), sr=fsr,
                                    hop_length=hop_length, chunk=chunk, out=features[:, at["chroma_cqt"]],
                                    n_samples=y_feat.n)
    finally:
        y_feat.close()
    if preset == "revolution":
        spectral.tempogram_chunked(onset_envelope=env, chunk=chunk, out=features[:, at["tempogram"]])

    features[:, at["beat"]] = rhythm.beat_onehot(beat_times=beat_times, fps=fps, n_frames=T)[:, None]
    if preset == "music2dance":
        features[:, at["downbeat"]] = rhythm.beat_onehot(beat_times=downbeat_times, fps=fps, n_frames=T)[:, None]
    assert np.isfinite(features).all(), "non-finite feature values from finite audio"
    fs = _feature_set(features, blocks=blocks, beat_times=beat_times, fps=fps, preset=preset, tempo=tempo,
                      hop_length=hop_length, downbeat_times=downbeat_times, strength=strength)
    return fs, env_fine
