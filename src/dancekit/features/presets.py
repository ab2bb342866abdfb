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

__all__ = ["BACKENDS", "PRESETS", "PRESET_DIMS", "extract", "feature_sr"]

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


def _check_choice(name: str, value: str, choices) -> None:
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
    _check_choice("preset", preset, PRESETS)
    _check_choice("backend", backend, BACKENDS)
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
        S_fine = rhythm._fine_log_mel(beat_source)
        env_fine = rhythm._fine_onset(S_fine)
        tempo, beat_times = rhythm._beat_track_fine(S_fine, env_fine)
        if preset == "music2dance":
            downbeat_times = rhythm._downbeats_fine(S_fine, env_fine, beat_times)
        del S_fine
    if backend == "madmom" or preset == "dual":  # the strength is measured on the full mix's envelope
        env_fine = rhythm._fine_onset(rhythm._fine_log_mel(y_fine))
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
    fs = FeatureSet(
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
    return fs, (env_fine if backend == "librosa" and preset != "dual" else None)
