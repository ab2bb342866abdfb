"""Paired (music, dance) datasets: preparation, whole-dance splits, windows, normalisation."""

from dancekit.data.prepared import (
    DEFAULT_PRESETS,
    GENRES,
    AudioRef,
    PreparedData,
    floor_curve,
    prepare_tang2018,
    split_by_genre,
    tang2018_genre,
)
from dancekit.data.representation import REPRESENTATIONS, decode_motion, encode_motion, pose_dim
from dancekit.data.stats import NormStats
from dancekit.data.windows import WindowDataset, compute_stats, load_pairs

__all__ = [
    "DEFAULT_PRESETS",
    "GENRES",
    "REPRESENTATIONS",
    "AudioRef",
    "NormStats",
    "PreparedData",
    "WindowDataset",
    "compute_stats",
    "decode_motion",
    "encode_motion",
    "floor_curve",
    "load_pairs",
    "pose_dim",
    "prepare_tang2018",
    "split_by_genre",
    "tang2018_genre",
]
