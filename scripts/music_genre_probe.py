"""Can the genre of a tang2018 song be told from its music alone? A probe, not part of the toolkit.

    python scripts/music_genre_probe.py --data data/tang2018

Logistic regression (class-balanced, standardised inputs) on 10-s windows (hop 5 s) of each training
song's ``revolution`` features: mean and std of the 52 onset/chroma/MFCC/beat columns and the mean of
the first 200 tempogram lags. A song's genre is the argmax of its windows' mean log-probability.
Prints the per-song predictions on the validation and test splits for three regularisation strengths.
If the music alone does not separate the genres, a dance model cannot be expected to either.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

WINDOW, HOP = 250, 125  # frames at 25 fps


def pooled(features: np.ndarray) -> np.ndarray:
    out = []
    for s in range(0, max(1, len(features) - WINDOW + 1), HOP):
        w = features[s : s + WINDOW]
        out.append(np.concatenate([w[:, :52].mean(0), w[:, :52].std(0), w[:, 52:436].mean(0)[:200]]))
    return np.array(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True)
    args = parser.parse_args(argv)

    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    from dancekit.data import PreparedData

    data = PreparedData(args.data)
    genres = list(data.genres)
    X, y = [], []
    for n in data.names("train"):
        f = pooled(data.features(n, "revolution")["features"])
        X.append(f)
        y += [genres.index(data.genre(n))] * len(f)
    X, y = np.concatenate(X), np.array(y)
    for C in (0.01, 0.1, 1.0):
        clf = make_pipeline(StandardScaler(), LogisticRegression(C=C, max_iter=3000, class_weight="balanced"))
        clf.fit(X, y)
        for split in ("val", "test"):
            pred = {n: genres[int(np.argmax(clf.predict_log_proba(pooled(data.features(n, "revolution")["features"]))
                                            .mean(0)))] for n in data.names(split)}
            acc = np.mean([data.genre(n) == g for n, g in pred.items()])
            print(f"C={C:<5} {split:5s} accuracy {acc:.3f}: " + ", ".join(f"{n}→{g}" for n, g in pred.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
