"""Inference pipelines (inference only: no training or dataset imports).

``Pipeline.from_pretrained(name_or_folder)(audio_path, seed=...) -> DanceResult`` for dance models, and
``pipe.dances(audio_path, seeds=[0, 1, 2]) -> list[DanceResult]`` (the song read once, one dance per seed, each bit for bit the seed's dance alone) for every
dance family (revolution, music2dance, dual);
:func:`load_pipeline` picks the pipeline class from the family registry (:mod:`dancekit.registry`).
Pipelines are imported lazily (``from dancekit.pipelines import RevolutionPipeline`` works).
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "RevolutionPipeline": "dancekit.pipelines.revolution",
    "MusicAttributePipeline": "dancekit.pipelines.music_attributes",
    "StylePipeline": "dancekit.pipelines.style",
    "DanceResult": "dancekit.pipelines.base",
    "DancePipeline": "dancekit.pipelines.dance",
    "StageConfig": "dancekit.pipelines.config",
    "DualPipeline": "dancekit.pipelines.dual",
    "ComposePipeline": "dancekit.pipelines.dual",
    "Music2DancePipeline": "dancekit.pipelines.music2dance",
    "FootConstraintPipeline": "dancekit.pipelines.foot_constraint",
    "load_pipeline": "dancekit.pipelines.base",
    "parse_seeds": "dancekit.pipelines.base",
}

__all__ = ["ComposePipeline", "DancePipeline", "DanceResult", "StageConfig", "DualPipeline", "FootConstraintPipeline", "Music2DancePipeline",
           "MusicAttributePipeline", "RevolutionPipeline", "StylePipeline", "load_pipeline", "parse_seeds"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dancekit.pipelines' has no attribute {name!r}")
