"""Does a song have a beat to dance to? Beat tracking plus a pulse-clarity test.

:func:`song_beats` tracks the beats on the fine grid of :func:`dancekit.features.beat_track` (22050 Hz,
hop 256: librosa's tracker halves the tempo on a coarse motion-rate grid) and measures the *pulse
clarity*: the autocorrelation of the mean-removed onset envelope at the beat period, normalised by its
value at lag 0 (1: a perfectly periodic envelope; ~0: no periodicity at that tempo). librosa always
returns beats, even for noise, a bird's call or a whale's song; a clarity below
:data:`MIN_PULSE_CLARITY` or fewer than :data:`MIN_BEATS` beats means "no beat".

Calibration (first 60 s of each file; ``../shared/music``): Sugar Plum Fairy 0.45, Vibe Ace 0.22, Brahms'
Hungarian dance no. 5 (string orchestra, rubato) 0.09, a synthesised Ode to Joy 0.89; a humpback
whale's song −0.003, white noise −0.02; the robin's single call gives 3 beats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancekit.errors import DancekitError
from dancekit.features.rhythm import (
    BEAT_HOP,
    BEAT_SR,
    beat_track_fine,
    fine_log_mel,
    fine_onset,
    fine_onset_chunked,
    to_beat_sr,
)

__all__ = ["MIN_BEATS", "MIN_PULSE_CLARITY", "SongBeats", "pulse_clarity", "song_beats", "song_beats_file"]

#: Below this pulse clarity a song is taken to have no beat.
MIN_PULSE_CLARITY = 0.05
#: A song with fewer tracked beats than this has no beat.
MIN_BEATS = 4


@dataclass(frozen=True)
class SongBeats:
    """Beats of a song: ``tempo`` (BPM), ``times`` ((B,) float64 seconds from the start of the audio),
    ``clarity`` (:func:`pulse_clarity`) and ``has_beat`` (enough beats and a clear enough pulse)."""

    tempo: float
    times: np.ndarray
    clarity: float
    has_beat: bool


def pulse_clarity(*, envelope: np.ndarray, tempo: float, frame_rate: float = BEAT_SR / BEAT_HOP) -> float:
    """Normalised autocorrelation of an onset envelope ``(n,)`` at the beat period ``60 / tempo`` s (the
    maximum over ±2 lags around it); 0.0 for a zero tempo or a constant envelope."""
    e = np.asarray(envelope, dtype=np.float64).reshape(-1)
    if not tempo > 0 or len(e) < 4:
        return 0.0
    e = e - e.mean()
    power = float(e @ e)
    if power <= 0:
        return 0.0
    lag = int(round(60.0 / float(tempo) * float(frame_rate)))
    values = [float(e[:-k] @ e[k:]) / power for k in range(max(1, lag - 2), lag + 3) if 0 < k < len(e)]
    return max(values) if values else 0.0


def song_beats(*, y: np.ndarray, sr: int, min_clarity: float = MIN_PULSE_CLARITY,
               min_beats: int = MIN_BEATS) -> SongBeats:
    """Beats of the audio ``y`` ``(n,)`` at ``sr`` Hz and whether it has a beat (see the module docstring)."""
    S_db = fine_log_mel(to_beat_sr(y, sr))
    env = fine_onset(S_db)
    tempo, times = beat_track_fine(S_db, env)
    return beats_from_fine(env, tempo, times, min_clarity=min_clarity, min_beats=min_beats)


def beats_cache_entry(path, *, start: float | None, end: float | None, cache_dir, sha256: str | None = None):
    """The cache file of a song's (excerpt's) :class:`SongBeats`, beside the music features."""
    from pathlib import Path

    from dancekit._io import file_sha256
    from dancekit.features.cache import cache_key, default_cache_dir

    key = cache_key(sha256=sha256 or file_sha256(Path(path)), fps=float(BEAT_SR) / BEAT_HOP, preset="song_beats",
                    hop_length=BEAT_HOP, start=start, end=end, backend="librosa")
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return folder / f"{key}.beats.npz"


def save_beats(entry, beats: SongBeats) -> None:
    from dancekit._io import atomic_path

    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(entry) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, tempo=beats.tempo, times=beats.times, clarity=beats.clarity, has_beat=beats.has_beat)
    except (OSError, DancekitError):
        pass  # caching is an optimisation only


def beats_from_fine(env: np.ndarray, tempo: float, times: np.ndarray, *, min_clarity: float = MIN_PULSE_CLARITY,
                     min_beats: int = MIN_BEATS) -> SongBeats:
    clarity = pulse_clarity(envelope=env, tempo=tempo)
    return SongBeats(tempo=float(tempo), times=np.asarray(times, np.float64), clarity=float(clarity),
                     has_beat=bool(len(times) >= min_beats and clarity >= min_clarity))


def song_beats_file(path, *, start: float | None = None, end: float | None = None, cache_dir=None,
                    use_cache: bool = True) -> SongBeats:
    """:func:`song_beats` of an audio file (or its excerpt ``[start, end)`` s; times from ``start``), cached
    beside the music features (:func:`dancekit.features.default_cache_dir`, keyed on the file's content and
    the excerpt), so that a song danced again does not track its beats again.
    :func:`dancekit.features.extract_file` fills this entry as well (the beats it tracks for the features
    are these beats), so the pipeline's beat-sync stage reads what the features step found."""
    from pathlib import Path

    from dancekit.audio.io import check_audio_path

    entry = None
    if use_cache:
        check_audio_path(Path(path))
        entry = beats_cache_entry(path, start=start, end=end, cache_dir=cache_dir)
        if entry.is_file():
            try:
                with np.load(entry) as z:
                    return SongBeats(tempo=float(z["tempo"]), times=np.asarray(z["times"], np.float64),
                                     clarity=float(z["clarity"]), has_beat=bool(z["has_beat"]))
            except (OSError, KeyError, ValueError, EOFError):
                pass  # an unreadable entry is recomputed
    beats = _song_beats_streamed(path, start=start, end=end)
    if entry is not None:
        save_beats(entry, beats)
    return beats


def _song_beats_streamed(path, *, start: float | None, end: float | None, min_clarity: float = MIN_PULSE_CLARITY,
                         min_beats: int = MIN_BEATS) -> SongBeats:
    """:func:`song_beats` of ``load(path, sr=BEAT_SR, start=start, end=end)`` with the song decoded and
    resampled in blocks straight into the fine mel spectrogram (:class:`~dancekit.features.spectral.MelPowerStream`,
    the same numbers): the song itself is never held, at any rate."""
    from dancekit.audio.io import stream
    from dancekit.features.presets import expected_sample_count
    from dancekit.features.rhythm import BEAT_NFFT
    from dancekit.features.spectral import MelPowerStream, power_to_db_inplace

    mel = MelPowerStream(sr=BEAT_SR, n_fft=BEAT_NFFT, hop_length=BEAT_HOP,
                         expected_samples=expected_sample_count(path, start, end, BEAT_SR))
    for (block,) in stream(path, rates=[BEAT_SR], start=start, end=end):
        mel.feed(block)
    S_db = power_to_db_inplace(mel.finish())
    env = fine_onset_chunked(S_db)
    tempo, times = beat_track_fine(S_db, env)
    del S_db
    return beats_from_fine(env, tempo, times, min_clarity=min_clarity, min_beats=min_beats)
