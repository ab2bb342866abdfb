"""Paired (music, dance) datasets: preparation, whole-dance splits, training windows.

How a dance becomes a model's vector lives in :mod:`dancekit.motion.representations`; normalisation
statistics in :mod:`dancekit.checkpoints.stats` (they travel with checkpoints).
"""

from dancekit.data.online import prepare_online
from dancekit.data.pairs import prepare_pairs
from dancekit.data.prepared import (
    DEFAULT_PRESETS,
    GENRES,
    AudioRef,
    PreparedData,
    prepare_tang2018,
    split_by_genre,
    tang2018_genre,
)
from dancekit.data.windows import WindowDataset, compute_stats, load_pairs

__all__ = [
    "DEFAULT_PRESETS",
    "GENRES",
    "AudioRef",
    "PreparedData",
    "WindowDataset",
    "compute_stats",
    "load_pairs",
    "prepare_online",
    "prepare_pairs",
    "prepare_tang2018",
    "split_by_genre",
    "tang2018_genre",
]
