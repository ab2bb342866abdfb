"""``dancekit dance SONG -o OUTDIR``: the main job — a dance for any song, rendered and exported."""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from dancekit.errors import DancekitError, ParameterError

FORMATS = ("mp4", "html", "npz", "bvh", "openpose")
DEFAULT_FORMATS = "mp4,html,npz,bvh"


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "dance",
        help="make a dance for a song: mp4 with the song, html player, npz and BVH",
        description="Generate a dance for AUDIO with an embedded model (default) or a checkpoint, "
        "then render and export it into OUTDIR.",
    )
    p.add_argument("audio", help="the song (wav, flac, ogg, mp3, m4a, ...)")
    p.add_argument("-o", "--out", required=True, help="output folder (created if missing)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--model", default=None,
                   help="model name (see `dancekit models`; also the user's models folder $DANCEKIT_MODELS) or folder")
    g.add_argument("--checkpoint", default=None, help="a checkpoint folder (from `dancekit train`)")
    p.add_argument("--genre", default="auto",
                   help="dance genre: auto, none or one of the model's genres (`dancekit models` lists them; the "
                        "default model: waltz, rumba, chacha, tango); auto (default): read from the music when the "
                        "model has a music attribute classifier, else as none; none: the model alone")
    p.add_argument("--seed", type=int, default=0, help="random seed: another seed, another dance (default 0)")
    p.add_argument("--start", type=float, default=None, help="start of the song excerpt, seconds")
    p.add_argument("--end", type=float, default=None, help="end of the song excerpt, seconds")
    p.add_argument("--format", default=DEFAULT_FORMATS, help=f"comma-separated outputs from {', '.join(FORMATS)}")
    p.add_argument("--width", type=int, default=640, help="video width in pixels (default 640)")
    p.add_argument("--height", type=int, default=480, help="video height in pixels (default 480)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def parse_formats(text: str) -> list[str]:
    formats = [f.strip().lower() for f in text.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ParameterError(f"unknown output format {', '.join(bad) or repr(text)}; choose from {', '.join(FORMATS)}")
    return list(dict.fromkeys(formats))


def run(args: argparse.Namespace) -> int:
    from dancekit.pipelines import load_pipeline
    from dancekit.render import AudioClip, RenderOptions

    t0 = time.perf_counter()
    formats = parse_formats(args.format)
    audio = Path(args.audio)
    if not audio.exists():
        raise DancekitError(f"audio file not found: {audio}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise DancekitError(f"output path exists and is not a folder: {out}")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DancekitError(f"cannot create output folder {out}: {exc.strerror}") from exc
    try:
        stage = tempfile.mkdtemp(prefix=".dancekit-", dir=out)
    except OSError as exc:
        raise DancekitError(f"output folder is not writable: {out} ({exc.strerror})") from exc
    stage = Path(stage)
    try:
        pipe = load_pipeline(args.model, args.checkpoint)
        result = pipe(str(audio), seed=args.seed, start=args.start, end=args.end, genre=args.genre,
                      progress=not args.quiet)
        motion = result.motion
        written = export_all(
            motion,
            stage,
            stem=audio.stem,
            formats=formats,
            audio=AudioClip(audio, args.start, args.end),
            options=RenderOptions(width=args.width, height=args.height),
            progress=not args.quiet,
        )
        final = []
        for p in written:
            target = out / p.name
            if target.is_dir():
                shutil.rmtree(target)
            p.replace(target)
            final.append(target)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise
    shutil.rmtree(stage, ignore_errors=True)
    elapsed = time.perf_counter() - t0
    how = f" {result.summary()}" if result.summary() else ""
    print(
        f"danced {audio.name}{how}: {motion.duration:.1f} s, {motion.num_frames} frames at {motion.fps:g} fps "
        f"in {elapsed:.1f} s → " + ", ".join(str(p) for p in final)
    )
    return 0


def export_all(
    motion,
    folder: Path,
    *,
    stem: str,
    formats: list[str],
    audio,
    options,
    progress: bool = True,
) -> list[Path]:
    """Write ``motion`` into ``folder`` in every format; returns the written paths."""
    from dancekit.motion.formats import write_motion

    written: list[Path] = []
    for fmt in formats:
        if fmt == "npz":
            path = folder / f"{stem}.npz"
            write_motion(path, motion)
        elif fmt == "bvh":
            path = folder / f"{stem}.bvh"
            write_motion(path, motion)
        elif fmt == "openpose":
            from dancekit.motion.formats.openpose import write_openpose

            path = folder / f"{stem}_openpose"
            m2 = motion if motion.skeleton.dims == 2 else motion.project_2d()
            write_openpose(path, m2)
        elif fmt == "mp4":
            from dancekit.render import render_motion_mp4

            path = folder / f"{stem}.mp4"
            render_motion_mp4(path, motion, audio=audio, options=options, progress=progress)
        elif fmt == "html":
            from dancekit.render import render_motion_html

            path = folder / f"{stem}.html"
            render_motion_html(path, motion, audio=audio, options=options)
        else:  # pragma: no cover - parse_formats guards this
            raise AssertionError(fmt)
        written.append(path)
    return written
