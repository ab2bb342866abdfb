"""Song-level accuracy of music attribute classifiers (``dancekit train music_attributes``) on a prepared dataset.

    python scripts/score_music_attributes.py runs/music_attributes/model [more checkpoints] --data data/tang2018

For every checkpoint and split, each song's music (the dance's excerpt, the prepared features of the
classifier's preset) is classified by :meth:`MusicAttributePipeline.classify_features` (the mean
log-probability of its 30-s windows); prints the accuracy and every validation / test prediction.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--data", required=True, help="prepared dataset folder")
    args = parser.parse_args(argv)

    from dancekit.data import PreparedData
    from dancekit.pipelines import MusicAttributePipeline

    data = PreparedData(args.data)
    for ckpt in args.checkpoints:
        pipe = MusicAttributePipeline.from_pretrained(ckpt)
        parts = [ckpt]
        for split in ("train", "val", "test"):
            pred = {}
            for name in data.names(split):
                probs = pipe.classify_features(data.features(name, pipe.preset)["features"], source=name)
                pred[name] = max(probs, key=probs.get)
            acc = np.mean([data.genre(n) == g for n, g in pred.items()])
            shown = "" if split == "train" else " [" + ", ".join(f"{n}→{g}" for n, g in pred.items()) + "]"
            parts.append(f"{split} {acc:.3f}{shown}")
        print(" | ".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
