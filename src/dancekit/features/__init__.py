"""dancekit.features: music features frame-aligned to a motion frame rate.

Pure NumPy functions with keyword-only arguments (``spectral``, ``rhythm``),
three presets (``revolution`` 438-D, ``music2dance`` 15-D, ``dual`` 53-D)
computed by :func:`extract` on audio arrays or :func:`extract_file` on files
(with an on-disk cache). Audio is resampled to ``sr = fps * hop_length`` so
feature frame ``i`` is motion frame ``i``; see ``docs/FEATURES.md``.
"""

from dancekit.features.cache import (
    CACHE_MAX_BYTES,
    FEATURES_VERSION,
    cache_key,
    cache_max_bytes,
    default_cache_dir,
    extract_file,
    prune_cache,
)
from dancekit.features.featureset import FeatureSet, parse_names
from dancekit.features.madmom_backend import import_madmom, madmom_available, madmom_downbeat_track
from dancekit.features.presets import BACKENDS, PRESET_DIMS, PRESETS, extract, feature_sr
from dancekit.features.rhythm import (
    BEAT_HOP,
    BEAT_SR,
    MUSIC_BEAT_STRENGTH,
    beat_onehot,
    beat_strength,
    beat_track,
    downbeats,
    fold_meter,
)
from dancekit.features.spectral import (
    chroma_cqt,
    hpss,
    log_melspectrogram,
    mfcc,
    mfcc_delta,
    n_frames,
    onset_strength,
    tempogram,
)

__all__ = [
    "BACKENDS",
    "BEAT_HOP",
    "BEAT_SR",
    "CACHE_MAX_BYTES",
    "FEATURES_VERSION",
    "MUSIC_BEAT_STRENGTH",
    "PRESETS",
    "PRESET_DIMS",
    "FeatureSet",
    "beat_onehot",
    "beat_strength",
    "beat_track",
    "cache_key",
    "cache_max_bytes",
    "chroma_cqt",
    "default_cache_dir",
    "downbeats",
    "extract",
    "extract_file",
    "feature_sr",
    "fold_meter",
    "hpss",
    "import_madmom",
    "log_melspectrogram",
    "madmom_available",
    "madmom_downbeat_track",
    "mfcc",
    "mfcc_delta",
    "n_frames",
    "onset_strength",
    "parse_names",
    "prune_cache",
    "tempogram",
]
