"""Many dances in one pass (issue 18): ``dancekit dance SONG --seeds 0-7`` against ``--seed 0``, end to end.

    PYTHONPATH=src python benchmarks/bench_seeds.py [--song PATH] [--seeds 0-7] [--repeats 2]
        [--formats npz mp4,html,npz,bvh]

Each run is a fresh ``python -m dancekit.cli.main dance`` process (imports, model loading, numba
compilation included: what a user waits for) with the default model, timed by wall clock. Two cache states:
*cold* (a fresh feature cache folder: the song's features and beats are computed in the run) and *warm* (the
cache filled by a previous run: only generation, stages and export are left). The table gives the median
wall time of ``--repeats`` runs for one seed and for the seed list, their ratio (target for ``--format
npz``: <= 2), and the 1-minute load average when each pair started (the machine may be shared). Rendering
is per dance: with mp4 in the formats, N seeds render N videos, so that row grows with N by design.
The song defaults to ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg (61.5 s).

``--compare [SECONDS]`` instead compares, in this process, each batched dance with the seed danced alone
(every dance family, stages off and on, the first SECONDS of the song, default 20): the largest and mean
joint distance in cm.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def dance(song: Path, out: Path, cache: Path, formats: str, seed_args: list[str]) -> float:
    env = {**os.environ, "DANCEKIT_CACHE": str(cache), "PYTHONPATH": str(ROOT / "src")}
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o", str(out), "--format",
                        formats, "--quiet", *seed_args], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"dancekit dance failed ({r.returncode}): {r.stderr.strip()}")
    return wall


def compare(song: Path, seeds: list[int], seconds: float) -> None:
    import numpy as np

    from dancekit.pipelines import load_pipeline

    print(f"song: {song.name}, first {seconds:g} s, seeds {seeds}: batch row against the seed alone")
    print("| model | stages | seed | max (cm) | mean (cm) |")
    print("| --- | --- | ---: | ---: | ---: |")
    for name in ("revolution", "music2dance", "dual"):
        pipe = load_pipeline(name)
        for on in (False, True):
            batch = pipe.dances(str(song), seeds=seeds, end=seconds, beat_sync=on, cleanup=on)
            for r, seed in zip(batch, seeds):
                alone = pipe(str(song), seed=seed, end=seconds, beat_sync=on, cleanup=on)
                d = np.abs(r.motion.to_positions() - alone.motion.to_positions())
                print(f"| {name} | {'on' if on else 'off'} | {seed} | {d.max():.4f} | {d.mean():.5f} |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--song", default=str(SONG))
    ap.add_argument("--seeds", default="0-7")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--formats", nargs="+", default=["npz", "mp4,html,npz,bvh"])
    ap.add_argument("--compare", type=float, nargs="?", const=20.0, default=None, metavar="SECONDS")
    args = ap.parse_args()
    song = Path(args.song)
    from dancekit.pipelines import parse_seeds

    if args.compare is not None:
        compare(song, parse_seeds(args.seeds)[:2] if args.seeds == "0-7" else parse_seeds(args.seeds), args.compare)
        return 0

    n = len(parse_seeds(args.seeds))
    rows = []
    with tempfile.TemporaryDirectory(prefix="dk-seeds-") as tmp:
        tmp = Path(tmp)
        for formats in args.formats:
            for cache_state in ("cold", "warm"):
                one, many, loads = [], [], []
                for r in range(args.repeats):
                    loads.append(os.getloadavg()[0])
                    for seed_args, times in ((["--seed", "0"], one), (["--seeds", args.seeds], many)):
                        cache = tmp / f"cache-{cache_state}-{r}-{len(times)}-{seed_args[0]}"
                        if cache_state == "warm":  # fill it first, untimed
                            dance(song, tmp / "warmup", cache, "npz", ["--seed", "0"])
                        times.append(dance(song, tmp / f"out-{len(rows)}-{r}-{seed_args[0]}", cache, formats,
                                           seed_args))
                a, b = statistics.median(one), statistics.median(many)
                rows.append((formats, cache_state, a, b, b / a, loads))
    print(f"song: {song.name}; {n} seeds ({args.seeds}); median of {args.repeats} runs; wall clock of a fresh process")
    print(f"| --format | feature cache | 1 seed (s) | {n} seeds (s) | ratio | load average at start |")
    print("| --- | --- | ---: | ---: | ---: | --- |")
    for formats, cache_state, a, b, ratio, loads in rows:
        print(f"| {formats} | {cache_state} | {a:.1f} | {b:.1f} | {ratio:.2f} | "
              + ", ".join(f"{x:.1f}" for x in loads) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
