"""Inference pipelines: ``Pipeline.from_pretrained(dir)(audio_path, seed=...) -> Motion``.

Pipelines are imported lazily (``from dancekit.pipelines import RevolutionPipeline`` works), so
``dancekit.pipelines.hub`` stays light for commands that only list models.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "RevolutionPipeline": "dancekit.pipelines.revolution",
    "MusicAttributePipeline": "dancekit.pipelines.music_attributes",
    "load_pipeline": "dancekit.pipelines.hub",
    "embedded_models": "dancekit.pipelines.hub",
}

__all__ = ["MusicAttributePipeline", "RevolutionPipeline", "embedded_models", "load_pipeline"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dancekit.pipelines' has no attribute {name!r}")
