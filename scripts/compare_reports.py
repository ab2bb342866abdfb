"""Side-by-side markdown table of several ``dancekit evaluate`` reports.

    python scripts/compare_reports.py NAME=report.json [NAME=report.json ...]

Rows are the metrics of ``dancekit.metrics.evaluate.TABLE_ROWS`` (the same labels as
``dancekit evaluate`` prints); the first column is the real reference dances of the first report.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path


def main(argv: list[str]) -> int:
    from dancekit.metrics.evaluate import TABLE_ROWS

    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    reports = []
    for arg in argv:
        name, _, path = arg.partition("=")
        reports.append((name, json.loads(Path(path).read_text())))
    header = ["metric", "real (test)"] + [name for name, _ in reports]
    lines = ["| " + " | ".join(header) + " |", "| --- |" + " ---: |" * (len(header) - 1)]
    for key, label, fmt in TABLE_ROWS:
        values = [reports[0][1]["real"].get(key)] + [r["metrics"].get(key) for _, r in reports]
        if all(v is None for v in values):
            continue
        cells = ["–" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v) for v in values]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
