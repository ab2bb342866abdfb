"""`dancekit serve`: from the upload of a 60-s song to a playing dance, beside the CLI in the same run.

    python benchmarks/bench_serve.py [--song SONG] [--repeats 5] [--out docs/results/serve.json]

A server (``dancekit serve --workers 1``; the runs start once its worker has loaded the default model and warmed
up, ``workers_ready`` in ``/api/options``) runs on 127.0.0.1. Each repeat uploads a
60-s excerpt of ``--song`` (each repeat another excerpt, a fresh feature cache for server and CLI alike, so no
run reads the features another computed) through the HTTP API with the dance page's defaults (model revolution,
genre auto, seed 0; formats html and npz: the player is written first whatever the formats, so the time to it is
the page's) and times, from the start of the upload, **playable**: the status lists the html player (the page
then shows and plays the dance). Beside it, on the same excerpt, ``dancekit dance EXCERPT --format html`` (its
time to a playable file from the process start: imports and model load included, as a user who types it pays
them). Both as wall time and as CPU seconds (the worker's, from /proc; the CLI's and its children's): on a
shared machine the wall time grows with the load, the CPU time much less. Medians of ``--repeats`` runs; the
1-minute load average is recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
DEFAULT_SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def cpu_seconds(pids: list[int]) -> float:
    """User + system CPU seconds of ``pids`` so far (Linux /proc)."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / tick
    return total


def excerpt(song: Path, start: float, out: Path) -> Path:
    from dancekit.render._ffmpeg import ffmpeg_exe

    subprocess.run([ffmpeg_exe(), "-v", "error", "-y", "-ss", f"{start:.3f}", "-t", "60", "-i", str(song),
                    "-c:a", "libvorbis", "-q:a", "4", str(out)], check=True)
    return out


def machine() -> str:
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor())
    return f"{cpu}, {os.cpu_count()} cores (shared), Python {platform.python_version()}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--song", default=str(DEFAULT_SONG))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default=str(ROOT / "docs" / "results" / "serve.json"))
    args = parser.parse_args()
    import httpx
    from _serve import Server

    src = str(ROOT / "src")
    rows, loads = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = {**os.environ, "PYTHONPATH": src + os.pathsep + os.environ.get("PYTHONPATH", ""),
               "DANCEKIT_CACHE": str(tmp / "features-server")}
        old = dict(os.environ)
        os.environ.update(env)  # the server subprocess inherits it
        srv = Server(tmp / "cache", "--workers", "1")
        os.environ.clear()
        os.environ.update(old)
        try:
            with httpx.Client(base_url=srv.url, timeout=60) as c:
                while c.get("/api/options").json()["workers_ready"] < 1:  # the worker has loaded and warmed up
                    time.sleep(0.2)
                for k in range(args.repeats):
                    song = excerpt(Path(args.song), 0.25 * k, tmp / f"song{k}.ogg")
                    cpu0, wall0 = cpu_seconds(srv.pids()), time.time()
                    r = c.post("/api/jobs/dance", files={"file": (song.name, song.read_bytes(), "audio/ogg")},
                               data={"formats": "html,npz"})
                    r.raise_for_status()
                    job, playable, cpu = r.json()["id"], None, None
                    while True:
                        s = c.get(f"/api/jobs/{job}").json()
                        if cpu is None and s["playable"]:
                            cpu = cpu_seconds(srv.pids()) - cpu0
                        if s["state"] in ("done", "failed", "cancelled"):
                            break
                        time.sleep(0.02)
                    assert s["state"] == "done", s
                    playable = s["playable_at"] - wall0  # the server's clock: the same machine's
                    if cpu is None:  # the job ended between two polls: its CPU to the end (npz included)
                        cpu = cpu_seconds(srv.pids()) - cpu0
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    t1 = time.perf_counter()
                    subprocess.run([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o",
                                    str(tmp / f"cli{k}"), "--format", "html", "--quiet"], check=True,
                                   env={**env, "DANCEKIT_CACHE": str(tmp / f"features-cli{k}")},
                                   stdout=subprocess.DEVNULL)
                    cli = time.perf_counter() - t1
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cli_cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                    loads.append(os.getloadavg()[0])
                    rows.append([k, round(playable, 2), round(cpu, 2), round(cli, 2), round(cli_cpu, 2),
                                 round(loads[-1], 1)])
                    print(f"run {k}: serve playable {playable:.2f} s ({cpu:.2f} CPU s); CLI html {cli:.2f} s "
                          f"({cli_cpu:.2f} CPU s); load {loads[-1]:.1f}", flush=True)
        finally:
            srv.stop()
    med = [round(statistics.median(r[i] for r in rows), 2) for i in range(1, 6)]
    rows.append(["median", *med])
    result = {
        "title": "dancekit serve: upload of a 60-s song to a playing dance, and the CLI beside it",
        "command": "python benchmarks/bench_serve.py --repeats " + str(args.repeats),
        "machine": machine(),
        "date": date.today().isoformat(),
        "columns": ["run", "serve: upload to playable, wall (s)", "serve: worker CPU to playable (s)",
                    "CLI: dance --format html, wall (s)", "CLI: CPU incl. children (s)", "load average (1 min)"],
        "rows": rows,
        "note": f"60-s excerpts of {Path(args.song).name} (another 0.25 s offset per run; fresh feature caches), "
                f"model revolution, genre auto, seed 0, formats html and npz (the player is written first), one worker with 1 torch thread. 'playable' is when the job "
                f"status lists the html player (the page then shows it); the CLI times include its process start, "
                f"imports and model load, which the server pays once. 1-minute load average during the runs: "
                f"{min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores shared with other work.",
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"median: serve playable {med[0]} s ({med[1]} CPU s); CLI html {med[2]} s ({med[3]} CPU s) → {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
