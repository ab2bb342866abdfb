"""dancekit.metrics: NumPy in, NumPy out, fps- and skeleton-aware evaluation of dances.

Pure functions: arrays (joint positions ``(T, J, 3)``, beat times, feature vectors) in, numbers or
arrays out. The metrics import nothing of dancekit but the motion analysis helpers
(:mod:`dancekit.motion.analysis`), :mod:`dancekit.errors` and :mod:`dancekit._checks`: no torch, no
models, no files. Scoring generated dances with a model or from folders is :mod:`dancekit.evaluation`.

=====================  ====================================================================
module                 metrics
=====================  ====================================================================
:mod:`.fid`            AIST++ FID_k / FID_g, Div_k / Div_g, the Fréchet distance
:mod:`.beat`           kinematic beats, BAS (Bailando and AIST++ conventions), beat
                       coverage and hit rate (Dance Revolution)
:mod:`.style`          on style-classifier features: FID, ACC, Diversity, Multimodality
:mod:`.stability`      FID over windows, freeze score, stillness share, smoothed energy, jitter
:mod:`.physics`        foot skating, PFC, bone-length variation, ground penetration,
                       torso lean
:mod:`.floor`          the floor report: how far the figure floats over the local floor, the
                       share of frames near it, the planted-foot share
:mod:`.music`          dance-to-music: notes accuracy (key-normalised), chroma L1, beat L1
:mod:`.music_beats`    composed music against a reference: beat coverage / hit (BCS, BHS; the
                       D2M-GAN/CDCD and LORIS protocols), beat F1 (mir_eval), tempo, click baselines
:mod:`.distance`       mean joint distance (the dual-learning paper's "Fréchet distance")
=====================  ====================================================================

Definitions, defaults and deviations from the papers: ``docs/METRICS.md``.
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
    feature_names,
    fid_breakdown,
    fid_diversity,
    frechet_distance,
    frechet_distance_from_stats,
    geometric_features,
    kinetic_features,
    normalize_features,
)
from dancekit.metrics.floor import floor_contact
from dancekit.metrics.music import beat_l1, chroma_l1, estimate_key, notes_accuracy, transpose_to_c
from dancekit.metrics.music_beats import (
    beat_f1,
    clicks_on,
    clip_bin_counts,
    clip_bin_counts_audio,
    coverage_hit,
    coverage_hit_audio,
    coverage_hit_scores,
    dense_clicks,
    metronome,
    onset_bins,
    onset_times,
    tempo_error,
    tempo_from_beats,
    tempo_hit,
    wrong_tempo_metronome,
)
from dancekit.metrics.physics import bone_length_variation, foot_skating, ground_penetration, pfc, torso_lean
from dancekit.metrics.stability import (
    freeze_score,
    jitter,
    smoothed_energy,
    stillness_share,
    windowed_fid,
)
from dancekit.metrics.style import (
    balanced_accuracy,
    classification_scores,
    dance_genre,
    multimodality,
    style_diversity,
    style_fid,
)

__all__ = [
    "beat_f1",
    "clicks_on",
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
    "GEOMETRIC_FEATURE_NAMES",
    "average_pairwise_distance",
    "balanced_accuracy",
    "beat_align_score",
    "beat_coverage",
    "beat_hit_rate",
    "beat_l1",
    "beat_metrics",
    "bone_length_variation",
    "chroma_l1",
    "classification_scores",
    "dance_genre",
    "estimate_key",
    "feature_names",
    "fid_breakdown",
    "fid_diversity",
    "floor_contact",
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
    "multimodality",
    "normalize_features",
    "notes_accuracy",
    "pfc",
    "smoothed_energy",
    "stillness_share",
    "style_diversity",
    "style_fid",
    "torso_lean",
    "transpose_to_c",
    "windowed_fid",
]

