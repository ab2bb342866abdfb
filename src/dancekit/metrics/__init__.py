"""dancekit.metrics: NumPy in, NumPy out, fps- and skeleton-aware evaluation of dances.

=====================  ====================================================================
module                 metrics
=====================  ====================================================================
:mod:`.fid`            AIST++ FID_k / FID_g, Div_k / Div_g, the Fréchet distance
:mod:`.beat`           kinematic beats, BAS (Bailando and AIST++ conventions), beat
                       coverage and hit rate (Dance Revolution)
:mod:`.style`          genre classifier; style FID, ACC, Diversity, Multimodality
:mod:`.stability`      FID over windows, freeze score, stillness share, smoothed energy, jitter
:mod:`.physics`        foot skating, PFC, bone-length variation, ground penetration
:mod:`.music`          dance-to-music: notes accuracy (key-normalised), chroma L1, beat L1
:mod:`.distance`       mean joint distance (the dual-learning paper's "Fréchet distance")
:mod:`.evaluate`       every metric over a folder of generated dances, one report
=====================  ====================================================================

Definitions, defaults and deviations from the papers: ``docs/METRICS.md``. The style
classifier (torch) is imported on first use.
"""

from dancekit.metrics.beat import (
    beat_align_score,
    beat_coverage,
    beat_hit_rate,
    beat_metrics,
    kinematic_beats,
)
from dancekit.metrics.distance import mean_joint_distance
from dancekit.metrics.fid import (
    GEOMETRIC_FEATURE_NAMES,
    average_pairwise_distance,
    fid_diversity,
    frechet_distance,
    frechet_distance_from_stats,
    geometric_features,
    kinetic_features,
    normalize_features,
)
from dancekit.metrics.music import beat_l1, chroma_l1, estimate_key, notes_accuracy, transpose_to_c
from dancekit.metrics.physics import bone_length_variation, foot_skating, ground_penetration, pfc
from dancekit.metrics.stability import (
    freeze_score,
    jitter,
    smoothed_energy,
    stillness_share,
    windowed_fid,
)

_LAZY = {
    "StyleModel": "dancekit.metrics.style",
    "load_style_classifier": "dancekit.metrics.style",
    "train_style_classifier": "dancekit.metrics.style",
    "fit_style_classifier": "dancekit.metrics.style",
    "evaluate_dirs": "dancekit.metrics.evaluate",
    "evaluate_motions": "dancekit.metrics.evaluate",
    "format_markdown": "dancekit.metrics.evaluate",
    "EvalSettings": "dancekit.metrics.evaluate",
}

__all__ = [
    "GEOMETRIC_FEATURE_NAMES",
    "average_pairwise_distance",
    "beat_align_score",
    "beat_coverage",
    "beat_hit_rate",
    "beat_l1",
    "beat_metrics",
    "bone_length_variation",
    "chroma_l1",
    "estimate_key",
    "fid_diversity",
    "foot_skating",
    "freeze_score",
    "frechet_distance",
    "frechet_distance_from_stats",
    "geometric_features",
    "ground_penetration",
    "jitter",
    "kinematic_beats",
    "kinetic_features",
    "mean_joint_distance",
    "normalize_features",
    "notes_accuracy",
    "pfc",
    "smoothed_energy",
    "stillness_share",
    "transpose_to_c",
    "windowed_fid",
    *_LAZY,
]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dancekit.metrics' has no attribute {name!r}")
