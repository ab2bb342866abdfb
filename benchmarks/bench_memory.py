"""Peak resident memory of ``dancekit dance`` on long songs (issue 18's target: <= 1 GB at 20 and 60 minutes).

    PYTHONPATH=src python benchmarks/bench_memory.py [--minutes 20 60] [--format mp4,html,npz,bvh] [--song PATH]

For each ``--minutes`` the song is the real recordings of ../shared/music (Sugar Plum Fairy, Vibe Ace,
Brahms' Hungarian dance no. 5, 3.8 minutes together) concatenated over and over up to that length and
written as a 44.1-kHz stereo 128-kbit/s mp3 by the bundled ffmpeg (what a user's long mix looks like),
unless ``--song`` is given. ``dancekit dance`` then runs in a child process with a fresh feature cache and
the default model; its peak resident set size is read from ``/usr/bin/time -f %M`` (the child's
``ru_maxrss``), printed in a table with the wall time and the 1-minute load average at the start (the
machine may be shared: load slows the run but does not change resident memory). ``--profile`` also runs the generation step alone in-process under ``tracemalloc`` and prints
the ten largest allocation sites at the peak (Python allocations only: NumPy and torch buffers are counted,
librosa/numba/ffmpeg's C buffers are not).

``--trace`` runs ``dancekit dance`` (every format) in a child process whose resident memory (``VmRSS`` of
/proc/self/status) a thread samples every 0.1 s, with the step running at each sample (features per preset,
genre reading, generation, song beats, each pipeline stage, each export format: the functions are wrapped,
not changed), and prints the peak of each step; ``--plot FILE.png`` draws RSS over time for every song.

``--post-frames N`` (e.g. 90000: 60 minutes at 25 fps) measures only what comes after the generation, fast:
the default model's dance of Vibe Ace tiled to N frames (each copy moved on by the dance's travel) with Vibe
Ace's beats tiled alike, then the stages (clean-up, smoothing, foot lock, beat sync) and the exports of
``--format`` (mp4 left out unless named), in this process, with the peak RSS of each step.
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
    """The songs of ../shared/music looped to ``minutes`` (checked: the file written lasts at least that long)."""
    import soundfile

    from dancekit.render._ffmpeg import ffmpeg_exe

    together = sum(soundfile.info(str(MUSIC / name)).duration for name in SONGS)  # 227 s
    loops = int(minutes * 60 / together) + 1
    listing = dst.parent / f"{dst.stem}.txt"
    listing.write_text("".join(f"file '{MUSIC / name}'\n" for _ in range(loops) for name in SONGS))
    subprocess.run([ffmpeg_exe(), "-nostdin", "-v", "error", "-y", "-f", "concat", "-safe", "0", "-i", str(listing),
                    "-vn", "-t", str(minutes * 60), "-ar", "44100", "-ac", "2", "-c:a", "libmp3lame", "-b:a", "128k",
                    str(dst)], check=True)
    made = _duration(dst)
    if made < minutes * 60 - 1:
        raise SystemExit(f"{dst.name}: made {made:.0f} s, wanted {minutes * 60:.0f} s")
    print(f"{dst.name}: {made:.1f} s", flush=True)
    return dst


def _duration(path: Path) -> float:
    """Seconds of audio in ``path``, by decoding it to the end (an mp3's header may not say)."""
    from dancekit.render._ffmpeg import ffmpeg_exe

    r = subprocess.run([ffmpeg_exe(), "-nostdin", "-i", str(path), "-f", "null", "-"], capture_output=True, text=True)
    last = [line for line in r.stderr.replace("\r", "\n").splitlines() if "time=" in line][-1]
    h, m, s = last.split("time=")[1].split()[0].split(":")
    return int(h) * 3600 + int(m) * 60 + float(s)


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


#: What ``--trace`` marks: (module, attribute, label); a class attribute is "Class.method". The label may use
#: ``{preset}`` / ``{fmt}`` (keyword or positional argument of that name).
TRACED = [
    ("dancekit.features", "extract_file", "features {preset}"),
    ("dancekit.pipelines.revolution", "RevolutionPipeline.read_genre", "genre reading"),
    ("dancekit.pipelines.revolution", "RevolutionPipeline.generate_many", "generation"),
    ("dancekit.pipelines.revolution", "song_beats_for", "song beats"),
    ("dancekit.pipelines.stages", "clean_up", "clean-up"),
    ("dancekit.pipelines.stages", "smooth", "smoothing"),
    ("dancekit.pipelines.stages", "foot_lock", "foot lock"),
    ("dancekit.pipelines.stages", "beat_sync", "beat sync"),
    ("dancekit.export.writer", "_write", "export {fmt}"),
    ("dancekit.motion.motion", "Motion.with_rotations", "IK (with_rotations)"),
]


def _rss() -> int:
    """This process's resident set size now, bytes (VmRSS)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def trace_child(song: str, out: str, csv: str, formats: str) -> int:
    """In this (fresh) process: ``dancekit dance song`` with the steps of :data:`TRACED` marked and RSS
    sampled every 0.1 s into ``csv`` (seconds, bytes, the innermost step running)."""
    import functools
    import importlib
    import inspect
    import threading

    stack: list[str] = ["imports"]
    rows: list[tuple[float, int, str]] = []
    t0 = time.perf_counter()
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.1):
            rows.append((time.perf_counter() - t0, _rss(), stack[-1]))

    def wrap(fn, label):
        sig = inspect.signature(fn)

        @functools.wraps(fn)
        def inner(*a, **k):
            try:
                bound = sig.bind_partial(*a, **k).arguments
            except TypeError:
                bound = k
            stack.append(label.format(preset=bound.get("preset", ""), fmt=bound.get("fmt", "")))
            rows.append((time.perf_counter() - t0, _rss(), stack[-1]))
            try:
                return fn(*a, **k)
            finally:
                rows.append((time.perf_counter() - t0, _rss(), stack[-1]))
                stack.pop()
        return inner

    threading.Thread(target=sample, daemon=True).start()
    from dancekit.cli.main import main as cli_main

    for module, attr, label in TRACED:
        mod = importlib.import_module(module)
        owner, name = (getattr(mod, attr.split(".")[0]), attr.split(".")[1]) if "." in attr else (mod, attr)
        setattr(owner, name, wrap(getattr(owner, name), label))
    stack[-1] = "load model, other"
    code = cli_main(["dance", song, "-o", out, "--format", formats, "--quiet"])
    done.set()
    rows.append((time.perf_counter() - t0, _rss(), "end"))
    Path(csv).write_text("".join(f"{t:.2f},{b},{what}\n" for t, b, what in rows))
    print(f"peak RSS (ru_maxrss) {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 2**30:.3f} GiB; "
          f"wall {time.perf_counter() - t0:.0f} s; CPU {time.process_time():.0f} s", flush=True)
    return code


def _trace_table(csv: Path) -> list[tuple[str, float, float, int]]:
    """(step, first second, last second, peak bytes) per step of a trace, in order of first appearance."""
    steps: dict[str, list] = {}
    for line in csv.read_text().splitlines():
        t, b, what = line.split(",", 2)
        row = steps.setdefault(what, [float(t), float(t), 0])
        row[1] = float(t)
        row[2] = max(row[2], int(b))
    return [(k, *v) for k, v in steps.items()]


def plot(traces: dict[str, Path], png: Path) -> None:
    """RSS over time of each trace (one line per song; each step named below the axis where it first runs),
    drawn with Pillow."""
    from PIL import Image, ImageDraw

    w, h, left, bottom, top = 1100, 450 + 90 * len(traces), 70, 30 + 90 * len(traces), 20
    data = {k: [(float(t), int(b) / 1e9, what) for t, b, what in (ln.split(",", 2) for ln in p.read_text().splitlines())]
            for k, p in traces.items()}
    tmax = max(r[-1][0] for r in data.values())
    ymax = 1.3
    img = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(img)

    def xy(t, g):
        return left + (w - left - 20) * t / tmax, h - bottom - (h - bottom - top) * g / ymax

    for g in (0.25, 0.5, 0.75, 1.0, 1.25):
        d.line([xy(0, g), xy(tmax, g)], fill=(225, 225, 225) if g != 1.0 else (200, 0, 0))
        d.text((8, xy(0, g)[1] - 6), f"{g:.2f} GB", fill="black")
    for s in range(0, int(tmax) + 1, 300 if tmax > 1200 else 60):
        d.text((xy(s, 0)[0] - 10, h - bottom + 6), f"{s} s", fill="black")
    colours = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (148, 103, 189)]
    zip_index = {name: k for k, name in enumerate(data)}
    for (name, rows), colour in zip(data.items(), colours):
        d.line([xy(t, g) for t, g, _ in rows], fill=colour, width=2)
        d.text((xy(rows[-1][0], 0)[0] - 60, xy(0, rows[-1][1])[1] - 16), name, fill=colour)
        seen: list[str] = []  # each step named once, where it first runs, on one of four staggered rows
        for t, _g, what in rows:
            if what not in seen and what not in ("end", "imports"):
                seen.append(what)
                row = len(seen) % 4
                y = h - bottom + 24 + 90 * zip_index[name] + 16 * row  # the trace's own band below the axis
                d.line([(xy(t, 0)[0], xy(0, 0.03)[1]), (xy(t, 0)[0], y + 8)], fill=colour)
                d.text((xy(t, 0)[0] + 2, y), what[:18], fill=colour)
    d.text((left, 2), "dancekit dance SONG (mp4, html, npz, bvh): resident memory (VmRSS, GB = 1e9 bytes) "
           "against seconds; red: the 1-GB target", fill="black")
    img.save(png)


def post(frames: int, formats: str) -> None:
    """The steps after the generation on an ``frames``-frame dance (see the module docstring)."""
    import threading

    import numpy as np

    from dancekit.export import check_formats, export_motion
    from dancekit.features.pulse import SongBeats
    from dancekit.motion import Motion
    from dancekit.pipelines import load_pipeline, stages
    from dancekit.pipelines.base import DanceResult

    song = MUSIC / SONGS[1]
    pipe = load_pipeline()
    one = pipe.generate(str(song), seed=0)
    beats = stages.song_beats_for(song)
    pos, n = one.positions, one.num_frames
    travel = pos[-1, one.skeleton.root] - pos[0, one.skeleton.root]
    travel[one.skeleton.up_index] = 0
    reps = frames // n + 1
    tiled = np.concatenate([pos + k * travel for k in range(reps)])[:frames].astype(np.float32)
    times = np.concatenate([beats.times + k * n / one.fps for k in range(reps)])
    beats = SongBeats(tempo=beats.tempo, times=times[times < frames / one.fps], clarity=beats.clarity,
                      has_beat=True)
    result = DanceResult(motion=Motion(skeleton=one.skeleton, fps=one.fps, positions=tiled), model="", seed=0)
    del tiled, pos, one
    label, peaks = ["dance made (imports, model, tiled dance)"], {}
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.05):
            peaks[label[0]] = max(peaks.get(label[0], 0), _rss())

    threading.Thread(target=sample, daemon=True).start()
    print(f"  {label[0]}: RSS {_rss() / 2**30:.3f} GiB", flush=True)
    steps = [("clean-up", stages.clean_up), ("smoothing", stages.smooth), ("foot lock", stages.foot_lock),
             ("beat sync", lambda r: stages.beat_sync(r, song, beats=beats))]
    with tempfile.TemporaryDirectory(prefix="dk-mem-") as out:
        steps += [(f"export {fmt}", lambda r, fmt=fmt: export_motion(r.motion, out, stem="x", formats=[fmt],
                                                                      audio=song, progress=False) and r)
                  for fmt in check_formats(formats)]
        for name, fn in steps:
            peaks[label[0]] = max(peaks.get(label[0], 0), _rss())
            label[0] = name
            t0 = time.perf_counter()
            result = fn(result)
            peaks[name] = max(peaks.get(name, 0), _rss())
            print(f"  {name:12s} {time.perf_counter() - t0:6.1f} s  peak RSS {peaks[name] / 2**30:.3f} GiB", flush=True)
    done.set()
    print(f"{frames} frames ({'; '.join(result.notes)}); peak RSS of the process (ru_maxrss) "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.3f} GiB")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[20.0, 60.0])
    ap.add_argument("--format", default="mp4,html,npz,bvh")
    ap.add_argument("--song", default=None)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--stages", action="store_true",
                    help="instead: run the steps one by one in this process, the peak after each")
    ap.add_argument("--trace", action="store_true",
                    help="instead: RSS sampled over time with the step running, the peak of each step")
    ap.add_argument("--plot", default=None, help="with --trace: draw RSS over time into this PNG")
    ap.add_argument("--post-frames", type=int, default=None,
                    help="instead: only the steps after the generation, on a dance tiled to this many frames")
    ap.add_argument("--trace-child", nargs=3, metavar=("SONG", "OUT", "CSV"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.post_frames:
        post(args.post_frames, "npz,html,bvh" if args.format == ap.get_default("format") else args.format)
        return 0
    if args.trace_child:
        return trace_child(*args.trace_child, formats=args.format)
    if args.trace:
        with tempfile.TemporaryDirectory(prefix="dk-mem-") as tmp:
            tmp = Path(tmp)
            traces = {}
            for minutes in ([None] if args.song else args.minutes):
                song = Path(args.song) if args.song else make_song(tmp / f"long{minutes:g}.mp3", minutes)
                label = song.name if args.song else f"{minutes:g} min"
                csv = tmp / f"trace{len(traces)}.csv"
                env = {**os.environ, "DANCEKIT_CACHE": str(tmp / f"cache{len(traces)}"),
                       "PYTHONPATH": str(ROOT / "src")}
                print(f"{label}: load average {os.getloadavg()[0]:.1f} at start", flush=True)
                r = subprocess.run([sys.executable, __file__, "--format", args.format, "--trace-child", str(song),
                                    str(tmp / "out"), str(csv)], env=env, text=True)
                shutil.rmtree(tmp / "out", ignore_errors=True)
                if r.returncode:
                    print(f"{label}: exit {r.returncode}")
                    continue
                traces[label] = csv
                print(f"| step ({label}) | from (s) | to (s) | peak RSS while running |")
                print("| --- | ---: | ---: | ---: |")
                for what, a, b, peak in _trace_table(csv):
                    print(f"| {what} | {a:.0f} | {b:.0f} | {peak / 2**30:.3f} GiB ({peak / 1e9:.3f} GB) |")
                if args.plot:
                    shutil.copy(csv, Path(args.plot).with_suffix(f".{len(traces) - 1}.csv"))
            if args.plot and traces:
                plot(traces, Path(args.plot))
        return 0
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
