"""dancekit.evaluation: score models and generated dances (what ``dancekit evaluate`` and friends run).

The metrics themselves are pure functions (:mod:`dancekit.metrics`); this package runs models, reads and
writes folders and assembles reports.

==========================  ==========================================================================
module                      what
==========================  ==========================================================================
:mod:`.score`               every metric of generated dances against the real ones, one report
                            (:func:`evaluate_motions`; folders: :func:`evaluate_dirs`)
:mod:`.generate`            dance every song of a split with a model, then score it
                            (:func:`evaluate_checkpoint`, ``dancekit evaluate --checkpoint``)
:mod:`.ablation`            FID after each pipeline stage and per set of seeds (``dancekit evaluate
                            --ablate-stages`` / ``--seed-sets K``)
:mod:`.report`              markdown tables (:func:`format_markdown`, :func:`format_comparison`,
                            ``dancekit compare``)
:mod:`.baselines`           calibrating baselines (:func:`run_baselines`, ``dancekit baselines``)
:mod:`.selection`           checkpoint selection on the validation songs (:func:`select_checkpoint`,
                            ``dancekit select-checkpoint``)
:mod:`.steering`            does the genre steer? (:func:`steering`, ``dancekit steering``)
:mod:`.classifiers`         accuracy of the style and music attribute classifiers
                            (:func:`score_classifier`, ``dancekit score-classifier``)
:mod:`.music`               composed music against the real music, with click-track baselines: BCS / BHS,
                            beat F1, tempo, notes accuracy (:func:`evaluate_music`, ``dancekit evaluate
                            --compose`` / ``--music``)
==========================  ==========================================================================

Report layout and metric definitions: ``docs/METRICS.md``; published figures: ``docs/BENCHMARKS.md``.
"""

from dancekit.evaluation.baselines import BASELINES, make_baselines, run_baselines
from dancekit.evaluation.classifiers import (
    music_attribute_scores,
    score_classifier,
    style_classifier_scores,
    style_split_scores,
)
from dancekit.evaluation.generate import dance_split, evaluate_checkpoint
from dancekit.evaluation.music import MusicSettings, compose_split, evaluate_music, format_music_markdown
from dancekit.evaluation.report import (
    TABLE_ROWS,
    format_comparison,
    format_markdown,
    format_value,
    metrics_table,
)
from dancekit.evaluation.score import (
    EvalSettings,
    dance_metrics,
    evaluate_dirs,
    evaluate_motions,
    group_predictions,
    load_classifier,
)
from dancekit.evaluation.selection import select_checkpoint
from dancekit.evaluation.steering import steering

__all__ = [
    "BASELINES",
    "TABLE_ROWS",
    "EvalSettings",
    "MusicSettings",
    "compose_split",
    "dance_metrics",
    "dance_split",
    "evaluate_checkpoint",
    "evaluate_dirs",
    "evaluate_motions",
    "evaluate_music",
    "format_comparison",
    "format_markdown",
    "format_music_markdown",
    "format_value",
    "group_predictions",
    "load_classifier",
    "make_baselines",
    "metrics_table",
    "music_attribute_scores",
    "run_baselines",
    "score_classifier",
    "select_checkpoint",
    "steering",
    "style_classifier_scores",
    "style_split_scores",
]
