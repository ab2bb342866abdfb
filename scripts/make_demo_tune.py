"""Write the demo tune: "Ode to Joy" (public domain) synthesised, ~32 s at 120 BPM.

Melody and bass by additive synthesis plus a click on every beat (accented on
each bar), so the beats are at k * 0.5 s and the downbeats every 2 s.

    python scripts/make_demo_tune.py OUT.wav [--sr 22050] [--bpm 120]
"""

from __future__ import annotations

import argparse
import sys

from dancekit.audio import save_wav
from dancekit.audio.synth import ode_to_joy
from dancekit.errors import DancekitError


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", metavar="OUT.wav")
    parser.add_argument("--sr", type=int, default=22050, help="sample rate in Hz (default 22050)")
    parser.add_argument("--bpm", type=float, default=120.0, help="tempo (default 120)")
    args = parser.parse_args(argv)
    try:
        y = ode_to_joy(sr=args.sr, bpm=args.bpm)
        path = save_wav(args.output, y, sr=args.sr)
    except DancekitError as exc:
        print(f"make_demo_tune: error: {exc}", file=sys.stderr)
        return 2
    print(f"{path}: {len(y) / args.sr:.1f} s at {args.sr} Hz, {args.bpm:g} BPM")
    return 0


if __name__ == "__main__":
    sys.exit(main())
