"""``dancekit compose MOTION -o OUTDIR``: music for a dance with the dual-learning model's G_D→M.

Writes ``STEM.mid`` (by default music that follows the dance: its tempo, beats and metre; chords of the printed
key changing on bars, chosen by G_D→M; bass and drums on the pulse), ``STEM.wav`` (FluidSynth when installed, else
the built-in synthesiser) and, unless ``--no-video``, ``STEM.mp4`` and ``STEM.html``: the dance with its new
music (:func:`dancekit.export.export_motion`). All files appear together or none do.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from dancekit.cli._options import add_output
from dancekit.cli.info import AUDIO_SUFFIXES, MIDI_SUFFIXES, VIDEO_SUFFIXES
from dancekit.errors import ParameterError

DEFAULT_COMPOSE_MODEL = "dual"
#: The shortest dance composed for (seconds): the shortest song dancekit reads back (``dancekit.audio.MIN_DURATION``),
#: so the WAV and mp4 that compose writes are songs ``dancekit dance`` and ``info`` accept.
MIN_COMPOSE_SECONDS = 1.0


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compose",
        help="compose music for a dance: MIDI (chords, bass, drums on the composed beats), WAV, mp4 and html",
        description="Compose chroma and beats for MOTION with a dual-learning model (G_D→M) and arrange them as "
                    "MIDI (chords on the beats, bass on the chord roots, drums on the beats), rendered to WAV with "
                    "FluidSynth when installed, else the built-in synthesiser; the dance with its new music as an "
                    "mp4 and an html player. A dance on another skeleton is mapped to the model's joints by role.",
    )
    p.add_argument("motion", help="a dance file the toolkit reads (npz, BVH, glb, AIST++ pkl, tang2018 folder), "
                                  f"at least {MIN_COMPOSE_SECONDS:g} s long")
    add_output(p, help="output folder (created if missing)", metavar="OUTDIR")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--model", default=None,
                   help=f"a dual model name (`dancekit models`) or folder (default: the embedded "
                        f"{DEFAULT_COMPOSE_MODEL!r} model)")
    g.add_argument("--checkpoint", default=None, help="a dual checkpoint folder (from `dancekit train dual`)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the start chord (default 0)")
    p.add_argument("--tempo", default=None, help="dance (the dance's own tempo, beats and metre; G_D→M chooses the "
                   "chords and accents), a tempo in BPM (the same at that tempo), auto (the peaks of G_D→M's beat "
                   "activation) or periodic (beats on its periodicity); default: the model's setting (dance)")
    p.add_argument("--render", default="auto", choices=("auto", "fluidsynth", "builtin"), help="audio renderer")
    p.add_argument("--no-video", action="store_true", help="write the MIDI and WAV only (no mp4 / html)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def parse_tempo(text: str | None) -> str | float | None:
    if text is None or text in ("dance", "auto", "periodic"):
        return text
    try:
        return float(text)
    except ValueError:
        raise ParameterError(f"--tempo must be 'dance', 'auto', 'periodic' or a number of BPM, got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    from dancekit.export import check_output_folder, export_motion
    from dancekit.motion.formats import read_motion
    from dancekit.pipelines.dual import ComposePipeline

    t0 = time.perf_counter()
    tempo = parse_tempo(args.tempo)
    src = Path(args.motion)
    if src.suffix.lower() in AUDIO_SUFFIXES | VIDEO_SUFFIXES | MIDI_SUFFIXES:
        raise ParameterError(f"{str(src)!r} is music, not a dance: compose makes music for a dance; for a dance to "
                             f"this song use `dancekit dance {src} -o OUTDIR`")
    out = check_output_folder(args.out)
    motion = read_motion(args.motion)
    if motion.num_frames / motion.fps < MIN_COMPOSE_SECONDS:
        raise ParameterError(f"the dance {str(src)!r} lasts {motion.num_frames / motion.fps:.2f} s "
                             f"({motion.num_frames} frames at {motion.fps:g} fps); compose needs at least "
                             f"{MIN_COMPOSE_SECONDS:g} s")
    pipe = ComposePipeline.from_pretrained(args.checkpoint or args.model or DEFAULT_COMPOSE_MODEL)
    result = pipe(motion, seed=args.seed, tempo=tempo)
    stem = Path(args.motion).stem or "dance"
    created = not out.exists()
    stage = Path(tempfile.mkdtemp(prefix=".dancekit-compose-"))
    try:
        music = result.write(stage, stem=stem, render=args.render)  # midi + wav, staged
        files = []
        if not args.no_video:
            files = export_motion(motion, out, stem=stem, formats=("mp4", "html"), audio=music["wav"],
                                  progress=not args.quiet)
        out.mkdir(parents=True, exist_ok=True)
        for path in music.values():
            shutil.move(str(path), str(out / path.name))  # a rename on the same file system
        files = [out / p.name for p in music.values()] + list(files)
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    if not args.quiet:
        arr = result.arrangement
        if hasattr(arr, "key_name"):  # the arranger that follows the dance: one chord per bar
            what, names, unit = f"in {arr.key_name()}, {arr.beats_per_bar} beats to a bar", arr.bar_chord_names(), "bar"
        else:
            what, names, unit = f"from {result.start_chord}", arr.chord_names(), "beat"
        print(f"composed {arr.duration:.1f} s {what}: {len(arr.beat_times)} beats at {arr.tempo:.1f} BPM, chords "
              f"(one per {unit}) {' '.join(names[:8])}{' ...' if len(names) > 8 else ''} "
              f"in {time.perf_counter() - t0:.1f} s")
        for path in files:
            print(f"  {path}")
    return 0

