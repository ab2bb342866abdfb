"""Finding pipelines: embedded default models and checkpoint folders.

Embedded models ship inside the package in ``dancekit/assets/models/<name>/`` (a checkpoint
folder plus ``card.json`` describing the training data, training time and metrics), so they
are found without any download. ``load_pipeline`` accepts an embedded model's name or any
checkpoint folder and returns the inference pipeline of its model family.
"""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path

from dancekit.errors import CheckpointError, ParameterError

MODELS_DIR = Path(__file__).resolve().parents[1] / "assets" / "models"
DEFAULT_MODEL = "revolution"

# model family (config.json "model") → "module:Class" of its inference pipeline
PIPELINES: dict[str, str] = {
    "revolution": "dancekit.pipelines.revolution:RevolutionPipeline",
}


def embedded_models() -> dict[str, Path]:
    """Name → folder of every embedded dance model (folders holding a ``config.json``)."""
    if not MODELS_DIR.is_dir():
        return {}
    return {
        p.name: p
        for p in sorted(MODELS_DIR.iterdir())
        if p.is_dir() and (p / "config.json").is_file() and p.name in _dance_model_names()
    }


def _dance_model_names() -> set[str]:
    names = set()
    for p in MODELS_DIR.iterdir():
        cfg = p / "config.json"
        if cfg.is_file():
            try:
                if json.loads(cfg.read_text()).get("model") in PIPELINES:
                    names.add(p.name)
            except json.JSONDecodeError:
                continue
    return names


def model_card(folder: str | os.PathLike) -> dict:
    """The ``card.json`` of a checkpoint folder (empty when there is none)."""
    card = Path(folder) / "card.json"
    return json.loads(card.read_text()) if card.is_file() else {}


def resolve_checkpoint(model: str | None = None, checkpoint: str | os.PathLike | None = None) -> Path:
    """Folder of the checkpoint to use: ``checkpoint`` if given, else the embedded ``model`` (default model)."""
    if checkpoint is not None:
        path = Path(checkpoint)
        if not (path / "config.json").is_file():
            raise CheckpointError(f"not a checkpoint folder (no config.json): {path}")
        return path
    name = model or DEFAULT_MODEL
    models = embedded_models()
    if name not in models:
        known = ", ".join(models) or "none"
        raise ParameterError(f"unknown model {name!r} (embedded models: {known}; or pass --checkpoint DIR)")
    return models[name]


def load_pipeline(model: str | None = None, checkpoint: str | os.PathLike | None = None):
    """The inference pipeline of an embedded model (by name) or of a checkpoint folder."""
    folder = resolve_checkpoint(model, checkpoint)
    try:
        family = json.loads((folder / "config.json").read_text())["model"]
    except (json.JSONDecodeError, KeyError) as exc:
        raise CheckpointError(f"corrupt config.json in {folder}: {exc}") from exc
    if family not in PIPELINES:
        raise CheckpointError(f"{folder} holds a {family!r} model, which has no dance pipeline")
    module_name, cls_name = PIPELINES[family].split(":")
    cls = getattr(importlib.import_module(module_name), cls_name)
    return cls.from_pretrained(folder)
