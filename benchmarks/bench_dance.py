"""The main job's speed: generation (decode + features + model) and mp4 rendering per minute of music.

    python benchmarks/bench_dance.py [--model revolution | --checkpoint DIR] [--long]

For each of the three real songs in ../shared/music: generation wall time with a cold feature cache
(a fresh cache folder; the process is warm, i.e. librosa/numba are imported and compiled once on a
2-second clip first), then the mp4 rendering time at 25 fps, 640x480. Targets (issue 6): generation
<= 3 s and rendering <= 10 s per minute of music on 2 cores. ``--long`` also dances a synthesised
10-minute song and reports the peak resident memory of that process (bounded-memory check).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUSIC = ROOT.parent / "shared" / "music"
SONGS = [
    "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg",
    "Kevin_MacLeod_-_Vibe_Ace.ogg",
    "brahms_hungarian_dance_5.ogg",
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--checkpoint", default=None)
    parser.add_argument("--long", action="store_true", help="also a 10-minute song (peak memory)")
    parser.add_argument("--_long_child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()

    import torch

    torch.set_num_threads(2)
    from dancekit.pipelines import load_pipeline
    from dancekit.render import render_motion_mp4

    if args._long_child:
        pipe = load_pipeline(args.model, args.checkpoint)
        t0 = time.perf_counter()
        motion = pipe(args._long_child, seed=0).motion
        el = time.perf_counter() - t0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"10-minute song: {motion.num_frames} frames generated in {el:.1f} s, peak RSS {peak:.0f} MiB")
        return 0

    os.environ["DANCEKIT_CACHE"] = tempfile.mkdtemp(prefix="dk-bench-cache-")
    pipe = load_pipeline(args.model, args.checkpoint)
    with tempfile.TemporaryDirectory() as tmp:
        # warm the process: imports and numba compilation, on a short clip of another song
        pipe(str(MUSIC / SONGS[0]), seed=0, start=0.0, end=2.0)
        rows = []
        for song in SONGS:
            path = MUSIC / song
            t0 = time.perf_counter()
            motion = pipe(str(path), seed=0).motion
            gen = time.perf_counter() - t0
            t0 = time.perf_counter()
            render_motion_mp4(Path(tmp) / "out.mp4", motion, audio=path, progress=False)
            ren = time.perf_counter() - t0
            minutes = motion.duration / 60
            rows.append((song, motion.duration, gen, gen / minutes, ren, ren / minutes))
        print("| song | duration (s) | generation (s) | per minute | mp4 render (s) | per minute |")
        print("| --- | ---: | ---: | ---: | ---: | ---: |")
        for song, dur, gen, genm, ren, renm in rows:
            print(f"| {song[:40]} | {dur:.1f} | {gen:.2f} | {genm:.2f} | {ren:.2f} | {renm:.2f} |")
        if args.long:
            import numpy as np

            from dancekit.audio import save_wav
            from dancekit.audio.synth import ode_to_joy

            sr = 22050
            y = ode_to_joy(sr=sr, bpm=120, repeats=19)[: 600 * sr]  # 10 minutes
            long_song = Path(tmp) / "long.wav"
            save_wav(long_song, np.asarray(y, np.float32), sr=sr)
            cmd = [sys.executable, __file__, "--_long_child", str(long_song)]
            if args.model:
                cmd += ["--model", args.model]
            if args.checkpoint:
                cmd += ["--checkpoint", args.checkpoint]
            subprocess.run(cmd, check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
