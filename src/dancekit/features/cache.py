"""Load + extract with an on-disk cache keyed by the song's content and every parameter."""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

from dancekit._io import file_sha256
from dancekit.audio.io import check_audio_path, load
from dancekit.errors import DancekitError
from dancekit.features.featureset import FeatureSet
from dancekit.features.presets import BACKENDS, PRESETS, _check_choice, extract, feature_sr

__all__ = ["FEATURES_VERSION", "cache_key", "default_cache_dir", "extract_file"]

#: Bump when feature values change, so stale cache entries are never read.
FEATURES_VERSION = 1


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
    import librosa

    params = {
        "version": FEATURES_VERSION,
        "librosa": librosa.__version__,
        "sha256": sha256,
        "fps": float(fps),
        "preset": preset,
        "hop_length": int(hop_length),
        "start": None if start is None else float(start),
        "end": None if end is None else float(end),
        "backend": backend,
    }
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()


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

    The cache entry is ``<cache_dir>/<key>.npz`` where the key hashes the
    file's SHA-256 and every parameter, so editing the file or changing any
    argument misses the cache. Entries are written atomically; an unreadable
    entry is recomputed and overwritten. A cache folder that cannot be
    created only disables caching (with a warning).

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
    _check_choice("preset", preset, PRESETS)
    _check_choice("backend", backend, BACKENDS)
    feature_sr(fps=fps, hop_length=hop_length)
    path = Path(path)
    entry = None
    if use_cache:
        check_audio_path(path)
        key = cache_key(
            sha256=file_sha256(path),
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
                return _with_flag(fs, True)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            warnings.warn(f"feature cache disabled: cannot create {str(folder)!r} ({exc})", stacklevel=2)
            entry = None

    y, sr = load(path, start=start, end=end)
    fs = extract(y, sr=sr, fps=fps, preset=preset, hop_length=hop_length, backend=backend)
    if entry is not None:
        try:
            fs.save(entry)
        except (OSError, DancekitError) as exc:
            warnings.warn(f"could not write feature cache entry {str(entry)!r} ({exc})", stacklevel=2)
    return fs


def _with_flag(fs: FeatureSet, from_cache: bool) -> FeatureSet:
    from dataclasses import replace

    return replace(fs, from_cache=from_cache)
