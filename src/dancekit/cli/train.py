"""``dancekit train FAMILY --data DIR --out RUN [--set key=value ...] [--resume]``: train a model.

``--set`` takes any field of the family's model configuration (e.g. ``d_model=256``,
``encoder=global``) or of :class:`~dancekit.training.TrainConfig` (e.g. ``steps=3000``,
``batch_size=32``, ``curriculum=quadratic``); prefix ``model.`` or ``train.`` to be explicit.
With ``--resume`` the configurations are read back from the newest checkpoint in RUN and the
``--set`` values applied on top (e.g. ``--set steps=5000`` to train longer).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
import types
import typing
from pathlib import Path
from typing import Any

from dancekit.errors import ParameterError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train",
        help="train a model family on a prepared dataset",
        description="Train a model on a dataset written by `dancekit prepare`, with checkpoints in OUT "
        "(OUT/model is the latest model, OUT/best the best on the validation split).",
    )
    from dancekit import registry

    p.add_argument("family", choices=registry.families(), help="model family (dancekit.registry)")
    p.add_argument("--data", required=True, help="prepared dataset folder (from `dancekit prepare`)")
    p.add_argument("--out", required=True, help="run folder: checkpoints, log.jsonl, model/, best/")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a model or training setting (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in --out")
    p.add_argument("--init", default=None, metavar="CHECKPOINT",
                   help="start from the weights (and model configuration) of a checkpoint folder: fine-tuning")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


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


def parse_sets(sets: list[str], model_cls: type, train_cls: type) -> tuple[dict[str, Any], dict[str, Any]]:
    """``["key=value", ...]`` → (model overrides, train overrides), typed by the dataclass fields.

    Raises
    ------
    ParameterError
        For a malformed item, an unknown or ambiguous key (named), or a value of the wrong type.
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


def run(args: argparse.Namespace) -> int:
    from dancekit import registry
    from dancekit.checkpoints import load_pretrained, read_config
    from dancekit.data import PreparedData, compute_stats
    from dancekit.errors import CheckpointError
    from dancekit.training import TrainConfig, checkpoints, train
    from dancekit.training.loop import seed_everything

    family = registry.get(args.family)
    config_cls, model_cls = family.config_class, family.module_class
    model_sets, train_sets = parse_sets(args.sets, config_cls, TrainConfig)
    out = Path(args.out)

    model_base: dict[str, Any] = {}
    train_base: dict[str, Any] = {}
    found = checkpoints(out) if args.resume else []
    if found:
        saved = read_config(found[-1])
        if saved["model"] != args.family:
            raise ParameterError(f"{found[-1]} holds a {saved['model']!r} model, not {args.family!r}")
        model_base, train_base = dict(saved["config"]), dict(saved.get("train", {}))
        unknown = sorted(set(train_base) - {f.name for f in dataclasses.fields(TrainConfig)})
        if unknown:
            raise CheckpointError(f"{found[-1]}: training settings {unknown} are unknown to this version")
    init_state = None
    if args.init and not found:
        init_model, init_meta, _ = load_pretrained(args.init)
        if init_meta["model"] != args.family:
            raise ParameterError(f"--init {args.init} holds a {init_meta['model']!r} model, not {args.family!r}")
        model_base = dict(init_meta["config"])
        init_state = init_model.state_dict()
    tc = TrainConfig(**{**family.train_defaults, **train_base, **train_sets})

    data = PreparedData(args.data)
    preset = family.preset
    t0 = time.perf_counter()
    stats = compute_stats(data, preset=preset, representation=tc.representation) if preset is not None else None
    train_set, val_set = family.load("dataset")(data, tc, stats, preset=preset)
    stats = getattr(train_set, "stats", stats)  # a family that reads no music has its own input statistics
    if len(train_set) == 0:
        raise ParameterError(f"no training window of {tc.seq_len} frames fits in the dances of {args.data}")

    # model fields the data decides (registry: data_fields): class count, window length, and the dataset's
    # own sizes (music_dim, pose_dim, ...); a classifier of fixed windows classifies windows as long as it
    # was trained on
    dims = {f: len(data.genres) if f == "n_classes" else tc.seq_len if f == "window" else getattr(train_set, f)
            for f in family.data_fields}
    for key, value in dims.items():
        if key in model_sets and model_sets[key] != value:
            what = f"seq_len ({value})" if key == "window" else f"the data ({key} = {value})"
            raise ParameterError(f"--set {key}={model_sets[key]} does not match {what}")
    model_config = config_cls(**{**model_base, **model_sets, **dims})
    seed_everything(tc.seed)  # the initial weights depend on the seed only
    model = model_cls(model_config)
    if init_state is not None:
        missing, unexpected = model.load_state_dict(init_state, strict=False)
        new = [k for k in missing if not k.startswith("genre_embedding.")]
        if new or unexpected:
            raise CheckpointError(f"--init {args.init} does not fit this configuration: missing {new}, "
                                  f"unexpected {list(unexpected)}")
    meta = {
        "representation": tc.representation,
        "preset": preset,
        "fps": data.fps,
        "hop_length": int(data.meta.get("hop_length", 512)),
        "skeleton": data.meta["skeleton"],
        "genres": list(data.genres),
        "data": {"root": str(Path(args.data).resolve()), "train": data.names("train"), "val": data.names("val")},
        "init": str(Path(args.init).resolve()) if init_state is not None else None,
    }
    n_params = sum(p.numel() for p in model.parameters() if p.requires_grad)
    if not args.quiet:
        print(f"{args.family}: {n_params / 1e6:.2f} M parameters; {len(train_set)} training windows of "
              f"{tc.seq_len} frames, {len(val_set)} validation windows; data loaded in {time.perf_counter() - t0:.1f} s")
        print("model:", json.dumps(dataclasses.asdict(model_config)))
        print("train:", json.dumps(dataclasses.asdict(tc)))
    result = train(model, train_set, val_set if len(val_set) else None, tc, step_fn=family.load("objective"),
                   out_dir=out, resume=args.resume, stats=stats, meta=meta, progress=not args.quiet)
    val = f", val loss {result.val_loss:.4f} (best {result.best_val_loss:.4f})" if result.val_loss is not None else ""
    loss = f"{result.train_loss:.4f}" if result.train_loss is not None else "n/a"
    print(f"trained {args.family} to step {result.step} (epoch {result.epoch}): train loss {loss}{val} "
          f"in {time.perf_counter() - t0:.0f} s → {out / 'model'}")
    return 0
