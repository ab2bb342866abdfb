"""``dancekit baselines --data DIR -o OUT``: what do trivial "models" score? (calibration of ``evaluate``)

Writes ``OUT/<baseline>/NAME.npz`` for every test dance (ground truth, a frozen mean pose, a random
training dance drawn ``--draws`` times, the training dance with the nearest music), scores each folder as ``dancekit evaluate``
would (``OUT/<baseline>.json``) and prints the combined table (``OUT/table.md``). See
:mod:`dancekit.evaluation.baselines` and docs/BENCHMARKS.md.
"""

from __future__ import annotations

import argparse


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "baselines",
        help="score trivial baselines (ground truth, frozen pose, random / nearest-music training dance)",
        description="Write four baseline dances for every test song of a prepared dataset and score them as "
        "`dancekit evaluate` would; the random training dance is drawn --draws times and scored per draw. Prints "
        "the table of all four, the random draws as each metric's median, min and max (OUT/table.md).",
    )
    p.add_argument("--data", required=True, metavar="PREPARED_DIR", help="prepared dataset folder")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of the random training dances and of Diversity")
    p.add_argument("--draws", type=int, default=10, help="random training dances drawn per test dance; the table "
                   "shows each metric's median, min and max over the draws (default 10)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from dancekit.evaluation import run_baselines

    _, table = run_baselines(args.data, args.output, seed=args.seed, draws=args.draws)
    print(table, end="")
    return 0
