"""Checkpoints and model lookup, shared by training (which writes them) and pipelines (which read them).

- :mod:`dancekit.checkpoints.folder`: a checkpoint is a folder (``config.json`` + ``model.safetensors`` +
  ``stats.npz``) that rebuilds its model from itself alone (:func:`save_pretrained`, :func:`load_pretrained`).
- :mod:`dancekit.checkpoints.stats`: :class:`NormStats`, normalisation statistics as plain arrays.
- :mod:`dancekit.checkpoints.hub`: :func:`resolve_model` (a name or path → a folder: explicit path, the
  user's models folder, the embedded models) and :func:`components` (the parts of a composite model).

The names from :mod:`~dancekit.checkpoints.folder` (which imports torch) load on first use, so that
:func:`resolve_model` and :func:`read_meta` serve a process that has not imported torch yet (a cold
``dancekit dance`` reads its model's feature settings before, :mod:`dancekit.features.prefetch`).
"""

from typing import Any

from dancekit.checkpoints.hub import (
    DEFAULT_MODEL,
    MODELS_DIR,
    available_models,
    components,
    declare_components,
    embedded_models,
    model_card,
    model_cards,
    read_meta,
    resolve_model,
    user_models_dir,
)
from dancekit.checkpoints.stats import NormStats

_FOLDER = ("CONFIG_FILE", "STATS_FILE", "WEIGHTS_FILE", "build_model", "load_pretrained", "read_config",
           "save_pretrained", "write_pretrained")


def __getattr__(name: str) -> Any:
    if name in _FOLDER:
        from dancekit.checkpoints import folder

        return getattr(folder, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "CONFIG_FILE",
    "DEFAULT_MODEL",
    "MODELS_DIR",
    "STATS_FILE",
    "WEIGHTS_FILE",
    "NormStats",
    "available_models",
    "build_model",
    "components",
    "declare_components",
    "embedded_models",
    "load_pretrained",
    "model_card",
    "model_cards",
    "read_config",
    "read_meta",
    "resolve_model",
    "save_pretrained",
    "user_models_dir",
    "write_pretrained",
]
