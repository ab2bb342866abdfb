"""``dancekit render MOTION -o OUT.mp4|OUT.html``: a dance (and its song) to a video or a web page.

``dancekit render DANCE.glb -o view.html`` (or ``--format glb-html`` for any motion) writes
a self-contained glTF viewer page instead, with the glb embedded.

MOTION is anything :func:`dancekit.motion.formats.read_motion` reads (npz, BVH, AIST++
pkl, OpenPose folder, tang2018 dance folder). A tang2018 folder brings its own song
slice; otherwise give ``--audio`` (and optionally ``--start`` / ``--end``, seconds
into the song, where frame 0 plays at ``--start``). A song shorter than the dance is refused
(one error line) unless ``--end`` says which part to render: the video is never silently cut.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from dancekit.cli._options import output_fps
from dancekit.errors import ParameterError

_FORMATS = {".mp4": "mp4", ".html": "html", ".htm": "html"}


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "render",
        help="render a dance to an mp4 (with its song) or a self-contained html player",
        description="Render a dance (and its song) to an mp4 video or a self-contained html player. "
        "MOTION is any motion file the toolkit reads; a tang2018 dance folder brings its own song slice.",
    )
    p.add_argument(
        "motion", metavar="MOTION", help="motion file or folder (npz, bvh, pkl, tang2018 folder, ...)"
    )
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output .mp4 or .html")
    p.add_argument("--audio", metavar="A", help="song to play with the dance")
    p.add_argument(
        "--start", type=float, metavar="S", help="second of the song at which the dance starts (default 0)"
    )
    p.add_argument(
        "--end",
        type=float,
        metavar="S",
        help="second of the song at which it ends (default: start + dance length)",
    )
    p.add_argument("--width", type=int, help="video width in pixels (mp4 only; default 640)")
    p.add_argument("--height", type=int, help="video height in pixels (mp4 only; default 480)")
    p.add_argument("--title", help="page title (html only; default: the output's file name)")
    p.add_argument("--fps", type=float, help="frame rate of the render (the motion resampled with slerp; at most 240)")
    p.add_argument("--figure", choices=("stick", "body"), default=None,
                   help="mp4 and html player: stick figure (default) or body (shaded volumetric mannequin)")
    p.add_argument("--format", choices=("mp4", "html", "glb-html"), default=None, dest="kind",
                   help="output kind (default: from the suffix; a .glb MOTION with .html output: glb-html, "
                        "a self-contained glTF viewer page that plays the glb's skinned body)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    src = Path(args.motion)
    kind = _FORMATS.get(out.suffix.lower())
    if kind is None:
        raise ParameterError(f"output must end in .mp4 or .html, got {str(out)!r}")
    if args.kind is not None:
        if (args.kind == "mp4") != (kind == "mp4"):
            raise ParameterError(f"--format {args.kind} does not match the output {str(out)!r}")
        kind = args.kind
    elif kind == "html" and src.suffix.lower() == ".glb":
        kind = "glb-html"
    if kind != "mp4" and (args.width is not None or args.height is not None):
        raise ParameterError("--width / --height apply to .mp4 output only")
    if kind == "glb-html":
        for flag, value in (("--audio", args.audio), ("--start", args.start), ("--end", args.end),
                            ("--figure", args.figure)):
            if value is not None:
                raise ParameterError(f"{flag} does not apply to the glTF viewer (glb-html)")
        if src.suffix.lower() == ".glb" and args.fps is not None:
            raise ParameterError("--fps does not apply to a .glb shown as it is")
    if kind == "mp4" and args.title is not None:
        raise ParameterError("--title applies to .html output only")
    args.fps = output_fps(args.fps)
    if not out.parent.is_dir() and str(out.parent):
        raise ParameterError(f"output folder does not exist: {out.parent}")
    if out.is_dir():  # the final rename onto a folder would fail after the whole render
        raise ParameterError(f"output {str(out)!r} is a folder; give a file name (e.g. {str(out / out.name)!r})")

    from dancekit.motion.formats import detect_format, read_motion, read_tang2018
    from dancekit.render import AudioClip, RenderOptions, render_motion_html, render_motion_mp4
    from dancekit.render.glb_html import render_glb_html, render_motion_glb_html

    given = {"width": args.width, "height": args.height, "title": args.title, "figure": args.figure}
    options = RenderOptions(**{k: v for k, v in given.items() if v is not None})  # validated before reading

    if kind == "glb-html" and src.suffix.lower() == ".glb":
        if not src.is_file():
            raise ParameterError(f"no such file: {src}")
        render_glb_html(out, src, options=options)
        if not args.quiet:
            print(out)
        return 0
    audio, start, end = args.audio, args.start, args.end
    if src.is_dir() and detect_format(src) == "tang2018":
        motion, song = read_tang2018(src)
        if audio is None:  # the folder's own song slice; --start / --end override it
            audio = song.path
            start = song.start if start is None else start
            end = song.end if end is None else end
    else:
        motion = read_motion(src)
    if args.fps is not None and args.fps != motion.fps:
        motion = motion.resample(args.fps)
    if audio is None and (start is not None or end is not None):
        raise ParameterError("--start / --end need --audio")

    if audio is not None and end is None:
        # refused rather than cut (ffmpeg would end the video with the song) or padded with silence
        from dancekit.render import audio_duration

        left = audio_duration(audio) - (start or 0.0)
        # the dance's last frame shows at (T - 1) / fps: a dance of a whole song (1 + n // hop frames, as
        # `dancekit dance` makes) ends with the song, one frame period past it by motion.duration
        last = (motion.num_frames - 1) / motion.fps
        if 0 < left and left + 0.5 / motion.fps < last:
            raise ParameterError(f"the song {str(audio)!r} holds {max(left, 0):.2f} s from --start "
                                 f"{start or 0:g} s, shorter than the dance ({motion.duration:.2f} s): give a "
                                 "longer song, or --end to render only the part of the dance the song covers")
    clip = None if audio is None else AudioClip(audio, start, end)
    if kind == "mp4":
        render_motion_mp4(out, motion, audio=clip, options=options, progress=not args.quiet)
    elif kind == "glb-html":
        render_motion_glb_html(out, motion, options=options)
    else:
        render_motion_html(out, motion, audio=clip, options=options)
    if not args.quiet:
        print(out)
    return 0
