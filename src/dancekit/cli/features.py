"""``dancekit features AUDIO -o OUT.npz --preset P --fps N``: music features for one song."""

from __future__ import annotations

import argparse
from pathlib import Path

from dancekit.errors import ParameterError

HELP = "extract frame-aligned music features (revolution / music2dance / dual) to an .npz"


def add_parser(subparsers) -> argparse.ArgumentParser:
    from dancekit.features.presets import BACKENDS, PRESET_DIMS

    p = subparsers.add_parser(
        "features",
        help=HELP,
        description=HELP + ". The npz holds features (T x D float32), fps, preset, names, beat_times, tempo.",
    )
    p.add_argument("audio", metavar="AUDIO", help="audio file (wav, flac, ogg, mp3, m4a, ...)")
    p.add_argument(
        "-o", "--output", required=True, metavar="OUT.npz", help="output .npz (written atomically)"
    )
    p.add_argument(
        "--preset",
        required=True,
        choices=sorted(PRESET_DIMS),
        help="feature set: " + ", ".join(f"{k} ({v}-D)" for k, v in PRESET_DIMS.items()),
    )
    p.add_argument("--fps", required=True, type=float, help="motion frame rate; one feature row per frame")
    p.add_argument(
        "--hop-length", type=int, default=512, help="hop at the feature rate fps*hop (default 512)"
    )
    p.add_argument("--start", type=float, default=None, metavar="S", help="excerpt start in seconds")
    p.add_argument("--end", type=float, default=None, metavar="S", help="excerpt end in seconds")
    p.add_argument(
        "--backend", choices=BACKENDS, default="librosa", help="beat/downbeat tracker (default librosa)"
    )
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the feature cache")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from dancekit.features import extract_file

    out = Path(args.output)
    if out.suffix != ".npz":
        raise ParameterError(f"output must end in .npz, got {str(out)!r}")
    fs = extract_file(
        args.audio,
        fps=args.fps,
        preset=args.preset,
        start=args.start,
        end=args.end,
        hop_length=args.hop_length,
        backend=args.backend,
        use_cache=not args.no_cache,
    )
    fs.save(out)
    source = "cache" if fs.from_cache else "computed"
    print(
        f"{out}: {fs.preset} features {fs.num_frames}x{fs.dim} at {fs.fps:g} fps "
        f"({fs.num_frames / fs.fps:.1f} s), {len(fs.beat_times)} beats, tempo {fs.tempo:.1f} BPM ({source})"
    )
    return 0
