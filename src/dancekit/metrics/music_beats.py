"""Rhythm scores of generated music against reference music, as the dance-to-music field reports them.

Onset bins (both published protocols)
    Onsets are binarised into bins of ``bin_size`` seconds (1 s in both protocols): bin ``i``
    of a clip is 1 when some onset falls in ``[i * bin_size, (i + 1) * bin_size)`` of that clip.
    A clip of duration ``d`` has ``ceil(d / bin_size)`` bins (a partial last bin counts, as in
    the published scripts). Per clip three counts are kept: the reference bins (``R``, bins
    with a reference onset), the generated bins (``G``) and the hits (``H``, bins with both).

Protocol A (D2M-GAN / CDCD, ``L-YeZhu/Beats_Scores``)
    Onsets: ``librosa.onset.onset_detect(wait=1, delta=0.2, pre_avg=1, post_avg=1, post_max=1)``
    (``pre_max`` left at librosa's default, 1 frame at 22050 Hz). Per clip
    ``BCS = G / R`` (can exceed 1) and ``BHS = H / R``; each is averaged over clips.

Protocol B (LORIS, ``OpenGVLab/LORIS``)
    Onsets: ``onset_detect(wait=1, delta=0.2, pre_avg=3, post_avg=3, pre_max=3, post_max=3)``.
    Per clip ``BCS = H / G`` (precision) and ``BHS = H / R`` (recall); BCS and BHS are their
    means over clips, CSD and HSD their sample standard deviations (``ddof=1``) over clips,
    and ``F1 = 2 * BCS * BHS / (BCS + BHS)`` is computed from the two means.

Clips
    The published numbers are computed on fixed-length clips (2 s for A on AIST++, 5 s and
    longer for B). ``clip_length=L`` cuts the compared span into consecutive clips
    ``[k L, (k + 1) L)``; a trailing piece shorter than ``L`` is dropped. ``clip_length=None``
    scores the whole span as one clip. A clip shorter than one bin (possible only for the whole
    span) is skipped. With audio, the detector runs on every clip separately (each clip is a
    file in the published evaluations), after resampling to 22050 Hz (``librosa.load``'s
    default, which both scripts use); generated and reference audio are compared over the
    shorter of the two.

Undefined ratios
    A clip whose ratio has a zero denominator (no reference onset for ``G / R`` and ``H / R``,
    no generated onset for ``H / G``) gets ``zero_division`` for that ratio: NaN by default,
    which leaves the clip out of that ratio's mean and standard deviation. A score with no
    defined clip is NaN; a standard deviation needs two defined clips, else NaN. The LORIS
    script scores such clips 0 (``zero_division=0.0`` reproduces it); the D2M-GAN script
    divides by zero.

Beat F1 and tempo
    :func:`beat_f1` is ``mir_eval.beat.f_measure`` with a ±0.1 s window (mir_eval's default is
    0.07 s). mir_eval's MIREX convention removes beats before 5 s (``trim_beats``, applied by
    ``mir_eval.beat.evaluate``, not by ``f_measure``); clips here are often shorter than that,
    so nothing is trimmed unless ``min_beat_time`` is given. :func:`tempo_error` is relative;
    a doubled or halved tempo counts as a miss unless ``allow_octave=True``.

Baselines
    Click tracks given by their click times (no detector or beat tracker needed): a metronome
    at a tempo with a seeded random phase, one at a wrong tempo (±20 %), a dense click track
    (4 clicks a second, which games the bin scores) and clicks on given times (e.g. a dance's
    kinematic beats).

Times are in seconds (float64); audio is a mono float array ``(n,)`` with its ``sr``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dancekit.errors import ParameterError

__all__ = [
    "ONSET_PARAMS",
    "beat_f1",
    "bin_counts",
    "clicks_on",
    "clip_spans",
    "clip_bin_counts",
    "clip_bin_counts_audio",
    "coverage_hit",
    "coverage_hit_audio",
    "coverage_hit_scores",
    "dense_clicks",
    "metronome",
    "onset_bins",
    "onset_times",
    "tempo_error",
    "tempo_from_beats",
    "tempo_hit",
    "wrong_tempo_metronome",
]

#: librosa ``onset_detect`` peak-picking settings of the two published protocols.
ONSET_PARAMS: dict[str, dict[str, float]] = {
    "A": {"wait": 1, "delta": 0.2, "pre_avg": 1, "post_avg": 1, "post_max": 1},
    "B": {"wait": 1, "delta": 0.2, "pre_avg": 3, "post_avg": 3, "pre_max": 3, "post_max": 3},
}
DETECTOR_SR = 22050
DEFAULT_BIN = 1.0
DEFAULT_TOLERANCE = 0.1
_EPS = 1e-9


# ----------------------------------------------------------------------------- checks


def _positive(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a positive number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ParameterError(f"{name} must be a positive number, got {value!r}")
    return v


def _duration(value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"duration must be a number of seconds >= 0, got {value!r}") from None
    if not math.isfinite(v) or v < 0:
        raise ParameterError(f"duration must be a number of seconds >= 0, got {value!r}")
    return v


def _times(times: Any, name: str) -> np.ndarray:
    t = np.asarray(times, dtype=np.float64)
    if t.ndim > 1:
        raise ParameterError(f"{name} must be a 1-D array of times in seconds, got shape {t.shape}")
    t = t.reshape(-1)
    if not np.isfinite(t).all():
        raise ParameterError(f"{name} contain NaN or inf")
    return np.sort(t)


def _protocol(protocol: str) -> str:
    if protocol not in ONSET_PARAMS:
        raise ParameterError(f"unknown protocol {protocol!r}; choose 'A' (D2M-GAN / CDCD) or 'B' (LORIS)")
    return protocol


def _clip_length(clip_length: float | None, bin_size: float) -> float | None:
    if clip_length is None:
        return None
    c = _positive("clip_length", clip_length)
    if c < bin_size - _EPS:
        raise ParameterError(f"clip_length ({c} s) is shorter than one bin ({bin_size} s)")
    return c


def _audio(y: Any, name: str) -> np.ndarray:
    a = np.asarray(y)
    if a.ndim != 1 or not np.issubdtype(a.dtype, np.floating):
        raise ParameterError(f"{name} must be a mono float audio array (n,), got {a.dtype} {a.shape}")
    if not np.isfinite(a).all():
        raise ParameterError(f"{name} audio contains NaN or inf")
    return a


# ----------------------------------------------------------------------------- onsets and bins


def onset_times(
    y: np.ndarray, *, sr: int, protocol: str = "A", detector_sr: int | None = DETECTOR_SR
) -> np.ndarray:
    """Onset times (seconds) of a mono signal with the librosa detector settings of a protocol.

    Parameters
    ----------
    y : (n,) float audio
    sr : sample rate of ``y``
    protocol : ``"A"`` (D2M-GAN / CDCD) or ``"B"`` (LORIS), see :data:`ONSET_PARAMS`
    detector_sr : resample to this rate first (22050 Hz, as the published scripts load audio);
        None runs the detector at ``sr``

    Returns
    -------
    (N,) float64 onset times in seconds, increasing; empty for silence.
    """
    import librosa

    params = ONSET_PARAMS[_protocol(protocol)]
    y = _audio(y, "y")
    sr = int(_positive("sr", sr))
    if detector_sr is not None and int(detector_sr) != sr:
        y = librosa.resample(y, orig_sr=sr, target_sr=int(_positive("detector_sr", detector_sr)))
        sr = int(detector_sr)
    if len(y) == 0:
        return np.zeros(0)
    t = librosa.onset.onset_detect(y=np.ascontiguousarray(y), sr=sr, units="time", **params)
    return np.asarray(t, dtype=np.float64)


def onset_bins(times: np.ndarray, *, duration: float, bin_size: float = DEFAULT_BIN) -> np.ndarray:
    """Binary onset bins ``(ceil(duration / bin_size),)``: True where an onset falls in the bin.

    Onsets outside ``[0, duration)`` are ignored; bin ``i`` covers ``[i, i + 1) * bin_size``.
    """
    duration = _duration(duration)
    bin_size = _positive("bin_size", bin_size)
    t = _times(times, "onset times")
    n = int(math.ceil(duration / bin_size - _EPS))
    bins = np.zeros(n, dtype=bool)
    t = t[(t >= 0) & (t < duration)]
    idx = np.floor(t / bin_size + _EPS).astype(np.int64)
    bins[idx[idx < n]] = True
    return bins


def clip_spans(
    duration: float, *, clip_length: float | None = None, bin_size: float = DEFAULT_BIN
) -> list[tuple[float, float]]:
    """``(start, length)`` in seconds of every scored clip of a span of ``duration`` seconds.

    Consecutive clips ``[k L, (k + 1) L)`` (a trailing piece shorter than ``L`` is dropped), or the
    whole span as one clip for ``clip_length=None`` (none when it is shorter than one bin).
    """
    duration = _duration(duration)
    bin_size = _positive("bin_size", bin_size)
    return _spans(duration, _clip_length(clip_length, bin_size), bin_size)


def bin_counts(generated: np.ndarray, reference: np.ndarray, *, duration: float,
               bin_size: float = DEFAULT_BIN) -> np.ndarray:
    """The counts ``(3,)`` [R, G, H] of one clip from its onset times (seconds from the clip's start)."""
    return np.asarray(
        _counts(onset_bins(generated, duration=duration, bin_size=bin_size),
                onset_bins(reference, duration=duration, bin_size=bin_size)),
        dtype=np.int64,
    )


def _spans(duration: float, clip_length: float | None, bin_size: float) -> list[tuple[float, float]]:
    """``(start, length)`` of every scored clip of a span of ``duration`` seconds."""
    if clip_length is None:
        return [(0.0, duration)] if duration >= bin_size - _EPS else []
    n = int(math.floor(duration / clip_length + _EPS))
    return [(k * clip_length, clip_length) for k in range(n)]


def _counts(gen_bins: np.ndarray, ref_bins: np.ndarray) -> list[int]:
    return [int(ref_bins.sum()), int(gen_bins.sum()), int((ref_bins & gen_bins).sum())]


def clip_bin_counts(
    generated: np.ndarray,
    reference: np.ndarray,
    *,
    duration: float,
    clip_length: float | None = None,
    bin_size: float = DEFAULT_BIN,
) -> np.ndarray:
    """Per-clip bin counts of two onset (or click) time lists over ``[0, duration)``.

    Parameters
    ----------
    generated, reference : onset times in seconds
    duration : length of the compared span, seconds
    clip_length : clip length in seconds (>= ``bin_size``), or None for the whole span
    bin_size : seconds per bin

    Returns
    -------
    (n_clips, 3) int64: reference bins ``R``, generated bins ``G``, hits ``H`` per clip.
    ``n_clips`` is 0 when the span is shorter than a clip (or, whole, than a bin).
    Counts of several songs can be stacked (``np.concatenate``) before
    :func:`coverage_hit_scores`, which averages over clips.
    """
    duration = _duration(duration)
    bin_size = _positive("bin_size", bin_size)
    clip = _clip_length(clip_length, bin_size)
    g, r = _times(generated, "generated onsets"), _times(reference, "reference onsets")
    rows = []
    for start, length in _spans(duration, clip, bin_size):
        gb = onset_bins(g - start, duration=length, bin_size=bin_size)
        rb = onset_bins(r - start, duration=length, bin_size=bin_size)
        rows.append(_counts(gb, rb))
    return np.asarray(rows, dtype=np.int64).reshape(-1, 3)


def clip_bin_counts_audio(
    generated: np.ndarray,
    reference: np.ndarray,
    *,
    sr: int,
    protocol: str = "A",
    clip_length: float | None = None,
    bin_size: float = DEFAULT_BIN,
    detector_sr: int | None = DETECTOR_SR,
) -> np.ndarray:
    """Per-clip bin counts ``(n_clips, 3)`` [R, G, H] of two signals, detecting onsets clip by clip.

    Both signals share ``sr`` and are compared over the shorter one; the detector
    (:func:`onset_times` with the protocol's settings) runs on each clip on its own.
    """
    sr = int(_positive("sr", sr))
    bin_size = _positive("bin_size", bin_size)
    clip = _clip_length(clip_length, bin_size)
    _protocol(protocol)
    g, r = _audio(generated, "generated"), _audio(reference, "reference")
    n = min(len(g), len(r))
    rows = []
    for start, length in _spans(n / sr, clip, bin_size):
        a = int(round(start * sr))
        b = min(n, int(round((start + length) * sr)))
        tg = onset_times(g[a:b], sr=sr, protocol=protocol, detector_sr=detector_sr)
        tr = onset_times(r[a:b], sr=sr, protocol=protocol, detector_sr=detector_sr)
        rows.append(
            _counts(
                onset_bins(tg, duration=length, bin_size=bin_size),
                onset_bins(tr, duration=length, bin_size=bin_size),
            )
        )
    return np.asarray(rows, dtype=np.int64).reshape(-1, 3)


# ----------------------------------------------------------------------------- scores


def _ratio(num: np.ndarray, den: np.ndarray, zero_division: float) -> np.ndarray:
    out = np.full(len(num), float(zero_division))
    ok = den > 0
    out[ok] = num[ok] / den[ok]
    return out


def _mean(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(x.mean()) if len(x) else float("nan")


def _std(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(x.std(ddof=1)) if len(x) >= 2 else float("nan")


def coverage_hit_scores(
    counts: np.ndarray, *, protocol: str = "A", zero_division: float = float("nan")
) -> dict:
    """Beat coverage and hit scores from per-clip bin counts (see the module docstring).

    Parameters
    ----------
    counts : (n_clips, 3) [R, G, H] per clip (:func:`clip_bin_counts`, stackable across songs)
    protocol : ``"A"`` (D2M-GAN / CDCD) or ``"B"`` (LORIS)
    zero_division : a clip's ratio when its denominator is 0 (NaN: the clip is left out)

    Returns
    -------
    dict. Protocol A: ``bcs`` (mean G/R), ``bhs`` (mean H/R), ``n_clips``. Protocol B:
    ``bcs`` (mean H/G), ``bhs`` (mean H/R), ``csd``, ``hsd`` (their standard deviations,
    ``ddof=1``), ``f1`` (from the means; 0 when both are 0), ``n_clips``.
    """
    protocol = _protocol(protocol)
    c = np.asarray(counts)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ParameterError(f"counts must be an (n_clips, 3) array [R, G, H], got shape {c.shape}")
    c = c.astype(np.float64)
    if (c < 0).any() or (c[:, 2] > np.minimum(c[:, 0], c[:, 1])).any():
        raise ParameterError("counts must be >= 0 with hits <= min(reference bins, generated bins)")
    ref, gen, hit = c[:, 0], c[:, 1], c[:, 2]
    bhs_clips = _ratio(hit, ref, zero_division)
    if protocol == "A":
        return {"bcs": _mean(_ratio(gen, ref, zero_division)), "bhs": _mean(bhs_clips), "n_clips": len(c)}
    bcs_clips = _ratio(hit, gen, zero_division)
    bcs, bhs = _mean(bcs_clips), _mean(bhs_clips)
    if not (math.isfinite(bcs) and math.isfinite(bhs)):
        f1 = float("nan")
    else:
        f1 = 2.0 * bcs * bhs / (bcs + bhs) if bcs + bhs > 0 else 0.0
    return {
        "bcs": bcs,
        "bhs": bhs,
        "csd": _std(bcs_clips),
        "hsd": _std(bhs_clips),
        "f1": f1,
        "n_clips": len(c),
    }


def coverage_hit(
    generated: np.ndarray,
    reference: np.ndarray,
    *,
    duration: float,
    protocol: str = "A",
    clip_length: float | None = None,
    bin_size: float = DEFAULT_BIN,
    zero_division: float = float("nan"),
) -> dict:
    """BCS / BHS (and for B: CSD, HSD, F1) of onset or click times; see :func:`coverage_hit_scores`.

    Examples
    --------
    >>> clicks = metronome(bpm=120, duration=10, phase=0.1)
    >>> coverage_hit(dense_clicks(duration=10), clicks, duration=10, protocol="A")["bcs"]
    1.0
    """
    counts = clip_bin_counts(
        generated, reference, duration=duration, clip_length=clip_length, bin_size=bin_size
    )
    return coverage_hit_scores(counts, protocol=protocol, zero_division=zero_division)


def coverage_hit_audio(
    generated: np.ndarray,
    reference: np.ndarray,
    *,
    sr: int,
    protocol: str = "A",
    clip_length: float | None = None,
    bin_size: float = DEFAULT_BIN,
    zero_division: float = float("nan"),
    detector_sr: int | None = DETECTOR_SR,
) -> dict:
    """BCS / BHS (and for B: CSD, HSD, F1) of two signals, detecting onsets with the protocol's settings."""
    counts = clip_bin_counts_audio(
        generated,
        reference,
        sr=sr,
        protocol=protocol,
        clip_length=clip_length,
        bin_size=bin_size,
        detector_sr=detector_sr,
    )
    return coverage_hit_scores(counts, protocol=protocol, zero_division=zero_division)


# ----------------------------------------------------------------------------- beat F1 and tempo


def beat_f1(
    estimated: np.ndarray,
    reference: np.ndarray,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    min_beat_time: float = 0.0,
) -> float:
    """F-measure of estimated beats against reference beats (``mir_eval.beat.f_measure``).

    Parameters
    ----------
    estimated, reference : beat times in seconds
    tolerance : half-width of the matching window, seconds (0.1 here; mir_eval's default is 0.07)
    min_beat_time : beats before this time are removed from both first (``mir_eval.beat.trim_beats``;
        the MIREX convention is 5 s, the default 0 keeps every beat so short clips can be scored)

    Returns
    -------
    float in [0, 1]; NaN when no reference beat is left, 0 when only the estimate is empty.
    """
    import mir_eval

    tolerance = _positive("tolerance", tolerance)
    est = _times(estimated, "estimated beats")
    ref = _times(reference, "reference beats")
    est, ref = est[est >= min_beat_time], ref[ref >= min_beat_time]
    if len(ref) == 0:
        return float("nan")
    if len(est) == 0:
        return 0.0
    return float(mir_eval.beat.f_measure(ref, est, f_measure_threshold=tolerance))


def tempo_from_beats(beats: np.ndarray) -> float:
    """Tempo in BPM from beat times: ``60 / median inter-beat interval`` (NaN with fewer than 2 beats)."""
    b = _times(beats, "beats")
    d = np.diff(b)
    d = d[d > 0]
    return float(60.0 / np.median(d)) if len(d) else float("nan")


def tempo_error(estimated_bpm: float, reference_bpm: float, *, allow_octave: bool = False) -> float:
    """Relative tempo error ``|est - ref| / ref``.

    With ``allow_octave=True`` the smallest error over ``est``, ``2 est`` and ``est / 2`` is
    returned, so a doubled or halved tempo scores 0; by default it counts fully (a doubled
    tempo has error 1.0, a halved one 0.5). NaN when the estimate is NaN.
    """
    ref = _positive("reference_bpm", reference_bpm)
    est = float(estimated_bpm)
    if math.isnan(est):
        return float("nan")
    est = _positive("estimated_bpm", est)
    factors = (1.0, 2.0, 0.5) if allow_octave else (1.0,)
    return float(min(abs(est * f - ref) / ref for f in factors))


def tempo_hit(
    estimated_bpm: float, reference_bpm: float, *, tolerance: float = 0.05, allow_octave: bool = False
) -> bool:
    """Whether the tempo is within ``tolerance`` (relative, default ±5 %) of the reference's.

    A doubled or halved tempo is a miss unless ``allow_octave=True``; a NaN estimate is a miss.
    """
    tolerance = _positive("tolerance", tolerance)
    err = tempo_error(estimated_bpm, reference_bpm, allow_octave=allow_octave)
    return bool(err <= tolerance + _EPS)


# ----------------------------------------------------------------------------- click-track baselines


def metronome(
    *, bpm: float, duration: float, seed: int | np.random.Generator | None = None, phase: float | None = None
) -> np.ndarray:
    """Click times of a metronome: ``phase + k * 60 / bpm`` in ``[0, duration)``.

    ``phase`` (seconds, in ``[0, 60 / bpm)``) is drawn uniformly from ``np.random.default_rng(seed)``
    when not given, so a seeded baseline is reproducible.
    """
    period = 60.0 / _positive("bpm", bpm)
    duration = _duration(duration)
    if phase is None:
        phase = float(np.random.default_rng(seed).uniform(0.0, period))
    elif not (math.isfinite(phase) and 0.0 <= phase < period):
        raise ParameterError(f"phase must be in [0, {period}) seconds, got {phase!r}")
    n = max(0, int(math.ceil((duration - phase) / period - _EPS)))
    return phase + period * np.arange(n, dtype=np.float64)


def wrong_tempo_metronome(
    *,
    bpm: float,
    duration: float,
    factor: float = 1.2,
    seed: int | np.random.Generator | None = None,
    phase: float | None = None,
) -> np.ndarray:
    """A metronome at ``factor * bpm`` (1.2 or 0.8: the ±20 % baseline), random phase as :func:`metronome`."""
    factor = _positive("factor", factor)
    if abs(factor - 1.0) < _EPS:
        raise ParameterError("factor must differ from 1 for a wrong-tempo metronome")
    return metronome(bpm=_positive("bpm", bpm) * factor, duration=duration, seed=seed, phase=phase)


def dense_clicks(*, duration: float, rate: float = 4.0, phase: float = 0.0) -> np.ndarray:
    """A dense click track: ``rate`` clicks a second (4 by default) from ``phase``, in ``[0, duration)``."""
    rate = _positive("rate", rate)
    return metronome(bpm=60.0 * rate, duration=duration, phase=phase)


def clicks_on(times: np.ndarray, *, duration: float) -> np.ndarray:
    """Clicks on given times (e.g. a dance's kinematic beats): sorted, unique, kept in ``[0, duration)``."""
    duration = _duration(duration)
    t = _times(times, "click times")
    return np.unique(t[(t >= 0) & (t < duration)])
