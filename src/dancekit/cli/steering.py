"""``dancekit steering --checkpoint MODEL --data DIR``: does ``--genre`` steer?

Dances every song of a split as every genre the model offers (seed 0, or ``--seeds``) and reads the genre
back with the style classifier; prints the read-back share and the confusion counts and writes the
report (``-o``). See :mod:`dancekit.evaluation.steering`.
"""

from __future__ import annotations

import argparse
import json
import time

from dancekit.cli._options import seed_run


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "steering",
        help="dance every song as every genre of a model and read the genre back",
        description="Measure whether --genre steers: every song of the split danced as every genre the model "
        "offers, each dance classified by the style classifier.",
    )
    p.add_argument("--checkpoint", required=True, metavar="MODEL", help="checkpoint folder or model name")
    p.add_argument("--data", required=True, metavar="PREPARED_DIR", help="prepared dataset folder")
    p.add_argument("--split", default="test")
    p.add_argument("--seeds", default=None, metavar="LIST",
                   help="the seeds danced for every song and genre: 0-N (default 0)")
    p.add_argument("--classifier", metavar="DIR", default=None,
                   help="style classifier checkpoint (default: the one shipped with dancekit)")
    p.add_argument("-o", "--output", metavar="JSON", help="write the report here")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from dancekit._io import atomic_path
    from dancekit.data import PreparedData
    from dancekit.errors import CheckpointError
    from dancekit.evaluation import load_classifier, steering
    from dancekit.pipelines import load_pipeline

    _, seeds = seed_run(args.seeds, verb="steering", default=1, from_zero=True)
    pipe = load_pipeline(args.checkpoint)
    style, note = load_classifier(args.classifier or "default")
    if style is None:
        raise CheckpointError(note or "no style classifier")
    t0 = time.perf_counter()
    report = steering(pipe, PreparedData(args.data), style, split=args.split, seeds=seeds,
                      progress=not args.quiet)
    report["checkpoint"] = str(args.checkpoint)
    report["elapsed_s"] = round(time.perf_counter() - t0, 1)
    if args.output:
        with atomic_path(args.output) as tmp:
            tmp.write_text(json.dumps(report, indent=1) + "\n")
    print(f"read back {report['read_back']:.3f} of {report['n']} dances; per genre "
          + ", ".join(f"{g} {v:.2f}" for g, v in report["read_back_per_genre"].items()))
    for g, row in report["matrix"].items():
        print(f"  asked {g:7s} → " + ", ".join(f"{r} {c}" for r, c in row.items() if c)
              + f"   (stillness max {report['stillness_max'][g]:.3f}, energy {report['smoothed_energy'][g]:.3f} m/s)")
    return 0
