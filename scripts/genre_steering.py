"""Does ``--genre`` steer? Dance every song of a split as every genre a model offers, and read it back.

    python scripts/genre_steering.py --checkpoint revolution --data data/tang2018 --split test \
        --out runs/revolution/steering.json

For each song of the split and each genre of the model (``pipe.genres``: a genre-conditioned model's
genres, or the genre models in its folder), one dance (seed 0) is generated for the same slice of the
song as in the dataset and classified by the embedded style classifier (``dancekit evaluate``'s). The
report gives the share of dances read back as the requested genre (``read_back``), the confusion
counts (requested → read), the classifier's mean probability of the requested genre, and per genre
the largest stillness share and the mean smoothed energy (m/s) of the dances (does it still dance?).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def steering(pipe, data, style, *, split: str, seeds: int = 1, progress: bool = True) -> dict:
    """Read-back scores of ``pipe`` (a dance pipeline with ``genres``) on the songs of ``split``."""
    from tqdm import tqdm

    from dancekit.metrics.stability import smoothed_energy, stillness_share

    if not pipe.genres:
        raise SystemExit("genre_steering: the model offers no genre (neither conditioned nor with genre models)")
    matrix = {g: dict.fromkeys(style.genres, 0) for g in pipe.genres}
    prob: dict[str, list[float]] = {g: [] for g in pipe.genres}
    still: dict[str, list[float]] = {g: [] for g in pipe.genres}
    energy: dict[str, list[float]] = {g: [] for g in pipe.genres}
    per_song = {}
    jobs = [(n, g, k) for n in data.names(split) for g in pipe.genres for k in range(seeds)]
    for name, genre, k in tqdm(jobs, desc="steering", unit="dance", disable=not progress):
        ref = data.audio(name)
        m = pipe(ref.path, seed=k, start=ref.start, end=ref.end, genre=genre).motion
        pos = m.to_positions()
        still[genre].append(stillness_share(pos, fps=m.fps, skeleton=m.skeleton))
        energy[genre].append(smoothed_energy(pos, fps=m.fps, skeleton=m.skeleton))
        _, logp = style.embed(pos, fps=m.fps, skeleton=m.skeleton)
        p = np.exp(logp).mean(axis=0)
        read = style.genres[int(np.argmax(logp.mean(axis=0)))]
        matrix[genre][read] += 1
        prob[genre].append(float(p[style.genres.index(genre)]))
        per_song.setdefault(name, {})[genre if seeds == 1 else f"{genre}__{k}"] = read
    n = len(jobs)
    hits = sum(matrix[g][g] for g in pipe.genres)
    return {
        "split": split, "seeds": seeds, "n": n, "read_back": hits / n,
        "read_back_per_genre": {g: matrix[g][g] / sum(matrix[g].values()) for g in pipe.genres},
        "mean_prob_requested": {g: float(np.mean(v)) for g, v in prob.items()},
        "stillness_max": {g: float(max(v)) for g, v in still.items()},
        "smoothed_energy": {g: float(np.mean(v)) for g, v in energy.items()},
        "matrix": matrix, "per_song": per_song,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", required=True, help="checkpoint folder, or an embedded model name")
    parser.add_argument("--data", required=True, help="prepared dataset folder")
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--out", help="write the report (JSON) here")
    args = parser.parse_args(argv)

    from dancekit.data import PreparedData
    from dancekit.metrics.style import load_style_classifier
    from dancekit.pipelines import load_pipeline

    ckpt = Path(args.checkpoint)
    pipe = load_pipeline(checkpoint=ckpt) if ckpt.is_dir() else load_pipeline(args.checkpoint)
    t0 = time.perf_counter()
    report = steering(pipe, PreparedData(args.data), load_style_classifier(), split=args.split, seeds=args.seeds)
    report["checkpoint"] = str(args.checkpoint)
    report["elapsed_s"] = round(time.perf_counter() - t0, 1)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(report, indent=1) + "\n")
    print(f"read back {report['read_back']:.3f} of {report['n']} dances; per genre "
          + ", ".join(f"{g} {v:.2f}" for g, v in report["read_back_per_genre"].items()))
    for g, row in report["matrix"].items():
        print(f"  asked {g:7s} → " + ", ".join(f"{r} {c}" for r, c in row.items() if c)
              + f"   (stillness max {report['stillness_max'][g]:.3f}, energy {report['smoothed_energy'][g]:.3f} m/s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
