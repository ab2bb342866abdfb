"""Cold-process time of ``dancekit dance``: a fresh Python process, an empty feature cache, one song.

    python benchmarks/bench_cold_start.py [--song ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg]
                                          [--model music2dance] [--repeats 5] [--format npz] [--threads N]
                                          [--src OTHER_CHECKOUT/src]

``--model=`` (empty) times the default model; ``--src`` another checkout's sources (e.g. main's, to compare).

Two kinds of fresh process, each with its own empty feature cache (``DANCEKIT_CACHE`` pointed at a new
temporary folder, so neither the music features nor the song's beats are cached):

1. ``--repeats`` runs of the real command, ``dancekit dance SONG --model M --format F --quiet -o TMP``:
   the wall time from spawning the process to its exit (median, min, max), the child's CPU time
   (user + system: the change of ``getrusage(RUSAGE_CHILDREN)`` over the run) and the 1-minute load average before each run (this 2-core machine is
   shared: under load the wall time grows, the CPU time much less);
2. one run of this file's ``--child`` mode, which does what ``dancekit dance`` does step by step and
   times each step: interpreter start-up (spawn to the first line), importing the CLI, loading the model,
   the music features (uncached), the dance (genre reading, generation, the pipeline stages; the
   features now come from the cache the previous step filled) and writing the outputs. It also lists the
   heavy modules the process imported (librosa, numba, scipy.signal, scipy.stats), which a dance should
   not need.

Numba, librosa and torch keep their own caches in site-packages; this script does not clear those (a
fresh install pays their compilation once). Prints a JSON line per run and a summary.
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
HEAVY = ("librosa", "numba", "scipy.signal", "scipy.stats", "scipy.sparse", "scipy.ndimage", "sklearn",
         "matplotlib", "PIL", "imageio")


def _env(cache: str, src: Path) -> dict:
    env = dict(os.environ)
    env["DANCEKIT_CACHE"] = cache
    env["PYTHONPATH"] = str(src) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def _threads_args(args: argparse.Namespace) -> list[str]:
    return [] if args.threads is None else ["--threads", str(args.threads)]


def spawn(cmd: list[str], env: dict) -> tuple[float, float, str]:
    """Run ``cmd``; wall seconds, the child's CPU seconds (user + system) and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout


def cli_runs(args: argparse.Namespace) -> list[dict]:
    runs = []
    for k in range(args.repeats):
        tmp = tempfile.mkdtemp(prefix="dk_cold_")
        try:
            cmd = [sys.executable, "-c", "import sys; from dancekit.cli.main import main; sys.exit(main())",
                   "dance", str(args.song), "--format", args.format, "--quiet", *_threads_args(args),
                   "-o", os.path.join(tmp, "out")]
            if args.model:
                cmd[5:5] = ["--model", args.model]
            load = os.getloadavg()[0]
            wall, cpu, out = spawn(cmd, _env(os.path.join(tmp, "cache"), args.src))
            run = {"kind": "cli", "run": k, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
                   "load1": round(load, 2), "said": out.strip().splitlines()[-1][-160:]}
            print(json.dumps(run), flush=True)
            runs.append(run)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return runs


def child(args: argparse.Namespace) -> None:
    """The steps of ``dancekit dance`` timed one by one (run in a fresh process by :func:`breakdown`)."""
    t_first = time.time()
    phases: dict[str, float] = {"startup": t_first - args.spawned_at}
    cpu = time.process_time()

    def mark(name: str, t0: float) -> float:
        nonlocal cpu
        now = time.perf_counter()
        phases[name] = now - t0
        c = time.process_time()
        phases[name + "_cpu"] = c - cpu
        cpu = c
        return now

    t = time.perf_counter()
    import dancekit.cli.dance  # noqa: F401
    import dancekit.cli.main  # noqa: F401
    from dancekit.export import export_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.render import AudioClip, RenderOptions

    t = mark("import_cli", t)
    pipe = load_pipeline(args.model or None)
    # the thread count the tree's own `dancekit dance` would use (its --threads default, or torch's)
    cli = dancekit.cli.main.build_parser().parse_args(["dance", str(args.song), "-o", "x", *_threads_args(args)])
    if getattr(cli, "threads", None):
        import torch

        torch.set_num_threads(cli.threads)
    t = mark("load_model", t)
    from dancekit.features import extract_file

    fs = extract_file(args.song, fps=pipe.fps, preset=pipe.preset, hop_length=pipe.hop_length)
    assert not fs.from_cache
    t = mark("features", t)
    result = pipe(str(args.song), seed=0)
    t = mark("dance", t)
    export_motion(result.motion, Path(args.out), stem=Path(args.song).stem, formats=[args.format],
                  audio=AudioClip(Path(args.song), None, None), options=RenderOptions(), progress=False)
    mark("export", t)
    phases["heavy_modules"] = sorted(m for m in HEAVY if m in sys.modules)
    phases["frames"] = int(result.motion.num_frames)
    print(json.dumps(phases))


def breakdown(args: argparse.Namespace) -> dict:
    tmp = tempfile.mkdtemp(prefix="dk_cold_")
    try:
        cmd = [sys.executable, __file__, "--child", "--song", str(args.song), "--format", args.format,
               *_threads_args(args),
               "--out", os.path.join(tmp, "out"), "--spawned-at", repr(time.time())]
        if args.model:
            cmd += ["--model", args.model]
        load = os.getloadavg()[0]
        wall, _, out = spawn(cmd, _env(os.path.join(tmp, "cache"), args.src))
        phases = json.loads(out.strip().splitlines()[-1])
        phases = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in phases.items()}
        phases.update(kind="breakdown", wall_s=round(wall, 3), load1=round(load, 2))
        print(json.dumps(phases), flush=True)
        return phases
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--song", type=Path, default=DEFAULT_SONG)
    ap.add_argument("--model", default="music2dance", help="model name ('' for the default model)")
    ap.add_argument("--format", default="npz")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None, help="dancekit dance --threads N (default: not given)")
    ap.add_argument("--src", type=Path, default=ROOT / "src",
                    help="the dancekit source tree to time (default: this checkout's; another to compare)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--spawned-at", type=float, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args)
        return
    runs = cli_runs(args)
    phases = breakdown(args)
    walls = [r["wall_s"] for r in runs]
    cpus = [r["cpu_s"] for r in runs]
    print(f"dancekit dance {args.song.name} --model {args.model or '(default)'} --format {args.format} "
          f"{' '.join(_threads_args(args))} ({args.src}), fresh "
          f"process, empty feature cache, {len(runs)} runs: wall median {statistics.median(walls):.2f} s "
          f"(min {min(walls):.2f}, max {max(walls):.2f}); CPU median {statistics.median(cpus):.2f} s; "
          f"load average {min(r['load1'] for r in runs):.1f}-{max(r['load1'] for r in runs):.1f}")
    steps = ("startup", "import_cli", "load_model", "features", "dance", "export")
    print("breakdown (wall s / CPU s): " + ", ".join(
        f"{s} {phases[s]:.2f}" + (f"/{phases[s + '_cpu']:.2f}" if s + "_cpu" in phases else "") for s in steps)
        + f"; heavy modules imported: {', '.join(phases['heavy_modules']) or 'none'}")


if __name__ == "__main__":
    main()
