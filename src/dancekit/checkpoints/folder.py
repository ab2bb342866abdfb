"""Checkpoints that rebuild themselves: ``config.json`` + ``model.safetensors`` + ``stats.npz``.

A checkpoint folder holds

``config.json``
    ``{"model": family, "config": {...dataclass fields}, "representation", "preset", "fps",
    "skeleton": {...}, "train": {...}, ...}`` — the family name and the model configuration, plus
    whatever ``extra`` the caller gave (data settings, training configuration).
``model.safetensors``
    the weights (``state_dict``), no pickled code.
``stats.npz``
    normalisation statistics as plain arrays (``music_mean``, ``music_std``, ``dance_mean``,
    ``dance_std``).

The family name resolves through :mod:`dancekit.registry` (the one table of model families).
A composite model (a dance model with its genre models and its music attribute classifier) lists its
components in ``config.json`` under ``"components"`` (see :mod:`dancekit.checkpoints.hub`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from dancekit import registry
from dancekit._io import atomic_dir
from dancekit.errors import CheckpointError, ParameterError

CONFIG_FILE = "config.json"
WEIGHTS_FILE = "model.safetensors"
STATS_FILE = "stats.npz"

def _stats_arrays(stats: Any) -> dict[str, np.ndarray]:
    if stats is None:
        return {}
    arrays = stats.as_arrays() if hasattr(stats, "as_arrays") else dict(stats)
    return {k: np.asarray(v) for k, v in arrays.items()}


def write_pretrained(
    folder: str | os.PathLike,
    model: nn.Module,
    config: Any,
    *,
    stats: Any = None,
    extra: Mapping[str, Any] | None = None,
) -> None:
    """Write the three checkpoint files into an existing ``folder`` (no atomicity: see :func:`save_pretrained`)."""
    from safetensors.torch import save_file

    folder = Path(folder)
    if not dataclasses.is_dataclass(config):
        raise ParameterError(f"config must be a dataclass instance, got {type(config).__name__}")
    doc = {"model": registry.family_of(model), "config": dataclasses.asdict(config), **(extra or {})}
    (folder / CONFIG_FILE).write_text(json.dumps(doc, indent=1, default=_json_default))
    state = {k: v.detach().to("cpu").contiguous() for k, v in model.state_dict().items()}
    save_file(state, str(folder / WEIGHTS_FILE))
    np.savez(folder / STATS_FILE, **_stats_arrays(stats))


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"cannot write {type(obj).__name__} to config.json")


def save_pretrained(
    folder: str | os.PathLike,
    model: nn.Module,
    config: Any,
    *,
    stats: Any = None,
    extra: Mapping[str, Any] | None = None,
) -> Path:
    """Save a model so that :func:`load_pretrained` can rebuild it from the folder alone.

    The folder is written beside its final place and renamed when complete
    (:func:`dancekit._io.atomic_dir`); an existing folder is replaced.

    Parameters
    ----------
    folder : checkpoint folder to create
    model : a model of a registered family (e.g. :class:`~dancekit.models.revolution.RevolutionModel`)
    config : its dataclass configuration
    stats : normalisation statistics: a :class:`~dancekit.data.NormStats` or a mapping of arrays
    extra : more JSON-serialisable entries for ``config.json`` (representation, preset, fps,
        skeleton, train, ...)

    Returns
    -------
    The folder path.
    """
    with atomic_dir(folder) as tmp:
        write_pretrained(tmp, model, config, stats=stats, extra=extra)
    return Path(folder)


def read_config(folder: str | os.PathLike) -> dict[str, Any]:
    """The parsed ``config.json`` of a checkpoint folder."""
    folder = Path(folder)
    path = folder / CONFIG_FILE
    if not folder.is_dir():
        raise CheckpointError(f"checkpoint folder not found: {folder}")
    if not path.is_file():
        raise CheckpointError(f"not a checkpoint: {path} is missing")
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CheckpointError(f"corrupt checkpoint file {path}: {exc}") from exc
    if not isinstance(doc, dict) or "model" not in doc or "config" not in doc:
        raise CheckpointError(f"corrupt checkpoint file {path}: needs the keys 'model' and 'config'")
    return doc


def build_model(family: str, config: Mapping[str, Any], *, folder: str | os.PathLike = "?") -> nn.Module:
    """A fresh model of ``family`` from a configuration mapping."""
    try:
        fam = registry.get(family)
        config_cls, model_cls = fam.config_class, fam.module_class
    except ParameterError as exc:
        raise CheckpointError(f"checkpoint {folder}: {exc}") from exc
    names = {f.name for f in dataclasses.fields(config_cls)}
    unknown = sorted(set(config) - names)
    if unknown:
        raise CheckpointError(
            f"checkpoint {folder}: config keys {unknown} are unknown to {config_cls.__name__} "
            "(saved by another version of the code?)"
        )
    try:
        return model_cls(config_cls(**config))
    except (TypeError, ParameterError) as exc:
        raise CheckpointError(f"checkpoint {folder}: bad model configuration: {exc}") from exc


def load_pretrained(
    folder: str | os.PathLike, *, device: str | torch.device = "cpu"
) -> tuple[nn.Module, dict[str, Any], dict[str, np.ndarray]]:
    """Rebuild a model from a checkpoint folder alone.

    Returns
    -------
    model : the model with its weights, in ``eval()`` mode, on ``device``
    meta : the whole ``config.json`` (``meta["config"]`` is the model configuration)
    stats : the arrays of ``stats.npz`` (empty dict when none were saved)

    Raises
    ------
    CheckpointError
        When the folder or one of its files is missing or corrupt, or does not match the code.
    """
    folder = Path(folder)
    meta = read_config(folder)
    model = build_model(meta["model"], meta["config"], folder=folder)
    state = read_weights(folder)
    try:
        model.load_state_dict(state)
    except RuntimeError as exc:
        raise CheckpointError(f"weights in {folder / WEIGHTS_FILE} do not match the configuration: {exc}") from exc
    return model.to(device).eval(), meta, read_stats(folder)


def read_weights(folder: str | os.PathLike) -> dict[str, torch.Tensor]:
    """The tensors of a checkpoint folder's ``model.safetensors`` (a missing or corrupt file is a
    :class:`~dancekit.errors.CheckpointError` naming it)."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    weights = Path(folder) / WEIGHTS_FILE
    if not weights.is_file():
        raise CheckpointError(f"not a checkpoint: {weights} is missing")
    try:
        return load_file(str(weights))
    except (SafetensorError, OSError, ValueError) as exc:
        raise CheckpointError(f"corrupt weights file {weights}: {exc}") from exc


def read_stats(folder: str | os.PathLike) -> dict[str, np.ndarray]:
    """The arrays of a checkpoint folder's ``stats.npz`` (a missing or corrupt file is a
    :class:`~dancekit.errors.CheckpointError` naming it)."""
    stats_path = Path(folder) / STATS_FILE
    if not stats_path.is_file():
        raise CheckpointError(f"not a checkpoint: {stats_path} is missing")
    try:
        with np.load(stats_path, allow_pickle=False) as z:
            return {k: np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"corrupt statistics file {stats_path}: {exc}") from exc
