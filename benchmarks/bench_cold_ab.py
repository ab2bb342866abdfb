"""Cold ``dancekit dance`` of two checkouts, interleaved: an A/B of a start-up change on a shared machine.

    python benchmarks/bench_cold_ab.py --a /work/main/src --b src [--repeats 3] [--models default music2dance]
                                       [--song ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg]

Every run is a fresh process ``python -m dancekit.cli.main dance SONG --format npz --quiet -o TMP
[--model M]`` with its own empty feature cache (``DANCEKIT_CACHE`` a new temporary folder) and
``PYTHONPATH`` the checkout's sources. The runs alternate A, B (B, A on every other repeat) for each model,
so both see the same load. Per run: wall seconds (spawn to exit), CPU seconds (user + system of the child
and its prefetch child: the change of ``getrusage(RUSAGE_CHILDREN)``), and the 1-minute load average
before it. Prints a JSON line per run and the median per (model, checkout).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def run_once(src: Path, song: Path, model: str) -> dict:
    cache, out = tempfile.mkdtemp(prefix="ab_cache_"), tempfile.mkdtemp(prefix="ab_out_")
    env = dict(os.environ, DANCEKIT_CACHE=cache, PYTHONPATH=str(src))
    cmd = [sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "--format", "npz", "--quiet", "-o", out]
    if model != "default":
        cmd += ["--model", model]
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    shutil.rmtree(cache, ignore_errors=True)
    shutil.rmtree(out, ignore_errors=True)
    if proc.returncode:
        raise SystemExit(f"{cmd} failed: {proc.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": round(wall, 3), "cpu_s": round(cpu, 3), "load1": round(load, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", type=Path, required=True, help="checkout A's src folder (the baseline)")
    ap.add_argument("--b", type=Path, required=True, help="checkout B's src folder (the change)")
    ap.add_argument("--song", type=Path, default=DEFAULT_SONG)
    ap.add_argument("--models", nargs="+", default=["default", "music2dance"])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    runs: dict[tuple[str, str], list[dict]] = {}
    for rep in range(args.repeats):
        for model in args.models:
            order = [("A", args.a), ("B", args.b)]
            for name, src in order if rep % 2 == 0 else order[::-1]:
                r = run_once(src.resolve(), args.song, model)
                runs.setdefault((model, name), []).append(r)
                print(json.dumps({"model": model, "checkout": name, "repeat": rep, **r}), flush=True)
    print("\nmodel        checkout  wall median (runs)           CPU median (runs)            load")
    for (model, name), rs in runs.items():
        w = [r["wall_s"] for r in rs]
        c = [r["cpu_s"] for r in rs]
        ld = [r["load1"] for r in rs]
        print(f"{model:12s} {name:8s}  {statistics.median(w):5.2f} s ({', '.join(f'{x:.2f}' for x in w)})"
              f"   {statistics.median(c):5.2f} s ({', '.join(f'{x:.2f}' for x in c)})"
              f"   {min(ld):.1f}-{max(ld):.1f}")


if __name__ == "__main__":
    main()
