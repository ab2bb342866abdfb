"""Load + extract with an on-disk cache keyed by the song's content and every parameter."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import re
import warnings
from pathlib import Path

from dancekit._io import file_sha256
from dancekit.audio.io import check_audio_path
from dancekit.errors import DancekitError, ParameterError
from dancekit.features.featureset import FeatureSet
from dancekit.features.presets import BACKENDS, PRESETS, check_choice, extraction_path, feature_sr

__all__ = ["CACHE_MAX_BYTES", "FEATURES_VERSION", "cache_key", "cache_max_bytes", "default_cache_dir",
           "extract_file", "prune_cache"]

#: Bump when feature values change, so stale cache entries are never read.
FEATURES_VERSION = 3  # 2: FeatureSet.beat_strength; 3: streamed extraction (extract_path: chromagram in chunks,
# ~1e-6) computed by features._dsp (NumPy) instead of librosa calls (same beats, tempo and downbeats; spectral
# values equal to librosa's to float32 rounding, |diff| <= 6e-5: see docs/FEATURES.md)

#: Default size bound of the feature cache folder in bytes (1 GiB: about twenty 20-minute songs'
#: revolution features); ``DANCEKIT_CACHE_MAX_MB`` overrides it.
CACHE_MAX_BYTES = 1 << 30

_ENTRY = re.compile(r"[0-9a-f]{64}(?:\.beats)?\.npz")  # music features; a song's beats (features.pulse)


def cache_max_bytes() -> int:
    """The cache's size bound in bytes: ``$DANCEKIT_CACHE_MAX_MB`` MiB if set (0 keeps only the newest entry),
    else :data:`CACHE_MAX_BYTES`.

    Raises
    ------
    ParameterError
        ``DANCEKIT_CACHE_MAX_MB`` is not a number >= 0.
    """
    text = os.environ.get("DANCEKIT_CACHE_MAX_MB", "").strip()
    if not text:
        return CACHE_MAX_BYTES
    try:
        mb = float(text)
    except ValueError:
        mb = -1.0
    if not mb >= 0 or mb == float("inf"):
        raise ParameterError(f"DANCEKIT_CACHE_MAX_MB must be a number of MiB >= 0, got {text!r}")
    return int(mb * (1 << 20))


def prune_cache(folder: str | os.PathLike, *, max_bytes: int, keep: str | os.PathLike | None = None) -> list[Path]:
    """Delete the least recently used cache entries of ``folder`` until the entries total at most
    ``max_bytes`` bytes; ``keep`` (the entry just written) is never deleted.

    Only files named like entries (64 hex digits + ``.npz`` or ``.beats.npz``) are counted or deleted, so a cache folder
    pointed at a folder with other files never loses them. Entries are ordered by modification time;
    :func:`extract_file` touches an entry when it reads it, so this is least-recently-used order.

    Returns
    -------
    list of Path
        The entries deleted, oldest first.
    """
    folder = Path(folder)
    keep_name = None if keep is None else Path(keep).name
    entries = []
    for p in folder.iterdir():
        if not _ENTRY.fullmatch(p.name):
            continue
        try:
            st = p.stat()
        except FileNotFoundError:  # removed meanwhile by another process
            continue
        entries.append((st.st_mtime, p.name, st.st_size, p))
    total = sum(e[2] for e in entries)
    removed = []
    for _, name, size, p in sorted(entries):
        if total <= max_bytes:
            break
        if name == keep_name:
            continue
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
            removed.append(p)
        total -= size
    return removed


def default_cache_dir() -> Path:
    """``$DANCEKIT_CACHE/features`` if ``DANCEKIT_CACHE`` is set, else ``~/.cache/dancekit/features``."""
    root = os.environ.get("DANCEKIT_CACHE")
    return (Path(root).expanduser() if root else Path.home() / ".cache" / "dancekit") / "features"


def cache_key(
    *,
    sha256: str,
    fps: float,
    preset: str,
    hop_length: int,
    start: float | None,
    end: float | None,
    backend: str,
) -> str:
    """Hex key of one (song content, parameters, code version) combination."""
    params = {
        "version": FEATURES_VERSION,
        "librosa": _librosa_version(),
        "sha256": sha256,
        "fps": float(fps),
        "preset": preset,
        "hop_length": int(hop_length),
        "start": None if start is None else float(start),
        "end": None if end is None else float(end),
        "backend": backend,
    }
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()


@functools.lru_cache(maxsize=1)
def _librosa_version() -> str:
    """librosa's version from its metadata (the dual preset's HPSS still runs librosa); no import of librosa,
    which costs half a second."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("librosa")
    except PackageNotFoundError:
        return "none"


def extract_file(
    path: str | os.PathLike,
    *,
    fps: float,
    preset: str,
    start: float | None = None,
    end: float | None = None,
    hop_length: int = 512,
    backend: str = "librosa",
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
) -> FeatureSet:
    """Load an audio file (or an excerpt) and :func:`~dancekit.features.extract` a preset, with caching.

    The features are computed by :func:`~dancekit.features.presets.extract_path`: the song is decoded and
    resampled in blocks and the chromagram and tempogram computed in chunks, so memory is bounded by a
    chunk (plus the feature-rate song and the output), equal to :func:`extract` on the loaded song to float
    rounding.

    The cache entry is ``<cache_dir>/<key>.npz`` where the key hashes the
    file's SHA-256 and every parameter, so editing the file or changing any
    argument misses the cache. Entries are written atomically; an unreadable
    entry is recomputed and overwritten. A cache folder that cannot be
    created only disables caching (with a warning). The folder is bounded:
    after each write the least recently used entries beyond
    :func:`cache_max_bytes` (1 GiB, or ``$DANCEKIT_CACHE_MAX_MB``) are deleted
    (:func:`prune_cache`).

    Parameters
    ----------
    path : str or PathLike
        Audio file (any format :func:`dancekit.audio.load` reads).
    fps, preset, hop_length, backend
        As for :func:`~dancekit.features.extract`.
    start, end : float, optional
        Excerpt in seconds; ``beat_times`` are relative to ``start``.
    cache_dir : str or PathLike, optional
        Defaults to :func:`default_cache_dir`.
    use_cache : bool
        ``False`` neither reads nor writes the cache.

    Returns
    -------
    FeatureSet
        ``from_cache`` is True when the result was read from the cache.

    Raises
    ------
    AudioError, ParameterError
        As for :func:`dancekit.audio.load` and :func:`~dancekit.features.extract`.
    """
    check_choice("preset", preset, PRESETS)
    check_choice("backend", backend, BACKENDS)
    feature_sr(fps=fps, hop_length=hop_length)
    path = Path(path)
    entry = None
    max_bytes = 0
    sha = None
    if use_cache:
        max_bytes = cache_max_bytes()  # a bad DANCEKIT_CACHE_MAX_MB is an error before any work
        check_audio_path(path)
        sha = file_sha256(path)
        key = cache_key(
            sha256=sha,
            fps=fps,
            preset=preset,
            hop_length=hop_length,
            start=start,
            end=end,
            backend=backend,
        )
        folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        entry = folder / f"{key}.npz"
        if entry.is_file():
            try:
                fs = FeatureSet.load(entry)
            except DancekitError:
                fs = None  # corrupt entry: recompute below
            if fs is not None and fs.preset == preset and fs.fps == float(fps):
                with contextlib.suppress(OSError):
                    os.utime(entry)  # recently used: pruned last
                return _with_flag(fs, True)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            warnings.warn(f"feature cache disabled: cannot create {str(folder)!r} ({exc})", stacklevel=2)
            entry = None

    fs, env_fine = extraction_path(path, fps=fps, preset=preset, hop_length=hop_length, backend=backend, start=start,
                                 end=end)
    if entry is not None:
        try:
            fs.save(entry)
            prune_cache(entry.parent, max_bytes=max_bytes, keep=entry)
        except (OSError, DancekitError) as exc:
            warnings.warn(f"could not write feature cache entry {str(entry)!r} ({exc})", stacklevel=2)
        if env_fine is not None:  # the song's beats were tracked just now: the beat-sync stage reads them
            from dancekit.features import pulse

            beats_entry = pulse.beats_cache_entry(path, start=start, end=end, cache_dir=entry.parent, sha256=sha)
            if not beats_entry.is_file():
                pulse.save_beats(beats_entry, pulse.beats_from_fine(env_fine, fs.tempo, fs.beat_times))
    return fs


def _with_flag(fs: FeatureSet, from_cache: bool) -> FeatureSet:
    from dataclasses import replace

    return replace(fs, from_cache=from_cache)
