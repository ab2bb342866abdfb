"""Refresh the test-split metrics in an embedded model's ``card.json`` (what ``dancekit models`` prints).

    dancekit evaluate --checkpoint revolution --data data/tang2018 --split test --seeds 0-4 -o runs/eval_rev
    python scripts/refresh_card_metrics.py revolution runs/eval_rev/report.json --date 2026-11-24

Replaces the card's ``metrics`` with the headline metrics of the report (the keys
:data:`embed_model.CARD_METRICS`, the same as when the model was embedded, plus any other key the card
already had and the report has) and ``metrics_source`` with how they
were measured (the report's split, dance count and seeds); other card entries are kept. The weights are
not touched. Refuses a report that is not a test-split report of that model.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from embed_model import CARD_METRICS, MODELS, _pick  # noqa: E402


def _seed_list(gen: dict) -> str:
    """The ``--seeds`` list of a report's ``generation`` (``seeds`` a count from ``first_seed``, or a list)."""
    seeds = gen.get("seeds")
    if isinstance(seeds, list):
        return ",".join(str(s) for s in seeds)
    first = int(gen.get("first_seed") or 0)
    return f"{first}-{first + int(seeds) - 1}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("name", help="embedded model folder name (dancekit/assets/models/NAME)")
    parser.add_argument("report", help="dancekit evaluate report.json of that model on the test split")
    parser.add_argument("--date", required=True, help="when the report was measured (YYYY-MM-DD)")
    parser.add_argument("--key", default="metrics", choices=("metrics", "metrics_genre_none"),
                        help="the card entry to replace (metrics_genre_none: a --genre none report)")
    args = parser.parse_args(argv)
    card_path = MODELS / args.name / "card.json"
    if not card_path.is_file():
        parser.error(f"no embedded model {args.name!r} ({card_path} missing)")
    report = json.loads(Path(args.report).read_text())
    gen = report.get("generation") or {}
    if gen.get("split") != "test":
        parser.error(f"{args.report}: not a test-split report of `dancekit evaluate --checkpoint` "
                     f"(split {gen.get('split')!r})")
    checkpoint = str(gen.get("checkpoint", ""))
    if Path(checkpoint).name != args.name and checkpoint != args.name:
        parser.error(f"{args.report}: a report of {checkpoint!r}, not of {args.name!r}")
    card = json.loads(card_path.read_text())
    counts = report.get("counts", {})
    card[args.key.replace("metrics", "metrics_source")] = (f"dancekit evaluate --checkpoint {args.name} --split test --seeds {_seed_list(gen)} "
                              f"--genre {gen.get('genre')} on tang2018 ({counts.get('songs', '?')} songs, "
                              f"{gen.get('files', '?')} dances, every default stage, beat sync "
                              f"{'on' if gen.get('beat_sync') else 'off'}), measured {args.date}; see docs/BENCHMARKS.md")
    if (args.key == "metrics_genre_none") != (gen.get("genre") == "none"):
        parser.error(f"{args.report}: a --genre {gen.get('genre')} report does not go into {args.key}")
    old = card.get(args.key) or {}
    extra = {k: round(float(report["metrics"][k]), 4) for k in old
             if k not in CARD_METRICS and report["metrics"].get(k) is not None}  # e.g. style_multimodality
    card[args.key] = {**_pick(report), **extra}
    card_path.write_text(json.dumps(card, indent=1, ensure_ascii=False) + "\n")
    print(f"{card_path}: metrics from {args.report}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
