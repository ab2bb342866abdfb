"""Peak resident memory of ``dancekit dance`` on long songs (issue 18's target: <= 1 GB at 20 and 60 minutes).

    PYTHONPATH=src python benchmarks/bench_memory.py [--minutes 20 60] [--format mp4,html,npz,bvh] [--song PATH]

For each ``--minutes`` the song is the real recordings of ../shared/music (Sugar Plum Fairy, Vibe Ace,
Brahms' Hungarian dance no. 5, 5.6 minutes together) concatenated over and over up to that length and
written as a 44.1-kHz stereo 128-kbit/s mp3 by the bundled ffmpeg (what a user's long mix looks like),
unless ``--song`` is given. ``dancekit dance`` then runs in a child process with a fresh feature cache and
the default model; its peak resident set size is read from ``/usr/bin/time -f %M`` (the child's
``ru_maxrss``), printed in a table with the wall time and the 1-minute load average at the start (the
machine may be shared: load slows the run but does not change resident memory). ``--profile`` also runs the generation step alone in-process under ``tracemalloc`` and prints
the ten largest allocation sites at the peak (Python allocations only: NumPy and torch buffers are counted,
librosa/numba/ffmpeg's C buffers are not).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUSIC = ROOT.parent / "shared" / "music"
SONGS = ["Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg", "Kevin_MacLeod_-_Vibe_Ace.ogg",
         "brahms_hungarian_dance_5.ogg"]


def make_song(dst: Path, minutes: float) -> Path:
    from dancekit.render._ffmpeg import ffmpeg_exe

    loops = int(minutes / 5) + 2  # the three songs last 5.6 minutes together
    listing = dst.parent / f"{dst.stem}.txt"
    listing.write_text("".join(f"file '{MUSIC / name}'\n" for _ in range(loops) for name in SONGS))
    subprocess.run([ffmpeg_exe(), "-nostdin", "-v", "error", "-y", "-f", "concat", "-safe", "0", "-i", str(listing),
                    "-vn", "-t", str(minutes * 60), "-ar", "44100", "-ac", "2", "-c:a", "libmp3lame", "-b:a", "128k",
                    str(dst)], check=True)
    return dst


def profile(song: Path) -> None:
    import tracemalloc

    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline()
    tracemalloc.start(5)
    pipe(str(song), seed=0)
    _, peak = tracemalloc.get_traced_memory()
    snap = tracemalloc.take_snapshot()
    tracemalloc.stop()
    print(f"tracemalloc peak during generation: {peak / 2**20:.0f} MiB (Python-visible allocations)")
    for stat in snap.statistics("lineno")[:10]:
        print(f"  {stat.size / 2**20:8.1f} MiB still held  {stat.traceback[0]}")


def stages(song: Path, formats: str, out: Path) -> None:
    """``dancekit dance``'s steps one by one in this process (default model, all stages), printing the peak
    resident memory after each (``ru_maxrss``: a step that does not raise it stayed below the earlier peak)."""
    from dancekit.export import check_formats, export_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.render import AudioClip

    def peak(what: str, t0: float) -> None:
        print(f"  {what:34s} peak RSS so far {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} GiB "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)

    t0 = time.perf_counter()
    pipe = load_pipeline()
    peak("imports + model", t0)
    from dancekit.features import extract_file

    for preset in (pipe.preset, "music2dance"):
        t0 = time.perf_counter()
        extract_file(song, fps=pipe.fps, preset=preset, hop_length=pipe.hop_length)
        peak(f"features ({preset})", t0)
    from dancekit.pipelines.stages import song_beats_for

    t0 = time.perf_counter()
    song_beats_for(song)
    peak("song beats (fine grid)", t0)
    t0 = time.perf_counter()
    result = pipe(str(song), seed=0)
    peak("dance (cached features; generation, stages)", t0)
    for fmt in check_formats(formats):
        t0 = time.perf_counter()
        export_motion(result.motion, out, stem=f"{song.stem}", formats=[fmt], audio=AudioClip(song), progress=False)
        peak(f"export {fmt}", t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[20.0, 60.0])
    ap.add_argument("--format", default="mp4,html,npz,bvh")
    ap.add_argument("--song", default=None)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--stages", action="store_true",
                    help="instead: run the steps one by one in this process, the peak after each")
    args = ap.parse_args()
    if args.stages:
        with tempfile.TemporaryDirectory(prefix="dk-mem-") as tmp:
            tmp = Path(tmp)
            os.environ["DANCEKIT_CACHE"] = str(tmp / "cache")
            for minutes in ([None] if args.song else args.minutes):
                song = Path(args.song) if args.song else make_song(tmp / f"long{minutes:g}.mp3", minutes)
                print(f"{song.name}, --format {args.format}:", flush=True)
                stages(song, args.format, tmp / "out")
        return 0
    rows = []
    with tempfile.TemporaryDirectory(prefix="dk-mem-") as tmp:
        tmp = Path(tmp)
        for minutes in ([None] if args.song else args.minutes):
            song = Path(args.song) if args.song else make_song(tmp / f"long{minutes:g}.mp3", minutes)
            env = {**os.environ, "DANCEKIT_CACHE": str(tmp / f"cache{minutes}"), "PYTHONPATH": str(ROOT / "src")}
            load = os.getloadavg()[0]
            t0 = time.perf_counter()
            r = subprocess.run(["/usr/bin/time", "-f", "%M", sys.executable, "-m", "dancekit.cli.main", "dance",
                                str(song), "-o", str(tmp / f"out{minutes}"), "--format", args.format, "--quiet"],
                               env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            kib = int(r.stderr.strip().splitlines()[-1])  # /usr/bin/time's %M: peak RSS in KiB
            print(r.stdout.strip() or r.stderr.strip(), flush=True)
            label = song.name if args.song else f"{minutes:g} min"
            rows.append((label, kib * 1024, wall, r.returncode, load))
            shutil.rmtree(tmp / f"out{minutes}", ignore_errors=True)
            if args.profile:
                os.environ["DANCEKIT_CACHE"] = str(tmp / "cache-profile")
                profile(song)
    print("| song | --format | peak RSS | wall | exit | load average at start |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for label, peak, wall, code, load in rows:
        print(f"| {label} | {args.format} | {peak / 2**30:.2f} GiB ({peak / 1e9:.2f} GB) | {wall:.0f} s | {code} | "
              f"{load:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
