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
from typing import NoReturn

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
    "serve": "dancekit.cli.serve",
    "live": "dancekit.cli.live",
}


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every other dancekit error: ``dancekit VERB: error:
    MESSAGE (see dancekit VERB --help)``, exit status 2 (argparse's own error prints the whole usage first).
    Sub-commands are made of the same class (``add_subparsers`` uses the parent's class)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(verbs: list[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser: every verb's (None), or only those of ``verbs`` (what :func:`main` builds for a
    command line that starts with a verb: the other verbs' modules are not imported)."""
    parser = OneLineParser(
        prog="dancekit",
        description="Turn music into dance and dance into music.",
    )
    parser.add_argument("--version", action="version", version=f"dancekit {__version__}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    for verb, module_name in VERBS.items():  # a verb whose module is missing is a bug: no silent skipping
        if verbs is None or verb in verbs:
            importlib.import_module(module_name).add_parser(sub)
    _alias_output_flags(parser)
    return parser


#: The names under which verbs store their output path (``-o``).
_OUTPUT_DESTS = ("out", "output", "install")

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


class QuietProgress:
    """``sys.stderr`` for a run whose stderr is not a terminal (a pipe, a log file): progress bars redraw their
    line with carriage returns many times a second, which a log keeps as one long line per update. Here a
    redraw becomes one plain line at most every :attr:`interval` seconds (the first one at once); everything
    else (warnings, error lines) passes through unchanged."""

    interval = 10.0

    def __init__(self, stream):
        self._stream = stream
        self._last = float("-inf")
        self._in_bar = False

    def write(self, text: str) -> int:
        import time

        if "\r" in text or (self._in_bar and not text.strip()):
            self._in_bar = True
            line = text.replace("\r", "").strip()
            now = time.monotonic()
            if line and now - self._last >= self.interval:
                self._stream.write(line + "\n")
                self._stream.flush()
                self._last = now
            return len(text)
        self._in_bar = False
        return self._stream.write(text)

    def __getattr__(self, name: str):  # flush, fileno, isatty, encoding, ...: the real stream's
        return getattr(self._stream, name)


def main(argv: list[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser([words[0]] if words and words[0] in VERBS else None)
    args = parser.parse_args(words)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    replaced = _handle_signals()
    stderr = sys.stderr
    if not _isatty(stderr):
        sys.stderr = QuietProgress(stderr)
    try:
        for dest in _OUTPUT_DESTS:  # an empty -o would write into the current folder
            if isinstance(getattr(args, dest, None), str):
                from dancekit.cli._options import check_output

                check_output(getattr(args, dest))
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
        sys.stderr = stderr
        for sig, handler in replaced.items():
            signal.signal(sig, handler)
    return int(result or 0)


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # a closed or file-less stream
        return False


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
