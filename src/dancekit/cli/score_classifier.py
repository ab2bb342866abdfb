"""``dancekit score-classifier CHECKPOINT... --data DIR``: accuracy of classifiers on a prepared dataset.

A style classifier (``dancekit train style``) is scored on the real dances of every split (accuracy and
balanced accuracy per 4-s window and per whole dance); a music attribute classifier (``dancekit train
music_attributes``) on the songs (per-song accuracy and every validation / test prediction). See
:mod:`dancekit.evaluation.classifiers`.
"""

from __future__ import annotations

import argparse
import json


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "score-classifier",
        help="accuracy of style / music attribute classifiers on every split",
        description="Score classifier checkpoints (style: motion → genre; music_attributes: music → genre) on "
        "the train, val and test splits of a prepared dataset.",
    )
    p.add_argument("checkpoints", nargs="+", metavar="CHECKPOINT", help="classifier checkpoint folders or names")
    p.add_argument("--data", required=True, metavar="PREPARED_DIR", help="prepared dataset folder")
    p.add_argument("-o", "--output", metavar="JSON", help="write the scores (a list, one entry per checkpoint)")
    p.set_defaults(func=run)
    return p


def _line(scores: dict) -> str:
    parts = [scores["checkpoint"]]
    for split in ("train", "val", "test"):
        r = scores.get(split)
        if not r:
            continue
        if scores["family"] == "style":
            parts.append(f"{split}: {r['n_dances']} dances, {r['n_windows']} windows | window acc "
                         f"{r['window_accuracy']:.3f}, balanced {r['window_balanced_accuracy']:.3f} | dance acc "
                         f"{r['dance_accuracy']:.3f}, balanced {r['dance_balanced_accuracy']:.3f}")
        else:
            shown = "" if split == "train" else " [" + ", ".join(f"{n}→{g}" for n, g in r["predictions"].items()) + "]"
            parts.append(f"{split} {r['accuracy']:.3f}{shown}")
    return "\n  ".join(parts) if scores["family"] == "style" else " | ".join(parts)


def run(args: argparse.Namespace) -> int:
    from dancekit._io import atomic_path
    from dancekit.data import PreparedData
    from dancekit.evaluation import score_classifier

    data = PreparedData(args.data)
    results = []
    for ckpt in args.checkpoints:
        scores = score_classifier(ckpt, data)
        results.append(scores)
        print(_line(scores))
    if args.output:
        with atomic_path(args.output) as tmp:
            tmp.write_text(json.dumps(results, indent=1))
    return 0
