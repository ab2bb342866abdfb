"""``dancekit compose MOTION -o OUTDIR``: music for a dance with the dual-learning model's G_D→M (MIDI + WAV)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dancekit.errors import ParameterError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compose",
        help="compose music for a dance: MIDI (chords, bass, drums on the composed beats) and WAV",
        description="Compose chroma and beats for MOTION with a dual-learning model (G_D→M) and arrange them as "
                    "MIDI (chords on the beats, bass on the chord roots, drums on the beats), rendered to WAV with "
                    "FluidSynth when installed, else the built-in synthesiser.",
    )
    p.add_argument("motion", help="a dance file the toolkit reads (npz, BVH, AIST++ pkl, tang2018 folder)")
    p.add_argument("-o", "--out", required=True, help="output folder (created if missing)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--model", default=None, help="a dual model name (`dancekit models`) or folder")
    g.add_argument("--checkpoint", default=None, help="a dual checkpoint folder (from `dancekit train dual`)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the start chord (default 0)")
    p.add_argument("--tempo", default="auto", help="auto (the composed beats, default) or a tempo in BPM")
    p.add_argument("--render", default="auto", choices=("auto", "fluidsynth", "builtin"), help="audio renderer")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def parse_tempo(text: str) -> str | float:
    if text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise ParameterError(f"--tempo must be 'auto' or a number of BPM, got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    from dancekit.motion.formats import read_motion
    from dancekit.pipelines.dual import ComposePipeline

    t0 = time.perf_counter()
    tempo = parse_tempo(args.tempo)
    motion = read_motion(args.motion)
    pipe = ComposePipeline.from_pretrained(args.checkpoint or args.model)
    result = pipe(motion, seed=args.seed, tempo=tempo)
    files = result.write(Path(args.out), stem=Path(args.motion).stem, render=args.render)
    if not args.quiet:
        arr = result.arrangement
        print(f"composed {arr.duration:.1f} s from {result.start_chord}: {len(arr.beat_times)} beats at "
              f"{arr.tempo:.1f} BPM, chords {' '.join(arr.chord_names()[:8])}{' ...' if len(arr.chords) > 8 else ''} "
              f"in {time.perf_counter() - t0:.1f} s")
        for path in files.values():
            print(f"  {path}")
    return 0
