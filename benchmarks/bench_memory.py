"""Peak resident memory of ``dancekit dance`` on a 20-minute song (target < 2 GB).

    PYTHONPATH=src python benchmarks/bench_memory.py [--minutes 20] [--format mp4,html,npz,bvh] [--song PATH]

The song is a real recording of ../shared/music (Vibe Ace, 61 s) looped to ``--minutes`` and written as a
44.1-kHz stereo 128-kbit/s mp3 by the bundled ffmpeg (what a user's long mix looks like), unless ``--song``
is given. ``dancekit dance`` then runs in a child process with a fresh feature cache and the default model;
its peak resident set size is the child's ``ru_maxrss`` (``getrusage(RUSAGE_CHILDREN)``), printed with the
wall time. ``--profile`` also runs the generation step alone in-process under ``tracemalloc`` and prints
the ten largest allocation sites at the peak (Python allocations only: NumPy and torch buffers are counted,
librosa/numba/ffmpeg's C buffers are not).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def make_song(dst: Path, minutes: float) -> Path:
    from dancekit.render._ffmpeg import ffmpeg_exe

    loops = int(minutes * 60 / 60) + 2
    listing = dst.parent / "loop.txt"
    listing.write_text("".join(f"file '{SONG}'\n" for _ in range(loops)))
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--format", default="mp4,html,npz,bvh")
    ap.add_argument("--song", default=None)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="dk-mem-") as tmp:
        tmp = Path(tmp)
        song = Path(args.song) if args.song else make_song(tmp / "long.mp3", args.minutes)
        env = {**os.environ, "DANCEKIT_CACHE": str(tmp / "cache"), "PYTHONPATH": str(ROOT / "src")}
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o", str(tmp / "out"),
                            "--format", args.format, "--quiet"], env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20  # KiB -> GiB
        print(r.stdout.strip() or r.stderr.strip())
        print(f"{args.minutes:g}-minute song, --format {args.format}: peak RSS {peak:.2f} GiB "
              f"({peak * 2**30 / 1e9:.2f} GB), wall {wall:.0f} s, exit {r.returncode}")
        if args.profile:
            os.environ["DANCEKIT_CACHE"] = str(tmp / "cache2")
            profile(song)
    return 0


if __name__ == "__main__":
    sys.exit(main())
