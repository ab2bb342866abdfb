"""Train the style (genre) classifier used by ``dancekit evaluate`` on a prepared dataset.

    python scripts/train_style.py --data data/tang2018 --out runs/style [--epochs 15] [--install]

Writes the training run to ``OUT/run`` (checkpoints, ``log.jsonl``), the final checkpoint
(best validation loss, scores in its ``config.json``) to ``OUT/classifier`` and the scores to
``OUT/report.json``; prints accuracy and balanced accuracy on the real validation and test
dances (per 4-s window and per whole dance). ``--install`` copies the classifier to
``src/dancekit/assets/models/style/`` (the one ``dancekit evaluate`` uses by default).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from dancekit._io import atomic_dir
from dancekit.errors import DancekitError


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, help="prepared dataset folder (dancekit prepare tang2018 ...)")
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument("--epochs", type=int, default=15)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    parser.add_argument("--install", action="store_true", help="copy the classifier into the package assets")
    args = parser.parse_args(argv)

    from dancekit.metrics.style import DEFAULT_CLASSIFIER, train_style_classifier

    try:
        _, report = train_style_classifier(args.data, args.out, epochs=args.epochs, seed=args.seed,
                                           threads=args.threads)
    except DancekitError as exc:
        print(f"train_style: error: {exc}", file=sys.stderr)
        return 2
    for split in ("train", "val", "test"):
        r = report.get(split)
        if r:
            print(f"{split:5s}: {r['n_dances']} dances, {r['n_windows']} windows | "
                  f"window acc {r['window_accuracy']:.3f}, balanced {r['window_balanced_accuracy']:.3f} | "
                  f"dance acc {r['dance_accuracy']:.3f}, balanced {r['dance_balanced_accuracy']:.3f}")
    src = Path(args.out) / "classifier"
    size = sum(f.stat().st_size for f in src.iterdir())
    print(f"classifier: {src} ({size / 1e6:.2f} MB)")
    if args.install:
        with atomic_dir(DEFAULT_CLASSIFIER) as tmp:
            tmp.chmod(0o755)  # package data: readable by everyone
            for f in src.iterdir():
                shutil.copy2(f, tmp / f.name)
                (tmp / f.name).chmod(0o644)
        print(f"installed: {DEFAULT_CLASSIFIER}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
