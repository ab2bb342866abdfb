"""Speed of ``render_mp4``: a 60 s dance at 25 fps, 640x480, with its song.

Target: at most 10 s of rendering per minute of music on the 2-core CI machine.
Uses the first 60 s of tang2018 DANCE_T_5 (100 s long) when ``../shared`` is beside the repository,
otherwise a synthetic stick figure and a synthetic tone. Run by hand::

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_render.py [--seconds 60] [--figure body] [--html] [--repeats 3]

Each run prints its wall time, the CPU time of the Python process and of its ffmpeg children (user + sys:
comparable on a shared machine, where wall time is not) and the 1-minute load average when it started.
The exit status says whether the best run met the target.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dancekit.render import AudioClip, RenderOptions, render_html, render_mp4
from dancekit.render._ffmpeg import ffmpeg_exe

ROOT = Path(__file__).resolve().parents[1]
DANCE = ROOT.parent / "shared" / "data" / "tang2018" / "DANCE_T_5"
TARGET_S_PER_MIN = 10.0

# tang2018 drawing tree (pelvis root) for the raw arrays; the library's Skeleton is not needed
_PARENTS = np.array([2, 0, -1, 2, 3, 4, 5, 2, 7, 8, 9, 10, 2, 12, 13, 14, 2, 16, 17, 18, 19, 15, 6])
_SIDES = np.array([0, 0, 0] + [-1] * 9 + [1] * 10 + [-1])


def _synthetic(seconds: float, fps: float, tmp: Path) -> tuple[np.ndarray, Path]:
    import subprocess

    t = np.arange(int(seconds * fps)) / fps
    rng = np.random.default_rng(0)
    base = rng.normal(size=(23, 3)) * 20 + [0, 100, 0]
    base[[9, 10, 11, 18, 19, 20], 1] = 8
    pos = base[None] + 10 * np.sin(2 * np.pi * 0.5 * t)[:, None, None]
    pos[:, :, 0] += 100 * np.sin(2 * np.pi * 0.05 * t)[:, None]
    song = tmp / "tone.wav"
    subprocess.run(
        [
            ffmpeg_exe(),
            "-v",
            "error",
            "-f",
            "lavfi",
            "-i",
            f"sine=frequency=440:duration={seconds}",
            str(song),
        ],
        check=True,
    )
    return pos.astype(np.float32), song


def _cpu() -> tuple[float, float]:
    """CPU seconds (user + sys) used so far by this process and by its waited-for children (ffmpeg)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--figure", choices=("stick", "body"), default="stick",
                    help="stick figure (default) or the volumetric body")
    ap.add_argument("--html", action="store_true", help="also time render_html")
    ap.add_argument("--repeats", type=int, default=1, help="render this many times (the best run is judged)")
    args = ap.parse_args()
    fps = 25.0
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if (DANCE / "skeletons.json").is_file():
            raw = json.loads((DANCE / "skeletons.json").read_text())
            pos = np.asarray(raw["skeletons"], np.float32) + np.asarray(raw["center"], np.float32)[:, None]
            pos = pos[: int(args.seconds * fps)]
            start = json.loads((DANCE / "config.json").read_text())["start_position"] / fps
            song, source = DANCE / "audio.mp3", f"tang2018 {DANCE.name}"
        else:
            pos, song = _synthetic(args.seconds, fps, tmp)
            start = 0.0
            source = "synthetic"
        seconds = pos.shape[0] / fps
        out = tmp / "bench.mp4"
        best = float("inf")
        for _ in range(max(1, args.repeats)):
            load = os.getloadavg()[0]
            cpu0 = _cpu()
            t0 = time.perf_counter()
            render_mp4(
                out,
                pos,
                parents=_PARENTS,
                fps=fps,
                sides=_SIDES,
                head=0,
                audio=AudioClip(song, start=start),
                options=RenderOptions(width=args.width, height=args.height, figure=args.figure),
                progress=False,
            )
            took = time.perf_counter() - t0
            py, ff = (b - a for a, b in zip(cpu0, _cpu(), strict=True))
            per_min = took / seconds * 60
            best = min(best, per_min)
            print(
                f"render_mp4 {source}, {args.figure} figure: {seconds:.1f} s of dance at {fps:g} fps, "
                f"{args.width}x{args.height}: {took:.2f} s ({per_min:.2f} s per minute of music; target <= "
                f"{TARGET_S_PER_MIN:g}); CPU python {py:.2f} s + ffmpeg {ff:.2f} s; load {load:.2f} at start; "
                f"{out.stat().st_size / 1e6:.1f} MB"
            )
        if args.html:
            t0 = time.perf_counter()
            render_html(
                tmp / "bench.html",
                pos,
                parents=_PARENTS,
                fps=fps,
                sides=_SIDES,
                head=0,
                audio=AudioClip(song, start=start),
            )
            print(
                f"render_html: {time.perf_counter() - t0:.2f} s, {(tmp / 'bench.html').stat().st_size / 1e6:.1f} MB"
            )
    return 0 if best <= TARGET_S_PER_MIN else 1


if __name__ == "__main__":
    sys.exit(main())
