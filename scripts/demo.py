"""`make demo`: dance to the user's song, or to a tune the toolkit synthesises itself.

The repository ships no third-party audio: without ``--song`` a public-domain melody
(Beethoven's "Ode to Joy") is synthesised with dancekit's own small synthesiser.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--song", default=None, help="your song (any format dancekit reads)")
    parser.add_argument("--out", default="demo_out", help="output folder")
    args = parser.parse_args()

    from dancekit.cli.main import main as dancekit

    out = Path(args.out)
    song = args.song
    if not song:
        from dancekit.audio import save_wav
        from dancekit.audio.synth import ode_to_joy

        out.mkdir(parents=True, exist_ok=True)
        song = str(out / "ode_to_joy.wav")
        sr = 22050
        save_wav(song, ode_to_joy(sr=sr, bpm=120, repeats=1), sr=sr)
        print(f"synthesised a demo tune (Ode to Joy, public domain): {song}")
    code = dancekit(["dance", song, "-o", str(out)])
    if code == 0:
        stem = Path(song).stem
        print(f"\nwatch it:   {out / (stem + '.mp4')}")
        print(f"play in 3D: {out / (stem + '.html')}  (open in a browser; works offline)")
    return code


if __name__ == "__main__":
    sys.exit(main())
