"""``dancekit`` entry point: one sub-command per verb.

Each verb lives in its own module ``dancekit.cli.<verb>`` exposing
``add_parser(subparsers)`` (which registers the sub-command and sets
``func``). Known errors (:class:`~dancekit.errors.DancekitError`) are printed
as one line on stderr with exit code 2; a traceback is shown only when
``DANCEKIT_DEBUG=1``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from dancekit import __version__
from dancekit.errors import DancekitError

# verb → module; modules are imported lazily so `dancekit --help` stays fast.
VERBS: dict[str, str] = {
    "features": "dancekit.cli.features",
    "info": "dancekit.cli.info",
    "prepare": "dancekit.cli.prepare",
    "train": "dancekit.cli.train",
    "evaluate": "dancekit.cli.evaluate",
    "baselines": "dancekit.cli.baselines",
    "compare": "dancekit.cli.compare",
    "select-checkpoint": "dancekit.cli.select_checkpoint",
    "steering": "dancekit.cli.steering",
    "score-classifier": "dancekit.cli.score_classifier",
    "dance": "dancekit.cli.dance",
    "render": "dancekit.cli.render",
    "models": "dancekit.cli.models",
    "convert": "dancekit.cli.convert",
    "compose": "dancekit.cli.compose",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dancekit",
        description="Turn music into dance and dance into music.",
    )
    parser.add_argument("--version", action="version", version=f"dancekit {__version__}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    for module_name in VERBS.values():  # a verb whose module is missing is a bug: no silent skipping
        importlib.import_module(module_name).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        result = args.func(args)
    except DancekitError as exc:
        if os.environ.get("DANCEKIT_DEBUG") == "1":
            raise
        print(f"dancekit {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"dancekit {args.verb}: interrupted", file=sys.stderr)
        return 130
    return int(result or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
