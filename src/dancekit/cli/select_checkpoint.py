"""``dancekit select-checkpoint --run RUN --data DIR``: pick a run's checkpoint on the validation songs.

Scores every checkpoint of the run (``RUN/checkpoints/step_*`` and ``RUN/best``) by what its dances look
like on the validation split (style accuracy, stillness, optionally genre steering), writes
``RUN/selection.json`` and, with ``--install DIR``, copies the chosen checkpoint's model files there.
See :mod:`dancekit.evaluation.selection`.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from dancekit.cli._options import seed_run

MODEL_FILES = ("config.json", "model.safetensors", "stats.npz")


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "select-checkpoint",
        help="pick a training run's checkpoint by its dances on the validation songs",
        description="Score every checkpoint of a run on the validation split (balanced style accuracy, "
        "stillness, optionally genre steering) and choose one; never select on the test split.",
    )
    p.add_argument("--run", required=True, help="training run folder (with checkpoints/ and log.jsonl)")
    p.add_argument("--data", required=True, metavar="PREPARED_DIR", help="prepared dataset folder")
    p.add_argument("--split", default="val", help="split to score on (default val; never select on test)")
    p.add_argument("--seeds", default=None, metavar="LIST", help="the seeds danced for every song: 0-N (default 0-1)")
    p.add_argument("--steer", action="store_true", help="also score genre steering")
    p.add_argument("--max-stillness", type=float, default=0.05, help="largest admissible stillness share")
    p.add_argument("--min-step", type=int, default=0, help="skip step checkpoints before this step")
    p.add_argument("-o", "--out", "--output", "--install", dest="install", metavar="DIR",
                   help="copy the chosen checkpoint's model files to this folder (--install: the old spelling)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from dancekit._io import atomic_dir
    from dancekit.data import PreparedData
    from dancekit.evaluation import select_checkpoint

    _, seeds = seed_run(args.seeds, verb="select-checkpoint", default=2, from_zero=True)
    report = select_checkpoint(args.run, PreparedData(args.data), split=args.split, seeds=seeds,
                               steer=args.steer, max_stillness=args.max_stillness, min_step=args.min_step,
                               progress=not args.quiet)
    chosen = report["chosen"]
    print(f"chosen: {chosen['checkpoint']} (step {chosen['step']}): " + json.dumps(
        {k: chosen[k] for k in ("style", "dance_accuracy", "stillness_max", "steer", "val_loss") if k in chosen}))
    if args.install:
        with atomic_dir(args.install) as tmp:
            for f in MODEL_FILES:
                shutil.copy2(Path(chosen["checkpoint"]) / f, Path(tmp) / f)
        print(f"installed to {args.install}")
    return 0
