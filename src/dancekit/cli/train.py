"""``dancekit train FAMILY --data DIR -o RUN [--set key=value ...] [--resume]``: train a model.

``--set`` takes any field of the family's model configuration (e.g. ``d_model=256``,
``encoder=global``) or of :class:`~dancekit.training.TrainConfig` (e.g. ``steps=3000``,
``batch_size=32``, ``curriculum=quadratic``); prefix ``model.`` or ``train.`` to be explicit.
Under ``torchrun --nproc_per_node=N`` the same command trains with distributed data parallelism
(:mod:`dancekit.training.distributed`); rank 0 alone prints and writes.
With ``--resume`` the configurations are read back from the newest checkpoint in RUN and the
``--set`` values applied on top (e.g. ``--set steps=5000`` to train longer).

The run is assembled by :func:`dancekit.training.assemble_run` and trained by :meth:`~dancekit.training.TrainRun.fit`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any


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
    p.add_argument("-o", "--out", "--output", dest="out", required=True, metavar="RUN",
                   help="run folder: checkpoints, log.jsonl, model/, best/")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a model or training setting (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in --out")
    p.add_argument("--init", default=None, metavar="CHECKPOINT",
                   help="start from the weights (and model configuration) of a checkpoint folder: fine-tuning")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    plain = p.format_help
    p.format_help = lambda: plain() + "\n" + set_keys_help()  # computed on `train --help` only (imports torch)


def set_keys_help() -> str:
    """The ``--set`` keys: every field of TrainConfig and of each family's model configuration, with defaults."""
    import dataclasses
    import textwrap

    from dancekit import registry
    from dancekit.training.config import TrainConfig

    def fields(cls) -> str:
        items = [f"{f.name}={f.default!r}" if f.default is not dataclasses.MISSING else f.name
                 for f in dataclasses.fields(cls) if f.init]
        return textwrap.fill(", ".join(items), width=100, initial_indent="    ", subsequent_indent="    ")

    out = ["--set keys (KEY=VALUE; defaults shown; prefix train. or model. to be explicit):", "  training:",
           fields(TrainConfig)]
    for family in registry.families():
        out += [f"  model ({family}):", fields(registry.get(family).config_class)]
    return "\n".join(out) + "\n"


def __getattr__(name: str) -> Any:
    # `parse_sets` lives in dancekit.training.runs; imported on use so that `dancekit --help` loads no torch
    if name == "parse_sets":
        from dancekit.training.runs import parse_sets

        return parse_sets
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def run(args: argparse.Namespace) -> int:
    from dancekit.training.distributed import is_main_process
    from dancekit.training.runs import assemble_run

    t0 = time.perf_counter()
    train_run = assemble_run(args.family, args.data, args.out, sets=args.sets, resume=args.resume, init=args.init)
    main = is_main_process()  # under torchrun: rank 0 alone prints
    if not args.quiet and main:
        print("\n".join(train_run.summary_lines()))
    result = train_run.fit(progress=not args.quiet)
    if not main:
        return 0
    val = f", val loss {result.val_loss:.4f} (best {result.best_val_loss:.4f})" if result.val_loss is not None else ""
    loss = f"{result.train_loss:.4f}" if result.train_loss is not None else "n/a"
    print(f"trained {args.family} to step {result.step} (epoch {result.epoch}): train loss {loss}{val} "
          f"in {time.perf_counter() - t0:.0f} s → {Path(args.out) / 'model'}")
    return 0
