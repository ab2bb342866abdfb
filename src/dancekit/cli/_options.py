"""Flags shared by several verbs, with one meaning everywhere.

- ``-o/--out/--output``: where a verb writes (a file or a folder; never empty).
- ``--seeds LIST``: a list of seeds, ``0-7`` (a range, both ends included), ``0,3,9`` or both (``0-3,10``);
  ``--seed N``: one seed. Parsed in the verb's ``run`` (not by argparse), so a bad value is one error line.
- ``--fps F``: the frame rate of what a verb writes, in ``(0, MAX_OUTPUT_FPS]``.
"""

from __future__ import annotations

import argparse
import sys

from dancekit.errors import ParameterError

#: Highest output frame rate (frames per second): motion capture's fastest common rate; above it a dance is
#: only more frames of the same motion.
MAX_OUTPUT_FPS = 240.0

SEEDS_HELP = "0-7 (a range, ends included), 0,3,9, or both (0-3,10)"


def add_output(p: argparse.ArgumentParser, *, help: str, required: bool = True, metavar: str | None = None,
               dest: str = "out") -> argparse.Action:
    """``-o/--out/--output`` (every spelling) on ``p``."""
    return p.add_argument("-o", "--out", "--output", dest=dest, required=required, metavar=metavar or "OUT",
                          help=help)


def check_output(value: str | None, *, flag: str = "-o") -> str | None:
    """``value`` unless it is empty or blank (which would write into the current folder)."""
    if value is not None and not str(value).strip():
        raise ParameterError(f"{flag} must name a file or folder, got {value!r}")
    return value


def seed_list(text: str | None, *, flag: str = "--seeds") -> list[int] | None:
    """The seeds of a ``--seeds LIST`` value (see the module docstring), or None when not given."""
    if text is None:
        return None
    from dancekit.pipelines.base import parse_seeds

    try:
        return parse_seeds(text)
    except ParameterError as exc:
        raise ParameterError(f"{flag} {text}: {exc}") from None


def one_seed(text: str | int | None, *, flag: str = "--seed") -> int | None:
    """An integer ``--seed`` (any integer; seeds outside ``[0, 2**63)`` are hashed to 63 bits)."""
    if text is None:
        return None
    from dancekit._checks import reduce_seed

    try:
        return reduce_seed(int(text))
    except ValueError:
        raise ParameterError(f"{flag} must be an integer, got {text!r}") from None


def consecutive(seeds: list[int], *, verb: str) -> tuple[int, int]:
    """``(first, count)`` of a list of consecutive seeds (the verbs that dance seed sets ``K..K+N-1``)."""
    first = seeds[0]
    if seeds != list(range(first, first + len(seeds))):
        raise ParameterError(f"{verb} dances consecutive seeds (e.g. --seeds 0-4); got {seeds}")
    return first, len(seeds)


def output_fps(fps: float | None, *, flag: str = "--fps") -> float | None:
    """An output frame rate in ``(0, MAX_OUTPUT_FPS]``, or None."""
    if fps is None:
        return None
    if not fps > 0 or fps != fps:
        raise ParameterError(f"{flag} must be positive, got {fps:g}")
    if fps > MAX_OUTPUT_FPS:
        raise ParameterError(f"{flag} {fps:g} is above {MAX_OUTPUT_FPS:g} fps (the most dancekit writes)")
    return float(fps)


def seed_run(text: str | None, *, verb: str, default: int, first_seed: int | None = None,
             from_zero: bool = False) -> tuple[int, int]:
    """``(first, count)`` of the consecutive seeds ``--seeds LIST`` names, for the verbs that dance a run of
    seeds per song (default: ``0..default-1``). ``from_zero``: the run must start at seed 0.

    Deprecated, still read with a note on stderr saying how to write it now: a bare number ``--seeds N`` in
    these verbs (their old count: N seeds, ``0..N-1``; documented commands keep their results) and
    ``--first-seed K`` (N seeds from K)."""
    if first_seed is not None and first_seed < 0:
        raise ParameterError(f"--first-seed: the first seed must be a whole number >= 0, got {first_seed}")
    if text is not None and text.strip().isdigit() or first_seed is not None:
        n = default if text is None else (int(text) if text.strip().isdigit() else None)
        if n is None:
            raise ParameterError(f"--first-seed goes with a number of seeds (deprecated); write --seeds as a list "
                                 f"instead, e.g. --seeds {first_seed}-{first_seed + 4}")
        if n < 1:
            raise ParameterError(f"--seeds {text}: at least one seed")
        k = first_seed or 0
        old = f"--seeds {n}" + (f" --first-seed {k}" if first_seed is not None else "")
        print(f"dancekit {verb}: note: {old} (a count of seeds) is deprecated: --seeds is a list, as in "
              f"`dancekit dance`; write --seeds {k}-{k + n - 1}", file=sys.stderr)
        first, count = k, n
    elif text is None:
        return 0, default
    else:
        first, count = consecutive(seed_list(text), verb=verb)
    if from_zero and first != 0:
        raise ParameterError(f"{verb} dances the seeds 0..N-1: write --seeds 0-{count - 1}, got --seeds {text}")
    return first, count
