"""``dancekit dance SONG -o OUTDIR``: the main job — a dance for any song, rendered and exported."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dancekit.cli._options import SEEDS_HELP, add_output, one_seed, output_fps, seed_list
from dancekit.errors import DancekitError, ParameterError
from dancekit.export import DEFAULT_FORMATS, FORMATS


def describe(result) -> str:
    """What the summary line says of a dance: ``as waltz (read from the music, p = 0.46); beat-synced ...``,
    or for a model without genres ``by dual; energy lifted ...``: it always says what danced."""
    summary = result.summary()
    if summary.startswith("as ") or summary.startswith("by "):
        return summary
    name = Path(str(result.model)).name or str(result.model)
    return f"by {name}" + (f"; {summary}" if summary else "")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "dance",
        help="make a dance for a song: mp4 with the song, html player, npz and BVH",
        description="Generate a dance for AUDIO with an embedded model (default) or a checkpoint, "
        "then render and export it into OUTDIR.",
    )
    p.add_argument("audio", help="the song (wav, flac, ogg, mp3, m4a, ...)")
    add_output(p, help="output folder (created if missing)", metavar="OUTDIR")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--model", default=None,
                   help="model name (see `dancekit models`; also the user's models folder $DANCEKIT_MODELS) or folder")
    g.add_argument("--checkpoint", default=None, help="a checkpoint folder (from `dancekit train`)")
    p.add_argument("--genre", default="auto",
                   help="dance genre: auto, none or one of the model's genres (`dancekit models` lists them; the "
                        "default model: waltz, rumba, chacha, tango); auto (default): read from the music when the "
                        "model has a music attribute classifier, else as none; none: the model alone")
    p.add_argument("--seed", default=None, metavar="N",
                   help="random seed: another seed, another dance (default 0); any integer (seeds outside "
                        "[0, 2**63) are hashed to 63 bits)")
    p.add_argument("--seeds", default=None, metavar="LIST",
                   help=f"several dances in one run, one per seed: {SEEDS_HELP}; the song is read and its "
                        "features computed once, the seeds' decoders run side by side on the CPU cores (each seed "
                        "the same dance as --seed K), and each is written as NAME_seedK.mp4, NAME_seedK.html, ... "
                        "(at most 64 seeds)")
    p.add_argument("--foot-constraint", nargs="?", const="default", default=None, metavar="MODEL",
                   help="post-process the dance with the Foot Constraint Model of Music2Dance (less foot sliding; "
                        "the lower body alone is corrected, the path over the floor is kept): the one embedded with "
                        "the music2dance model, or MODEL (a foot_constraint checkpoint). Any model on the tang2018 "
                        "skeleton (default: off)")
    p.add_argument("--start", type=float, default=None, help="start of the song excerpt, seconds")
    p.add_argument("--end", type=float, default=None, help="end of the song excerpt, seconds")
    p.add_argument("--beat-sync", choices=("on", "off"), default="on",
                   help="time-warp the dance so its movement beats land on the song's beats (speed kept within "
                        "±15 %%, or the model's own bound: dual ±30 %%, music2dance ±40 %%, changing by at most 2 %% a frame; "
                        "default on; a song without a clear beat is left as it is, with a note)")
    p.add_argument("--cleanup", choices=("on", "off"), default="on",
                   help="physical clean-up: lowest joint on the floor, the figure kept within a dance floor "
                        "(turned back beyond 4 m from its start; default on)")
    p.add_argument("--foot-lock", choices=("on", "off"), default=None,
                   help="hold planted feet where they were planted (two-bone IK on the legs, blended in and out; "
                        "default: as --cleanup)")
    p.add_argument("--smooth", choices=("on", "off"), default=None,
                   help="filter frame-to-frame jitter out of a jittery dance (a Savitzky-Golay filter whose window "
                        "is chosen per dance; a smooth dance is left alone; default: as --cleanup)")
    e = p.add_argument_group("editing (docs/EDITING.md; applied to the finished dance, any model)")
    e.add_argument("--prefix", default=None, metavar="FILE",
                   help="a motion (npz, bvh, glb, pkl) kept exactly for its length; the dance continues from it "
                        "(aligned to its last frame and faded over 0.5 s after it)")
    e.add_argument("--keyframes", default=None, metavar="KEYS.json",
                   help='poses at given times or beats: [{"time": s | "beat": i, "pose": FILE | {joint: [x, y, z]}}]; '
                        "the dance passes exactly through them, smoothly corrected within 1 s around each")
    e.add_argument("--path", default=None, metavar="PATH.json",
                   help='a path on the floor {"points": [[x, z], ...] (m), "times": [...] (s, optional)}: the '
                        "root follows it (its own sway kept), the feet held again by the foot lock")
    e.add_argument("--keep", default=None, metavar="upper|lower|JOINTS",
                   help="body part taken from --from: upper, lower or comma-separated joint names")
    e.add_argument("--from", dest="take", default=None, metavar="TAKE",
                   help="the take (npz, bvh, glb, pkl) whose --keep joints the dance keeps (mapped by role from "
                        "another skeleton)")
    p.add_argument("--format", default=",".join(DEFAULT_FORMATS),
                   help=f"comma-separated outputs from {', '.join(FORMATS)}")
    p.add_argument("--bvh-rig", choices=("exact", "humanoid"), default="exact",
                   help="BVH and FBX rig: the skeleton's own joints (exact, default) or a standard humanoid "
                        "(Hips/Spine/Neck/Head, Mixamo-like names, for retargeting in Blender or Unity)")
    p.add_argument("--fps", type=float, default=None,
                   help="frame rate of the outputs (resampled with slerp; at most 240; default: the model's)")
    p.add_argument("--figure", choices=("stick", "body"), default="stick",
                   help="how the mp4 and the html player draw the dancer: stick (default) or body "
                        "(shaded volumetric mannequin)")
    p.add_argument("--width", type=int, default=640, help="video width in pixels (default 640)")
    p.add_argument("--height", type=int, default=480, help="video height in pixels (default 480)")
    p.add_argument("--precision", default="fp32", metavar="{fp32,bf16,int8}",
                   help="decoding precision of autoregressive models (revolution, music2dance, dual): fp32 (default, "
                        "the model as trained), bf16, or int8 (int8 weights, dynamic activation quantisation; "
                        "several times faster for large models; see docs/BENCHMARKS.md for its accuracy budget)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--threads", type=int, default=1,
                   help="CPU threads of the model (default 1: the embedded models are small and generate frame by "
                        "frame, so a second thread costs more in synchronisation than it saves; more for "
                        "paper-size checkpoints)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes that share --seeds' dances (default: one per CPU core, at most one per seed; each "
                        "dance is the same whatever the number)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dancekit.export import check_formats, check_output_folder
    from dancekit.pipelines.prefetch import prefetch_for_model
    from dancekit.render import AudioClip, RenderOptions

    t0 = time.perf_counter()
    formats = check_formats(args.format)
    audio = Path(args.audio)
    if not audio.exists():
        raise DancekitError(f"audio file not found: {audio}")
    if args.seed is not None and args.seeds is not None:
        raise ParameterError("give --seed N (one dance) or --seeds LIST (several), not both")
    args.seeds = seed_list(args.seeds)
    args.seed = one_seed(args.seed if args.seed is not None else 0)
    args.fps = output_fps(args.fps)
    if args.threads < 1:
        raise ParameterError(f"--threads must be at least 1, got {args.threads}")
    if args.workers is not None and args.workers < 1:
        raise ParameterError(f"--workers must be at least 1, got {args.workers}")
    edit = _edit_config(args)  # before the dance is made: a missing file or a contradiction fails fast
    clip = AudioClip(audio, args.start, args.end)
    options = RenderOptions(width=args.width, height=args.height, figure=args.figure)
    out = check_output_folder(args.out)  # before the dance is made, not after
    if not out.exists() and out.suffix[1:].lower() in FORMATS:  # "-o d.npz": a folder, which may surprise
        import sys

        print(f"dancekit dance: note: -o {out} is an output folder: the files are written inside it "
              f"(--format chooses them)", file=sys.stderr)
    # the song's features computed in a second process while this one imports torch and loads the model
    prefetch = prefetch_for_model(audio, args.checkpoint if args.checkpoint is not None else args.model,
                                  start=args.start, end=args.end)
    try:
        return _dance(args, audio, clip, options, out, formats, prefetch, t0, edit)
    finally:
        prefetch.cancel()


def _edit_config(args):
    """The :class:`~dancekit.pipelines.config.EditConfig` of the editing flags, or None without any."""
    if all(v is None for v in (args.prefix, args.keyframes, args.path, args.keep, args.take)):
        return None
    from dancekit.pipelines.config import EditConfig

    return EditConfig(prefix=args.prefix, keyframes=args.keyframes, path=args.path, keep=args.keep, take=args.take)


def _dance(args, audio, clip, options, out, formats, prefetch, t0, edit=None) -> int:
    from dancekit.export import export_motion
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline(args.model, args.checkpoint, precision=args.precision)
    import torch

    torch.set_num_threads(args.threads)
    fix = None
    if args.foot_constraint is not None:
        from dancekit.pipelines.foot_constraint import load_foot_constraint

        fix = load_foot_constraint(args.foot_constraint)  # before the dance: a bad name fails fast
    stages_on = {"beat_sync": args.beat_sync == "on", "cleanup": args.cleanup == "on"}
    extra = {k: None if v is None else v == "on" for k, v in (("foot_lock", args.foot_lock), ("smooth", args.smooth))}
    own = fix is None and all(v is None for v in extra.values())  # the pipeline runs the stages itself
    seeds = [args.seed] if args.seeds is None else args.seeds
    prefetch.wait()
    from dancekit.pipelines.parallel import usable_cores

    workers = args.workers if args.workers is not None else min(len(seeds), usable_cores())
    results = pipe.dances(str(audio), seeds=seeds, start=args.start, end=args.end, genre=args.genre,
                          progress=not args.quiet, edit=edit if own else None, workers=workers,
                          **(stages_on if own else {"beat_sync": False, "cleanup": False}))
    if not own:  # the foot model sees the model's own dance; the stages come after it
        import dataclasses

        from dancekit.pipelines.stages import Song, finish

        song = Song(str(audio), args.start, args.end)  # its beats tracked once
        config = pipe.stage_options(**stages_on, **extra)  # the checkpoint's stage settings, as in pipe.dances
        if edit is not None:
            config = dataclasses.replace(config, edit=edit)
        results = [finish(dataclasses.replace(r, motion=r.motion if fix is None else fix(r.motion)), song, config)
                   for r in results]
    t_made = time.perf_counter()
    for result in results:
        motion = result.motion
        if args.fps is not None and args.fps != motion.fps:
            motion = motion.resample(args.fps)
        stem = audio.stem if args.seeds is None else f"{audio.stem}_seed{result.seed}"
        t_export = time.perf_counter()
        written = export_motion(motion, out, stem=stem, formats=formats, audio=clip, options=options,
                                progress=not args.quiet, bvh_rig=args.bvh_rig)
        seed = "" if args.seeds is None else f" (seed {result.seed})"
        took = time.perf_counter() - t0 if args.seeds is None else time.perf_counter() - t_export
        timing = f"in {took:.1f} s" if args.seeds is None else f"written in {took:.1f} s"
        print(f"danced {audio.name}{seed} {describe(result)}: {motion.duration:.1f} s, {motion.num_frames} frames "
              f"at {motion.fps:g} fps {timing} → " + ", ".join(str(p) for p in written))
    if args.seeds is not None:
        print(f"danced {len(results)} seeds in {time.perf_counter() - t0:.1f} s (the dances made in "
              f"{t_made - t0:.1f} s, then written one by one)")
    return 0
