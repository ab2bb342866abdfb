"""``dancekit evaluate``: score a folder of generated dances against the real ones.

    dancekit evaluate --pred runs/model/test --ref data/tang2018 --data data/tang2018 -o report.json

Prints a markdown table (generated vs real) and writes every metric, per-dance values and the
settings used to a JSON file (atomically). Layout, music lookup and defaults:
:mod:`dancekit.metrics.evaluate` and docs/METRICS.md.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dancekit._io import atomic_path
from dancekit.errors import ParameterError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "evaluate",
        help="score generated dances against real ones (FID_k/g, BAS, style FID/ACC, ...)",
        description="Score a folder of generated dances (NAME.npz or NAME__k.npz, NAME = a reference dance) "
        "against the reference dances and print a markdown table; every metric goes to the JSON report.",
    )
    p.add_argument("--pred", required=True, metavar="DIR", help="folder of generated .npz dances")
    p.add_argument("--ref", required=True, metavar="DIR",
                   help="folder of real NAME.npz dances, or a prepared dataset folder (its --split)")
    p.add_argument("--split", default="test", help="split of a prepared --ref folder (default test)")
    music = p.add_mutually_exclusive_group()
    music.add_argument("--data", metavar="PREPARED_DIR",
                       help="prepared dataset: music beats (features_*.npz beat_times), genres, FID reference")
    music.add_argument("--audio", metavar="DIR", help="folder of NAME.wav|mp3|ogg|flac songs (beats are tracked)")
    p.add_argument("-o", "--output", required=True, metavar="JSON", help="report file to write")
    p.add_argument("--sigma", type=float, default=0.05, help="BAS Gaussian sigma in seconds (default 0.05)")
    p.add_argument("--tolerance", type=float, default=0.1,
                   help="beat hit tolerance in seconds for coverage / hit rate (default 0.1)")
    p.add_argument("--segment-seconds", type=float, default=10.0,
                   help="FID_k / FID_g segment length in seconds; 0 = whole dances (default 10)")
    p.add_argument("--fid-ref", choices=("ref", "train", "all"), default=None,
                   help="FID reference set (default: train with --data, else ref)")
    p.add_argument("--bug-compatible", action="store_true",
                   help="reproduce the public reference feature code (acceleration bug, 1/120 s frame time)")
    p.add_argument("--classifier", metavar="DIR", default=None,
                   help="style classifier checkpoint (default: the one shipped with dancekit)")
    p.add_argument("--no-style", action="store_true", help="skip the style-classifier metrics")
    p.add_argument("--preset", default=None, help="feature preset whose beat_times to use (default revolution)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random pairs of Diversity (default 0)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from dancekit.metrics.evaluate import EvalSettings, evaluate_dirs, format_markdown

    if args.segment_seconds < 0:
        raise ParameterError(f"--segment-seconds must be >= 0, got {args.segment_seconds}")
    out = Path(args.output)
    if not out.parent.exists():
        raise ParameterError(f"output folder does not exist: {out.parent}")
    settings = EvalSettings(
        sigma=args.sigma,
        tolerance=args.tolerance,
        segment_seconds=args.segment_seconds or None,
        bug_compatible=args.bug_compatible,
        fid_reference=args.fid_ref,
        seed=args.seed,
    )
    classifier = None if args.no_style else (args.classifier or "default")
    report = evaluate_dirs(args.pred, args.ref, data=args.data, audio_dir=args.audio, classifier=classifier,
                           settings=settings, preset=args.preset, split=args.split)
    print(format_markdown(report), end="")
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    print(f"report: {out}")
    return 0
