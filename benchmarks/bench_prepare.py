"""``prepare`` throughput with 1 and 2 worker processes, on tang2018 dances as a folder of the user's pairs.

    PYTHONPATH=src python benchmarks/bench_prepare.py [--dances 8] [--presets revolution] [--workers 1,2]

The first ``--dances`` dances of ../shared/data/tang2018 are turned into a ``prepare pairs`` folder (each
dance's motion as ``NAME.npz`` and its song excerpt as ``NAME.wav``; not timed), then ``prepare_pairs``
runs on it once per worker count (uncached features), and the wall time, dances per minute and minutes of
dance prepared per minute are printed. The AIST++ path (``prepare aistpp``) runs the same per-pair code.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TANG = ROOT.parent / "shared" / "data" / "tang2018"


def make_pairs(dst: Path, n: int) -> float:
    """Write ``n`` tang2018 dances as pairs into ``dst``; returns their total duration in seconds."""
    from dancekit.audio.io import load, save_wav
    from dancekit.motion.formats import read_tang2018, write_motion

    total = 0.0
    for folder in sorted(p for p in TANG.iterdir() if p.is_dir())[:n]:
        motion, audio = read_tang2018(folder)
        y, sr = load(audio.path, start=audio.start, end=audio.end)
        save_wav(dst / f"{folder.name}.wav", y, sr=sr)
        write_motion(dst / f"{folder.name}.npz", motion)
        total += motion.duration
    return total


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dances", type=int, default=8)
    ap.add_argument("--presets", default="revolution")
    ap.add_argument("--workers", default="1,2")
    args = ap.parse_args()
    from dancekit.data.pairs import prepare_pairs

    presets = tuple(p for p in args.presets.split(",") if p)
    with tempfile.TemporaryDirectory(prefix="dk-prep-") as tmp:
        src = Path(tmp) / "pairs"
        src.mkdir()
        seconds = make_pairs(src, args.dances)
        print(f"{args.dances} tang2018 dances, {seconds / 60:.1f} min of dance, presets {','.join(presets)}")
        for w in (int(x) for x in args.workers.split(",")):
            t0 = time.perf_counter()
            _, report = prepare_pairs(src, Path(tmp) / f"out{w}", presets=presets, workers=w, progress=False)
            wall = time.perf_counter() - t0
            n = len(report["prepared"])
            print(f"workers {w}: {wall:.1f} s for {n} dances: {60 * n / wall:.1f} dances/min, "
                  f"{seconds / wall:.2f} min of dance per minute")
    return 0


if __name__ == "__main__":
    sys.exit(main())
