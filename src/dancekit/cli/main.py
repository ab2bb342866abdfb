"""``dancekit`` entry point: one sub-command per verb.

Each verb lives in its own module ``dancekit.cli.<verb>`` exposing
``add_parser(subparsers)`` (which registers the sub-command and sets
``func``). Known errors (:class:`~dancekit.errors.DancekitError`) are printed
as one line on stderr with exit code 2; a traceback is shown only when
``DANCEKIT_DEBUG=1``. SIGTERM and SIGHUP stop a verb like Ctrl-C does: the cleanup of
staging folders and temporary files runs, then the exit code is 128 + the signal number.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
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
    "live": "dancekit.cli.live",
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
    _alias_output_flags(parser)
    return parser


#: The output flag's two spellings: every verb that has one accepts both (documented: ``-o/--output``).
OUTPUT_FLAGS = ("--output", "--out")


def _alias_output_flags(parser: argparse.ArgumentParser) -> None:
    """Give every (sub-)command's output option both spellings of :data:`OUTPUT_FLAGS`, so that
    ``dance --output`` and ``render --out`` work like ``dance --out`` and ``render --output``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):  # aliases map to the same parser
                _alias_output_flags(child)
            continue
        have = [f for f in OUTPUT_FLAGS if f in action.option_strings]
        if not have:
            continue
        for flag in OUTPUT_FLAGS:
            if flag not in action.option_strings and flag not in parser._option_string_actions:
                action.option_strings.append(flag)
                parser._option_string_actions[flag] = action


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: raised in the main thread so that every ``finally`` / ``except
    BaseException`` cleanup runs (staging folders, temporary files) before the process exits."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated(signum)


def _handle_signals() -> dict[int, object]:
    """Turn SIGTERM and SIGHUP (where they have their default action) into :class:`Terminated`; returns the
    handlers replaced, for :func:`main` to put back."""
    import threading

    replaced: dict[int, object] = {}
    if threading.current_thread() is not threading.main_thread():
        return replaced
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) in (signal.SIG_DFL, None):
            replaced[sig] = signal.signal(sig, _raise_terminated)
    return replaced


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    replaced = _handle_signals()
    try:
        result = args.func(args)
    except DancekitError as exc:
        if os.environ.get("DANCEKIT_DEBUG") == "1":
            raise
        print(f"dancekit {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"dancekit {args.verb}: stopped by SIGINT; nothing partial was left", file=sys.stderr)
        return 128 + signal.SIGINT
    except Terminated as exc:
        print(f"dancekit {args.verb}: stopped by {signal.Signals(exc.signum).name}; nothing partial was left",
              file=sys.stderr)
        return 128 + exc.signum
    finally:
        for sig, handler in replaced.items():
            signal.signal(sig, handler)
    return int(result or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
