"""Latency, keeping up and endurance of ``dancekit live`` (issue 43), a file fed at the pace of the clock.

    # one run: MODEL danced live for MINUTES of the songs of ../shared/music (one after the other, looped),
    # fed in real time; the per-frame log and the per-minute figures go to OUT (JSON)
    PYTHONPATH=src nice python benchmarks/bench_live.py run --model revolution --minutes 60 --out /tmp/live_rev.json
    # the table of runs → docs/results/live.json
    PYTHONPATH=src python benchmarks/bench_live.py table /tmp/live_rev.json /tmp/live_m2d.json -o docs/results/live.json

Per frame: the arrival of the block that holds its centre and the moment it was sent (the latency), and the
arrival of the block that completed it (the lookahead part: the rest is compute and queueing). Per minute of
audio: the median and 99th percentile latency, the CPU time of the session's thread and its wall time per second
of audio, the resident memory (VmRSS), how many blocks took the lighter path or were fed together with the one
before. The machine's load average is logged every minute (the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import threading
import time
from pathlib import Path

import numpy as np

SONGS = ["Kevin_MacLeod_-_Vibe_Ace.ogg", "brahms_hungarian_dance_5.ogg",
         "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg", "glacier-bay-humpback.ogg",
         "456440__inspectorj__bird-whistling-robin-single-13.ogg"]


def rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def run(args) -> None:
    import torch
    from threadpoolctl import threadpool_limits

    from dancekit.live import LiveConfig
    from dancekit.live.session import LiveSession, file_source

    torch.set_num_threads(1)
    music = Path(args.music)
    songs = [music / s for s in SONGS]
    with threadpool_limits(1):
        session = LiveSession(args.model, config=LiveConfig())
        minutes: list[dict] = []
        cur = {"lat": [], "look": [], "t0": None}
        taking = threading.Lock()  # the sink appends and the monitor takes a minute's frames, never both at once
        frames_log = []

        def sink(frames):
            with taking:
                for f in frames:
                    cur["lat"].append(f.latency)
                    cur["look"].append(f.ready - f.arrival)
            if args.log_frames:
                frames_log.extend((f.index, f.arrival, f.ready, f.sent) for f in frames)

        session.sinks.append(sink)
        session.keep_stats = False
        stop = threading.Event()
        audio_per_minute = 60.0
        mark = {"audio": 0.0, "cpu": 0.0, "wall": 0.0, "light": 0, "merged": 0}

        def monitor():
            while not stop.wait(2.0):
                st = session.stats
                audio = float(np.sum(st.block_audio))
                if audio - mark["audio"] >= audio_per_minute:
                    cpu, wall = float(np.sum(st.cpu)), float(np.sum(st.compute))
                    with taking:
                        lat, look = np.asarray(cur["lat"]), np.asarray(cur["look"])
                        cur["lat"], cur["look"] = [], []
                    minutes.append({
                        "minute": len(minutes) + 1, "frames": int(len(lat)),
                        "latency_median_s": float(np.median(lat)) if len(lat) else None,
                        "latency_p99_s": float(np.quantile(lat, 0.99)) if len(lat) else None,
                        "lookahead_median_s": float(np.median(look)) if len(look) else None,
                        "compute_median_s": float(np.median(lat - look)) if len(lat) else None,
                        "cpu_per_audio_s": (cpu - mark["cpu"]) / (audio - mark["audio"]),
                        "wall_per_audio_s": (wall - mark["wall"]) / (audio - mark["audio"]),
                        "rss_mb": rss_mb(), "load1": os.getloadavg()[0],
                        "light_blocks": st.light_blocks - mark["light"], "merged_blocks": st.merged_blocks - mark["merged"],
                        "latencies": [round(float(x), 4) for x in lat] if args.keep_latencies else None,
                    })
                    mark.update(audio=audio, cpu=cpu, wall=wall, light=st.light_blocks, merged=st.merged_blocks)
                    m = minutes[-1]
                    print(f"[{args.model}] minute {m['minute']}: latency median {m['latency_median_s']:.3f} s "
                          f"p99 {m['latency_p99_s']:.3f} s, cpu {m['cpu_per_audio_s']:.3f} s/s, wall "
                          f"{m['wall_per_audio_s']:.3f} s/s, RSS {m['rss_mb']:.0f} MB, load {m['load1']:.1f}",
                          file=sys.stderr, flush=True)

        mon = threading.Thread(target=monitor, daemon=True)
        mon.start()
        t0 = time.monotonic()
        rss0 = rss_mb()
        session.stats.cpu = []
        source = file_source([str(s) for s in songs], sr=session.sr, block_s=session.config.block_s, realtime=True,
                             loop=True)
        session.run(source, duration_s=args.minutes * 60.0)
        stop.set()
        mon.join()
    out = {"model": args.model, "minutes": args.minutes, "wall_s": time.monotonic() - t0, "rss_start_mb": rss0,
           "config": {k: getattr(session.config, k) for k in ("block_s", "lookahead_s", "model_lookahead_s")},
           "notes": session.notes, "per_minute": minutes, "light_blocks": session.stats.light_blocks,
           "merged_blocks": session.stats.merged_blocks, "machine": machine(), "date": time.strftime("%Y-%m-%d"),
           "command": " ".join(["python", "benchmarks/bench_live.py"] + sys.argv[1:])}
    Path(args.out).write_text(json.dumps(out, indent=1))


def machine() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (shared with other jobs), " \
           f"Python {platform.python_version()}"


def table(args) -> None:
    rows = []
    notes = []
    for path in args.runs:
        r = json.loads(Path(path).read_text())
        pm = r["per_minute"]
        first = [m for m in pm if m["minute"] <= 10]
        last = [m for m in pm if m["minute"] > len(pm) - 10]

        def pooled(ms, key):
            return float(np.median([m[key] for m in ms if m[key] is not None])) if ms else None

        def frames(ms):  # every frame's latency of these minutes (kept with --keep-latencies)
            return np.concatenate([m["latencies"] for m in ms]) if all(m.get("latencies") for m in ms) else None

        lat10 = frames(first)
        if lat10 is not None:
            med10, p99_10 = float(np.median(lat10)), float(np.quantile(lat10, 0.99))
        else:
            med10, p99_10 = pooled(first, "latency_median_s"), max(m["latency_p99_s"] for m in first)
        lat_last = frames(last)
        med_first = med10
        med_last = float(np.median(lat_last)) if lat_last is not None else pooled(last, "latency_median_s")
        rows.append([r["model"], len(pm),
                     round(med10, 3), round(p99_10, 3),
                     round(pooled(first, "lookahead_median_s"), 3), round(pooled(first, "compute_median_s"), 3),
                     round(float(np.mean([m["cpu_per_audio_s"] for m in pm])), 3),
                     round(float(np.mean([m["wall_per_audio_s"] for m in pm])), 3),
                     round(r["rss_start_mb"]), round(max(m["rss_mb"] for m in pm)), round(pm[-1]["rss_mb"]),
                     round(med_last / med_first, 3) if len(pm) >= 20 else None,
                     r["light_blocks"], r["merged_blocks"],
                     round(float(np.mean([m["load1"] for m in pm])), 1)])
        notes.extend(f"{r['model']}: {n}" for n in r["notes"][:3])
    out = {"title": "dancekit live: latency, keeping up and memory, a file fed at the pace of the clock",
           "command": "; ".join(json.loads(Path(p).read_text())["command"] for p in args.runs),
           "machine": json.loads(Path(args.runs[0]).read_text())["machine"],
           "date": json.loads(Path(args.runs[0]).read_text())["date"],
           "columns": ["model", "minutes recorded", "latency median s (first 10 min, every frame)",
                       "latency p99 s (first 10 min, every frame)", "lookahead s (median)", "compute+queue s (median)",
                       "CPU s per s of audio", "wall s per s of audio", "RSS start MB", "RSS max MB", "RSS end MB",
                       "last-10-min / first-10-min median latency", "lighter-path blocks", "merged blocks",
                       "load average (1 min, mean)"],
           "rows": rows,
           "note": "Latency: from the arrival of the audio block holding a frame's centre to the frame being sent "
                   "(lookahead: waiting for the block that completes the frame's 0.08 s feature and 0.08 s model "
                   "lookahead; the rest is compute and queueing). The machine (2 cores) was shared with other jobs "
                   "during the runs: the load average column says how much. " + " ".join(notes)}
    Path(args.output).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--model", default="revolution")
    r.add_argument("--minutes", type=float, default=10.0)
    r.add_argument("--music", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "music"))
    r.add_argument("--out", required=True)
    r.add_argument("--log-frames", action="store_true")
    r.add_argument("--keep-latencies", action="store_true")
    r.set_defaults(func=run)
    t = sub.add_parser("table")
    t.add_argument("runs", nargs="+")
    t.add_argument("-o", "--output", default="docs/results/live.json")
    t.set_defaults(func=table)
    args = ap.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
