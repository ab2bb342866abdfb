"""The speed targets of issue 45, each a cold process (median of ``--repeats``), written to
``docs/results/doors_speed.json``:

    python benchmarks/bench_doors.py [--song ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg] [--seconds 60]
                                     [--repeats 5] [--only dance,seeds,render,tools] [--out docs/results/doors_speed.json]

- ``dance``: ``dancekit dance SONG60 --format npz --quiet`` (target ≤ 4 s), the feature cache warm (one untimed run
  first fills a cache folder that every timed run shares, ``DANCEKIT_CACHE``);
- ``seeds``: the same with ``--seeds 0-7`` (target ≤ 2 x one seed);
- ``render``: ``dancekit render DANCE.npz --audio SONG60 -o x.mp4 -q`` with ``--figure stick`` and ``body``, in
  seconds per minute of music (targets ≤ 6 s and ≤ 10 s);
- ``tools``: ``info`` of a BVH, ``models``, ``convert`` of a glb to BVH (target ≤ 1 s each).

SONG60 is the first ``--seconds`` of the song (cut once with the bundled ffmpeg, audio only). Each row gives the wall
time (median, min, max), the child's CPU time (user + system of the process and its children, median: this 2-core
machine is shared, and the CPU time is much less sensitive to the load than the wall time) and the 1-minute load
average before the runs.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_cold_start import spawn  # benchmarks/ is on the path when run as a script

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def _spawn(argv: list[str], env: dict) -> tuple[float, float]:
    """Run ``dancekit ARGV`` in a fresh interpreter (:func:`bench_cold_start.spawn`): wall seconds and CPU seconds
    (user + system, children included)."""
    wall, cpu, _ = spawn([sys.executable, "-m", "dancekit.cli.main", *argv], env)
    return wall, cpu


def _timed(name: str, argv: list[str], env: dict, repeats: int, per_minute: float | None = None) -> dict:
    load = os.getloadavg()[0]
    walls, cpus = [], []
    for _ in range(repeats):
        w, c = _spawn(argv, env)
        walls.append(w)
        cpus.append(c)
    scale = 1.0 if per_minute is None else 60.0 / per_minute
    row = {"case": name, "wall_median_s": round(statistics.median(walls) * scale, 2),
           "wall_min_s": round(min(walls) * scale, 2), "wall_max_s": round(max(walls) * scale, 2),
           "cpu_median_s": round(statistics.median(cpus) * scale, 2), "load1_before": round(load, 1),
           "per_minute_of_music": per_minute is not None}
    print(json.dumps(row), flush=True)
    return row


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--song", type=Path, default=DEFAULT_SONG)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", default="dance,seeds,render,tools")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "doors_speed.json")
    args = ap.parse_args()
    only = set(args.only.split(","))
    work = Path(tempfile.mkdtemp(prefix="dk_doors_"))
    env = dict(os.environ, DANCEKIT_CACHE=str(work / "cache"),
               PYTHONPATH=str(ROOT / "src") + (os.pathsep + os.environ["PYTHONPATH"] if os.environ.get("PYTHONPATH") else ""))
    # bytecode written (by the untimed run) and reused, as for a user's install; a shell that sets
    # PYTHONDONTWRITEBYTECODE would otherwise compile dancekit's modules in every timed run (about 0.3 s)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    try:
        import imageio_ffmpeg

        song = work / f"song{args.seconds:g}.ogg"
        subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-v", "error", "-i", str(args.song), "-vn",
                        "-t", f"{args.seconds:g}", str(song)], check=True)
        _spawn(["dance", str(song), "--format", "npz,bvh,glb", "--quiet", "-o", str(work / "d")], env)  # warms the cache
        dance = work / "d" / f"{song.stem}.npz"
        rows = []
        if "dance" in only:
            rows.append(_timed("dance 60-s song to npz", ["dance", str(song), "--format", "npz", "--quiet", "-o",
                                                             str(work / "o1")], env, args.repeats))
        if "seeds" in only:
            rows.append(_timed("dance --seeds 0-7 to npz", ["dance", str(song), "--format", "npz", "--seeds", "0-7",
                                                             "--quiet", "-o", str(work / "o8")], env, args.repeats))
        if "render" in only:
            for figure in ("stick", "body"):
                rows.append(_timed(f"render mp4, {figure} figure (per minute of music)",
                                   ["render", str(dance), "--audio", str(song), "--figure", figure, "-q", "-o",
                                    str(work / f"{figure}.mp4")], env, args.repeats, per_minute=args.seconds))
        if "tools" in only:
            rows.append(_timed("info BVH", ["info", str(work / "d" / f"{song.stem}.bvh")], env, args.repeats))
            rows.append(_timed("models", ["models"], env, args.repeats))
            rows.append(_timed("convert glb to BVH", ["convert", str(work / "d" / f"{song.stem}.glb"), "-o",
                                                       str(work / "c.bvh"), "-q"], env, args.repeats))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    cols = ["case", "wall_median_s", "wall_min_s", "wall_max_s", "cpu_median_s", "load1_before", "per_minute_of_music"]
    result = {
        "title": "Issue 45 speed targets: dance, seeds, mp4 render, info/models/convert (cold process, warm features)",
        "command": "python benchmarks/bench_doors.py --song ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg "
                   f"--seconds {args.seconds:g} --repeats {args.repeats}" + (f" --only {args.only}" if only != {
                       "dance", "seeds", "render", "tools"} else ""),
        "machine": f"{_cpu_model()}, {os.cpu_count()} cores (shared with other jobs: see "
                   f"load1_before), Python {platform.python_version()}",
        "date": datetime.date.today().isoformat(),
        "columns": cols,
        "rows": [[r[c] for c in cols] for r in rows],
        "note": "median of the runs, each a fresh process; wall and CPU (user + system, children included) seconds; "
                "render rows are per minute of music. The feature cache is warm and the bytecode written (by one untimed "
                "run). "
                "Targets (issue 45): dance ≤ 4 s, seeds 0-7 ≤ 2 x one seed, stick ≤ 6 s and body ≤ 10 s per minute, "
                "tools ≤ 1 s. Under load the wall time grows with the load average; the CPU time is the figure to "
                "compare between runs.",
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=1, ensure_ascii=False) + "\n")
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
