"""Wall time of feature extraction for a 60 s song, per preset, at 25 fps (run by hand).

    OMP_NUM_THREADS=1 python benchmarks/bench_features.py [--fps 25] [--repeats 3]

Uses the first 60 s of a real song from ../shared/music when it is there,
otherwise the synthesised demo tune (looped to 60 s). Each preset runs once
to warm up (numba JIT, FFT plans), then ``--repeats`` times without the
cache; the best and median times are printed, split into decoding
(``audio.load``) and ``features.extract``. Target: revolution < 2 s warm.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from dancekit.audio import load
from dancekit.audio.synth import ode_to_joy
from dancekit.features import PRESET_DIMS, extract

SONG = Path(__file__).resolve().parents[1].parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fps", type=float, default=25)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()

    if SONG.exists():
        source = f"{SONG.name} [0, {args.seconds:g}) s"

        def get_audio():
            return load(SONG, start=0.0, end=args.seconds)
    else:
        source = "synthesised Ode to Joy (../shared absent)"
        sr = 22050
        tune = np.tile(ode_to_joy(sr=sr), 2)[: int(args.seconds * sr)]

        def get_audio():
            return tune, sr

    y, sr = get_audio()
    print(f"audio: {source}, {len(y) / sr:.1f} s at {sr} Hz; fps {args.fps:g}")
    t_load = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        get_audio()
        t_load.append(time.perf_counter() - t0)
    print(f"{'load':12s} best {min(t_load):6.3f} s  median {statistics.median(t_load):6.3f} s")
    for preset in PRESET_DIMS:
        t0 = time.perf_counter()
        extract(y, sr=sr, fps=args.fps, preset=preset)
        cold = time.perf_counter() - t0
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            fs = extract(y, sr=sr, fps=args.fps, preset=preset)
            times.append(time.perf_counter() - t0)
        print(
            f"{preset:12s} best {min(times):6.3f} s  median {statistics.median(times):6.3f} s  "
            f"(first run {cold:.3f} s)  -> {fs.features.shape}"
        )


if __name__ == "__main__":
    main()
