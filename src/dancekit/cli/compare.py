"""``dancekit compare NAME=report.json ...``: side-by-side markdown table of ``dancekit evaluate`` reports.

Rows are the metrics of :data:`dancekit.evaluation.TABLE_ROWS` (the labels ``dancekit evaluate`` prints);
the first column is the real reference dances of the first report.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dancekit.errors import DatasetError, ParameterError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "compare",
        help="side-by-side table of several evaluate reports",
        description="Print a markdown table of several `dancekit evaluate` reports (one column each, after "
        "the real dances of the first).",
    )
    p.add_argument("reports", nargs="+", metavar="NAME=REPORT", help="a column name and a report.json")
    p.add_argument("-o", "--output", metavar="MD", default=None, help="also write the table to this file")
    p.set_defaults(func=run)
    return p


def _read(item: str) -> tuple[str, dict]:
    name, sep, path = item.partition("=")
    if not sep or not name or not path:
        raise ParameterError(f"expected NAME=REPORT, got {item!r}")
    try:
        return name, json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DatasetError(f"report not found: {path}") from None
    except json.JSONDecodeError as exc:
        raise DatasetError(f"not a JSON report: {path}: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from dancekit._io import atomic_path
    from dancekit.evaluation import format_comparison

    reports = [_read(item) for item in args.reports]
    for name, report in reports:
        if not isinstance(report, dict) or "metrics" not in report or "real" not in report:
            raise DatasetError(f"{name}: not a `dancekit evaluate` report (no 'metrics' and 'real')")
    table = format_comparison(reports)
    print(table)
    if args.output:
        with atomic_path(args.output) as tmp:
            tmp.write_text(table + "\n")
    return 0
