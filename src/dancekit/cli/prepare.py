"""``dancekit prepare tang2018 SRC -o DIR``: paired dataset preparation."""

from __future__ import annotations

import argparse
import time


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "prepare",
        help="prepare a paired music+dance dataset for training and evaluation",
        description="Write aligned music features (every preset), motion (positions + IK rotations), "
        "genre labels and whole-dance train/val/test splits.",
    )
    p.add_argument("source", choices=["tang2018"], help="dataset kind")
    p.add_argument("src", help="source folder (e.g. ../shared/data/tang2018)")
    p.add_argument("-o", "--out", required=True, help="output folder (replaced when complete)")
    p.add_argument("--fps", type=float, default=25.0, help="motion and feature frame rate (default 25)")
    p.add_argument("--presets", default="revolution,music2dance,dual", help="comma-separated feature presets")
    p.add_argument("--seed", type=int, default=0, help="seed of the split (default 0)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dancekit.data import PreparedData, prepare_tang2018

    t0 = time.perf_counter()
    presets = tuple(p.strip() for p in args.presets.split(",") if p.strip())
    out = prepare_tang2018(args.src, args.out, fps=args.fps, presets=presets, seed=args.seed)
    data = PreparedData(out)
    sizes = ", ".join(f"{k} {len(data.names(k))}" for k in ("train", "val", "test"))
    print(f"prepared {len(data.names())} dances into {out} ({sizes}) in {time.perf_counter() - t0:.1f} s")
    return 0
