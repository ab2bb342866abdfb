"""`compose` speed and memory: 60 s of dance → MIDI + WAV with a dual model's G_D→M.

    python benchmarks/bench_compose.py [--model dual | --checkpoint DIR] [--data data/tang2018]
                                       [--dance DANCE_W_1] [--seconds 60] [--render builtin] [--repeats 2]

The first ``--seconds`` of a tang2018 dance (default: the first test dance of the prepared dataset) are composed
in a fresh child process: model load, composition (G_D→M's chroma + beats and the arrangement) and writing
(the MIDI and the WAV rendered with ``--render``) are timed separately over ``--repeats`` runs (the first run also
pays librosa / numba imports; the best is reported; process CPU times and the 1-minute load average are printed
beside the wall times, as the machine is shared), and the child's peak resident memory (``ru_maxrss``) is
printed with its resident memory before the model was loaded. Threads: ``torch.set_num_threads(--threads)``.

``--cold N``: instead, the acceptance measure of issue 41: ``dancekit compose DANCE.npz -o OUT --no-video
--render builtin`` of the first ``--seconds`` of the dance, run ``N`` times as a fresh process each (imports,
model load, G_D→M, the arrangement, MIDI + WAV); prints each run's wall time and CPU time (user + system of the
child) and their medians; ``--json PATH`` writes the figures in the docs/results shape.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _rss_mib() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def dance_excerpt(args: argparse.Namespace):
    """``(name, motion)``: the first ``args.seconds`` of ``args.dance`` (default: the first test dance) of the
    prepared dataset ``args.data``."""
    from dancekit.data import PreparedData

    data = PreparedData(args.data)
    name = args.dance or data.names("test")[0]
    motion = data.motion(name)
    n = int(round(args.seconds * motion.fps))
    if motion.num_frames < n:
        raise SystemExit(f"{name} has only {motion.num_frames / motion.fps:.1f} s of dance")
    return name, motion.slice(0, n)


def child(args: argparse.Namespace) -> dict:
    import torch

    torch.set_num_threads(args.threads)
    from dancekit.pipelines.dual import ComposePipeline

    name, motion = dance_excerpt(args)
    n = motion.num_frames
    rss_before = _rss_mib()
    t0 = time.perf_counter()
    pipe = ComposePipeline.from_pretrained(args.checkpoint or args.model)
    load_s = time.perf_counter() - t0
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            piece = pipe(motion, seed=k)
            t1, c1 = time.perf_counter(), time.process_time()
            files = piece.write(tmp, stem=f"run{k}", render=args.render)
            t2, c2 = time.perf_counter(), time.process_time()
            runs.append({"compose_s": t1 - t0, "write_s": t2 - t1, "total_s": t2 - t0, "compose_cpu_s": c1 - c0,
                         "write_cpu_s": c2 - c1, "load_avg": os.getloadavg()[0],
                         "beats": len(piece.arrangement.beat_times), "tempo_bpm": piece.arrangement.tempo,
                         "wav_bytes": files["wav"].stat().st_size, "mid_bytes": files["midi"].stat().st_size})
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"dance": name, "seconds": n / motion.fps, "model": str(pipe.folder), "load_s": load_s,
            "runs": runs, "rss_before_model_mib": rss_before, "peak_rss_mib": peak, "threads": args.threads,
            "render": args.render}


def cold(args: argparse.Namespace) -> int:
    import datetime
    import platform
    import statistics

    from dancekit.motion import write_motion

    name, excerpt = dance_excerpt(args)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        dance = Path(tmp) / f"{name}.npz"
        write_motion(dance, excerpt)
        cmd = [sys.executable, "-m", "dancekit.cli.main", "compose", str(dance), "-o", str(Path(tmp) / "out"),
               "--no-video", "--render", "builtin", "--quiet", "--model", args.model]
        for k in range(args.cold):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True)
            wall = time.perf_counter() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            rows.append([k, round(wall, 2), round(cpu, 2), round(os.getloadavg()[0], 1)])
            print(f"run {k}: wall {wall:.2f} s, CPU {cpu:.2f} s, load average {os.getloadavg()[0]:.1f}", flush=True)
    med_wall = statistics.median(r[1] for r in rows)
    med_cpu = statistics.median(r[2] for r in rows)
    print(f"median of {len(rows)} cold runs for {args.seconds:g} s of {name}: wall {med_wall:.2f} s, "
          f"CPU {med_cpu:.2f} s")
    if args.json:
        from dancekit._io import atomic_path

        out = {"title": f"dancekit compose: {args.seconds:g} s of dance -> MIDI + WAV, cold process",
               "command": "python " + " ".join([Path(__file__).relative_to(ROOT).as_posix()] + sys.argv[1:]),
               "machine": f"{platform.machine()}, {os.cpu_count()} CPUs (shared: see the load average column)",
               "date": datetime.date.today().isoformat(),
               "columns": ["run", "wall (s)", "CPU user + system (s)", "1-min load average"],
               "rows": rows + [["median", med_wall, med_cpu, None]],
               "note": f"{name}, first {args.seconds:g} s; `dancekit compose DANCE.npz -o OUT --no-video --render "
                       f"builtin --model {args.model}` as a fresh process per run (imports, model load, G_D→M, "
                       "arrangement, MIDI and WAV). The machine is shared with other jobs: the wall time rises "
                       "with the load average; the CPU time is what the command itself costs."}
        with atomic_path(Path(args.json)) as tmp_path:
            Path(tmp_path).write_text(json.dumps(out, indent=1) + "\n")
    return 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="dual", help="a dual model name or folder (default: dual)")
    p.add_argument("--checkpoint", default=None, help="a dual checkpoint folder (overrides --model)")
    p.add_argument("--data", default=str(ROOT / "data" / "tang2018"), help="prepared tang2018 folder")
    p.add_argument("--dance", default=None, help="dance name (default: the first test dance)")
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--render", default="builtin", choices=("builtin", "fluidsynth", "auto"))
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--cold", type=int, default=0, metavar="N",
                   help="time N cold `dancekit compose` processes instead (median; the acceptance measure)")
    p.add_argument("--json", default=None, help="with --cold: write the figures to this JSON file")
    p.add_argument("--_child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.cold:
        return cold(args)
    if args._child:
        print(json.dumps(child(args)))
        return 0
    cmd = [sys.executable, __file__, "--_child"] + sys.argv[1:]
    res = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
    best = min(res["runs"], key=lambda r: r["total_s"])
    print(f"dance {res['dance']} ({res['seconds']:.0f} s), model {res['model']}, render {res['render']}, "
          f"{res['threads']} thread(s)")
    print("| run | compose (s) | MIDI + WAV (s) | total (s) | CPU compose / write (s) | load avg | beats | tempo (BPM) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for k, r in enumerate(res["runs"]):
        print(f"| {k} | {r['compose_s']:.2f} | {r['write_s']:.2f} | {r['total_s']:.2f} | "
              f"{r['compose_cpu_s']:.2f} / {r['write_cpu_s']:.2f} | {r['load_avg']:.1f} | {r['beats']} | "
              f"{r['tempo_bpm']:.1f} |")
    print(f"model load {res['load_s']:.2f} s; best total {best['total_s']:.2f} s for {res['seconds']:.0f} s of dance; "
          f"peak RSS {res['peak_rss_mib']:.0f} MiB ({res['rss_before_model_mib']:.0f} MiB before the model was loaded)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
