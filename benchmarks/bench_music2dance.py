"""Music2Dance generation time: 60 s of dance from a song file, features included (run by hand, CPU).

    PYTHONPATH=src python benchmarks/bench_music2dance.py SONG [--model music2dance] [--threads 1] [--repeats 3]

Times ``Music2DancePipeline.from_pretrained(model)(SONG, end=60)`` (music features, F_map, the frame loop of
the WaveNet with its per-layer queues, decoding, floor) after one warm-up call, with and without the Foot
Constraint Model, and prints the median wall time, the median CPU time of the process (what an idle core
would take, nearly) and the machine's load average (the figure depends on it:
docs/BENCHMARKS.md). Target of issue 13: <= 5 s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import torch


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("song")
    p.add_argument("--model", default="music2dance")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    from dancekit.pipelines.foot_constraint import load_foot_constraint
    from dancekit.pipelines.music2dance import Music2DancePipeline

    pipe = Music2DancePipeline.from_pretrained(args.model)
    fix = load_foot_constraint()
    pipe(args.song, seed=0, end=5.0)  # warm-up (imports, allocations)
    times, cpu, fixed = [], [], []
    for k in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        r = pipe(args.song, seed=k, end=60.0)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        t0 = time.perf_counter()
        fix(r.motion)
        fixed.append(time.perf_counter() - t0)
    print(f"{args.model}: {r.motion.num_frames} frames ({r.motion.duration:.1f} s of dance), median "
          f"{statistics.median(times):.2f} s (runs {', '.join(f'{t:.2f}' for t in times)}), foot model +"
          f"{statistics.median(fixed):.2f} s; CPU time {statistics.median(cpu):.2f} s (about the wall time of an idle "
          f"core); threads {args.threads}; load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
