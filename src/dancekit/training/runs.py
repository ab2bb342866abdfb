"""Assembling a training run of a registered family from a prepared dataset (what ``dancekit train`` does).

:func:`assemble_run` reads the family's entry in :mod:`dancekit.registry`, merges the settings (family
defaults < a resumed checkpoint's < ``--set`` overrides, :func:`parse_sets`), builds the datasets and the
normalisation statistics, fills the model fields the data decides (``data_fields``), builds the model
(seeded; optionally from the weights of an ``init`` checkpoint) and the metadata every checkpoint
carries. The :class:`TrainRun` it returns trains with :meth:`TrainRun.fit`.

Examples
--------
>>> run = assemble_run("revolution", "data/tang2018", "runs/rev", sets=["steps=3000"])  # doctest: +SKIP
>>> print("\\n".join(run.summary_lines()))  # doctest: +SKIP
>>> result = run.fit()  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
import types
import typing
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from torch import nn
from torch.utils.data import Dataset

from dancekit import registry
from dancekit.errors import CheckpointError, ParameterError
from dancekit.training.config import TrainConfig
from dancekit.training.loop import TrainResult, checkpoints, seed_everything, train

# ---- --set key=value ---------------------------------------------------------------------------------


def _parse_value(text: str, annotation: Any, key: str) -> Any:
    """Convert ``text`` to the type ``annotation`` of field ``key`` (int, float, bool, str, list[str] and tuple[int, ...] as
    comma-separated items, X | None)."""
    origin = typing.get_origin(annotation)
    if origin in (list, tuple):
        items = [t.strip() for t in text.split(",") if t.strip()]
        if not items:
            raise ParameterError(f"--set {key}={text}: expected one or more comma-separated values")
        values = [_parse_value(t, typing.get_args(annotation)[0], key) for t in items]
        return tuple(values) if origin is tuple else values
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(annotation)
        if type(None) in args and text.strip().lower() in ("none", "null"):
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _parse_value(text, arg, key)
            except ParameterError as exc:
                errors.append(str(exc))
        raise ParameterError(errors[0] if errors else f"bad value for {key}: {text!r}")
    if annotation is bool:
        low = text.strip().lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise ParameterError(f"--set {key}={text}: expected true or false")
    if annotation in (int, float):
        try:
            return annotation(text)
        except ValueError:
            raise ParameterError(f"--set {key}={text}: expected {annotation.__name__}") from None
    return text


def parse_sets(sets: Sequence[str], model_cls: type, train_cls: type = TrainConfig) -> tuple[dict[str, Any], dict[str, Any]]:
    """``["key=value", ...]`` → (model overrides, train overrides), typed by the dataclass fields.

    A key names a field of ``model_cls`` or of ``train_cls`` (every field of :class:`TrainConfig`, generic or
    per family); ``model.KEY`` / ``train.KEY`` say which when both have it.

    Raises
    ------
    ParameterError
        For a malformed item, an unknown or ambiguous key (named), or a value of the wrong type.

    Examples
    --------
    >>> from dancekit.models.revolution import RevolutionConfig
    >>> parse_sets(["d_model=64", "lr=3e-4", "genres=rumba,tango"], RevolutionConfig)
    ({'d_model': 64}, {'lr': 0.0003, 'genres': ['rumba', 'tango']})
    """
    hints = {"model": typing.get_type_hints(model_cls), "train": typing.get_type_hints(train_cls)}
    fields = {"model": {f.name for f in dataclasses.fields(model_cls)},
              "train": {f.name for f in dataclasses.fields(train_cls)}}
    out: dict[str, dict[str, Any]] = {"model": {}, "train": {}}
    for item in sets:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ParameterError(f"--set expects KEY=VALUE, got {item!r}")
        scope, _, name = key.rpartition(".")
        if scope:
            if scope not in fields or name not in fields[scope]:
                raise ParameterError(f"unknown setting {key!r}")
            scopes = [scope]
        else:
            scopes = [s for s in ("model", "train") if name in fields[s]]
            if not scopes:
                known = ", ".join(sorted(fields["model"] | fields["train"]))
                raise ParameterError(f"unknown setting {name!r} (known: {known})")
            if len(scopes) > 1:
                raise ParameterError(f"setting {name!r} is ambiguous: write model.{name} or train.{name}")
        out[scopes[0]][name] = _parse_value(value, hints[scopes[0]][name], name)
    return out["model"], out["train"]


# ---- a run ----------------------------------------------------------------------------------------------


@dataclass
class TrainRun:
    """Everything a training run needs, assembled by :func:`assemble_run`; :meth:`fit` trains it."""

    family: registry.Family
    model: nn.Module
    config: TrainConfig
    train_set: Dataset
    val_set: Dataset
    stats: Any  # NormStats of the training split
    meta: dict[str, Any]  # the extra entries of every checkpoint's config.json
    out_dir: Path
    resume: bool  # continue from the newest checkpoint of out_dir (found: `resumed_from`)
    resumed_from: Path | None = None
    load_seconds: float = 0.0  # statistics and datasets

    @property
    def n_parameters(self) -> int:
        return sum(p.numel() for p in self.model.parameters() if p.requires_grad)

    def summary_lines(self) -> list[str]:
        """What ``dancekit train`` prints before training: sizes, then the model and training settings (JSON)."""
        return [
            f"{self.family.name}: {self.n_parameters / 1e6:.2f} M parameters; {len(self.train_set)} training windows "
            f"of {self.config.seq_len} frames, {len(self.val_set)} validation windows; data loaded in "
            f"{self.load_seconds:.1f} s",
            "model: " + json.dumps(dataclasses.asdict(self.model.config)),
            "train: " + json.dumps(dataclasses.asdict(self.config)),
        ]

    def fit(self, *, progress: bool = True, callbacks: Iterable[Callable[[dict[str, Any]], None]] = ()) -> TrainResult:
        """Train (:func:`dancekit.training.train`), resuming when the run was assembled with ``resume=True``."""
        return train(self.model, self.train_set, self.val_set if len(self.val_set) else None, self.config,
                     step_fn=self.family.load("objective"), out_dir=self.out_dir, resume=self.resume,
                     stats=self.stats, meta=self.meta, progress=progress, callbacks=callbacks)


def _saved_settings(family: str, out_dir: Path) -> tuple[Path | None, dict[str, Any], dict[str, Any]]:
    """(checkpoint, model settings, training settings) of the newest checkpoint in ``out_dir`` (None, {}, {})."""
    from dancekit.checkpoints import read_config

    found = checkpoints(out_dir)
    if not found:
        return None, {}, {}
    saved = read_config(found[-1])
    if saved["model"] != family:
        raise ParameterError(f"{found[-1]} holds a {saved['model']!r} model, not {family!r}")
    return found[-1], dict(saved["config"]), dict(saved.get("train", {}))


def _init_weights(family: str, init: str | os.PathLike) -> tuple[dict[str, Any], dict[str, Any]]:
    """(model settings, state dict) of the checkpoint ``init`` (fine-tuning)."""
    from dancekit.checkpoints import load_pretrained

    model, meta, _ = load_pretrained(init)
    if meta["model"] != family:
        raise ParameterError(f"--init {init} holds a {meta['model']!r} model, not {family!r}")
    return dict(meta["config"]), model.state_dict()


def _data_fields(family: registry.Family, data: Any, config: TrainConfig, train_set: Any) -> dict[str, Any]:
    """Model fields the data decides (registry: ``data_fields``): the class count, the window length, and
    the dataset's own sizes (``music_dim``, ``pose_dim``, ...); a classifier of fixed windows classifies
    windows as long as it was trained on."""
    return {f: len(data.genres) if f == "n_classes" else config.seq_len if f == "window" else getattr(train_set, f)
            for f in family.data_fields}


def assemble_run(
    family: str,
    data_dir: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    sets: Sequence[str] = (),
    resume: bool = False,
    init: str | os.PathLike | None = None,
) -> TrainRun:
    """A training run of ``family`` on the prepared dataset ``data_dir``, writing to ``out_dir``.

    Parameters
    ----------
    family : a name of :func:`dancekit.registry.families`
    data_dir : a folder written by ``dancekit prepare``
    out_dir : the run folder (checkpoints, ``log.jsonl``, ``model/``, ``best/``)
    sets : ``"key=value"`` overrides of the model configuration or of :class:`TrainConfig` (:func:`parse_sets`)
    resume : continue from the newest checkpoint in ``out_dir``: its model and training settings are the
        base, ``sets`` apply on top (e.g. ``steps=5000`` to train longer); without a checkpoint, start afresh
    init : a checkpoint folder whose weights and model configuration the model starts from (fine-tuning;
        ignored when resuming from a checkpoint). A genre embedding it lacks starts fresh.

    Returns
    -------
    :class:`TrainRun`

    Raises
    ------
    ParameterError
        For an unknown family or setting, a bad value, a setting that contradicts the data, a checkpoint of
        another family, or data in which no training window fits.
    CheckpointError
        For a checkpoint with unknown training settings, or an ``init`` checkpoint whose weights do not fit.
    DatasetError
        For a folder that is not a prepared dataset.
    """
    from dancekit.data import PreparedData, compute_stats

    fam = registry.get(family)
    config_cls, model_cls = fam.config_class, fam.module_class
    model_sets, train_sets = parse_sets(sets, config_cls, TrainConfig)
    out_dir = Path(out_dir)

    found, model_base, train_base = _saved_settings(fam.name, out_dir) if resume else (None, {}, {})
    init_state = None
    if init and found is None:
        model_base, init_state = _init_weights(fam.name, init)
    config = TrainConfig.from_saved(train_base, source=found, defaults=fam.train_defaults, **train_sets)

    data = PreparedData(data_dir)
    t0 = time.perf_counter()
    stats = (compute_stats(data, preset=fam.preset, representation=config.representation)
             if fam.preset is not None else None)
    train_set, val_set = fam.load("dataset")(data, config, stats, preset=fam.preset)
    stats = getattr(train_set, "stats", stats)  # a family that reads no music has its own input statistics
    if len(train_set) == 0:
        raise ParameterError(f"no training window of {config.seq_len} frames fits in the dances of {data_dir}")
    load_seconds = time.perf_counter() - t0

    dims = _data_fields(fam, data, config, train_set)
    for key, value in dims.items():
        if key in model_sets and model_sets[key] != value:
            what = f"seq_len ({value})" if key == "window" else f"the data ({key} = {value})"
            raise ParameterError(f"--set {key}={model_sets[key]} does not match {what}")
    model_config = config_cls(**{**model_base, **model_sets, **dims})
    seed_everything(config.seed)  # the initial weights depend on the seed only
    model = model_cls(model_config)
    if init_state is not None:
        missing, unexpected = model.load_state_dict(init_state, strict=False)
        new = [k for k in missing if not k.startswith(("genre_embedding.", "style_"))]  # new modules, zero-initialised where they enter
        if new or unexpected:
            raise CheckpointError(f"--init {init} does not fit this configuration: missing {new}, "
                                  f"unexpected {list(unexpected)}")
    meta = {
        "representation": config.representation,
        "preset": fam.preset,
        "fps": data.fps,
        "hop_length": int(data.meta.get("hop_length", 512)),
        "skeleton": data.meta["skeleton"],
        "genres": list(data.genres),
        "data": {"root": str(Path(data_dir).resolve()), "train": data.names("train"), "val": data.names("val")},
        "init": str(Path(init).resolve()) if init_state is not None else None,
    }
    if fam.kind == "dance" and data.skeleton.dims == 3:  # the real dances' per-genre tables the stages compare with
        stats_tables = _genre_stats(data)
        if stats_tables:
            meta["genre_stats"] = stats_tables
    return TrainRun(family=fam, model=model, config=config, train_set=train_set, val_set=val_set, stats=stats,
                    meta=meta, out_dir=out_dir, resume=resume, resumed_from=found, load_seconds=load_seconds)


def _genre_stats(data) -> dict[str, dict[str, float]]:
    """The ``"genre_stats"`` tables of a dance checkpoint (:mod:`dancekit.training.genre_stats`) from the training
    split, keeping the values a checkpoint may hold (finite and positive; a planted share of at most 1): a skeleton
    without legs has no planted share, a still test dance no jitter."""
    import numpy as np

    from dancekit.training.genre_stats import prepared_genre_stats

    tables = prepared_genre_stats(data, "train")
    top = {"planted_share": 1.0}
    out = {}
    for name, table in tables.items():
        kept = {g: v for g, v in table.items() if np.isfinite(v) and 0 < v <= top.get(name, np.inf)
                and (name != "smoothing" or v < 10)}
        if kept:
            out[name] = kept
    return out
