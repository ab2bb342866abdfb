"""``dancekit evaluate``: score generated dances against the real ones.

    dancekit evaluate --checkpoint revolution --data data/tang2018 --split test --seeds 0-4 -o runs/eval
    dancekit evaluate --pred runs/model/test --ref data/tang2018 --data data/tang2018 -o report.json
    dancekit evaluate --checkpoint revolution --data data/tang2018 --split val --seeds 30 --seed-sets 6 -o runs/s30
    dancekit evaluate --checkpoint revolution --data data/tang2018 --split val --ablate-stages -o runs/stages

    dancekit evaluate --compose dual --data data/tang2018 --split test -o runs/compose_eval
    dancekit evaluate --music runs/composed --data data/tang2018 --split test -o music_report.json

With ``--checkpoint`` the model first dances every song of the split (``OUT/pred/NAME__k.npz``) and the
report goes to ``OUT/report.json``; with ``--pred`` a folder of dances is scored into the JSON file ``-o``.
Prints a markdown table (generated vs real); the report holds every metric, per-dance values and the
settings used (written atomically). ``--seed-sets K`` adds FID_k / FID_g of K disjoint sets of the seeds (how much a figure
moves with the seeds); ``--ablate-stages`` adds FID_k / FID_g after each pipeline stage
(:mod:`dancekit.evaluation.ablation`). Layout, music lookup and defaults: :mod:`dancekit.evaluation` and
docs/METRICS.md.

Music: ``--compose MODEL`` composes music for every dance of the split with a ``dual`` model
(``OUT/music/NAME.mid|.wav``, report ``OUT/report.json``, table ``OUT/table.md``); ``--music DIR`` scores a
folder of ``NAME.mid|.wav`` into the JSON file ``-o``. Both print BCS / BHS (protocols A and B), beat F1,
tempo and notes accuracy next to the real music and the click-track baselines
(:mod:`dancekit.evaluation.music`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dancekit._io import atomic_path
from dancekit.cli._options import seed_run
from dancekit.errors import ParameterError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "evaluate",
        help="score dances against real ones (FID_k/g, BAS, style FID/ACC, ...), or composed music against the "
             "real music (BCS/BHS, beat F1, tempo)",
        description="Dance every song of a split with a model (--checkpoint) and score the dances, or score a "
        "folder of generated dances (--pred: NAME.npz or NAME__k.npz, NAME = a reference dance) against the "
        "reference dances; or compose music for the dances of a split with a dual model (--compose) or score a "
        "folder of composed music (--music) against the real music, next to click-track baselines; prints a "
        "markdown table, every metric goes to the JSON report.",
    )
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--checkpoint", metavar="MODEL",
                      help="a checkpoint folder or model name: dance the songs of --split, then score (needs --data)")
    what.add_argument("--pred", metavar="DIR", help="folder of generated .npz dances (needs --ref)")
    what.add_argument("--compose", metavar="MODEL",
                      help="a dual checkpoint folder or model name: compose music for the dances of --split, then "
                           "score it against their real music with the baselines (needs --data)")
    what.add_argument("--music", metavar="DIR",
                      help="folder of composed music NAME.mid|.wav (NAME = a dance of --split): score it against "
                           "the real music with the baselines (needs --data)")
    p.add_argument("--ref", metavar="DIR",
                   help="with --pred: folder of real NAME.npz dances, or a prepared dataset folder (its --split)")
    p.add_argument("--split", default="test", help="split to dance / of a prepared --ref folder (default test)")
    music = p.add_mutually_exclusive_group()
    music.add_argument("--data", metavar="PREPARED_DIR",
                       help="prepared dataset: songs, music beats (features_*.npz beat_times), genres, FID reference")
    music.add_argument("--audio", metavar="DIR", help="folder of NAME.wav|mp3|ogg|flac songs (beats are tracked)")
    p.add_argument("-o", "--output", required=True, metavar="PATH",
                   help="with --checkpoint: output folder (pred/, report.json); with --pred: the report file")
    gen = p.add_argument_group("generation (--checkpoint)")
    gen.add_argument("--seeds", default=None, metavar="LIST",
                     help="the seeds danced for every song, consecutive: 0-4 (default), or another seed set such "
                          "as 5-9 (how much the metrics move between sets)")
    gen.add_argument("--first-seed", type=int, default=None, help=argparse.SUPPRESS)  # deprecated: --seeds K-L
    gen.add_argument("--genre", default=None,
                     help="auto (the genre read from the music when the model has a music attribute classifier, "
                          "else the model alone; default), none (the model alone), true (each song's own genre), "
                          "or a genre name for every song")
    gen.add_argument("--precision", default=None, metavar="{fp32,bf16,int8}",
                     help="decoding precision of the model (default fp32; see dancekit dance --precision)")
    gen.add_argument("--beat-sync", choices=("on", "off"), default=None,
                     help="the pipeline's beat-synchronous stage (default on); when on, the report also compares "
                          "the beat metrics before and after the warp (OUT/pred_unwarped holds the dances before it)")
    gen.add_argument("--ablate-stages", action="store_true",
                     help="also dance the split with the pipeline's stages off and report FID_k / FID_g after each "
                          "stage (raw, clean-up, smoothing, ..., beat sync; the report's stage_ablation entry)")
    p.add_argument("--seed-sets", type=int, default=None, metavar="K",
                   help="also report FID_k / FID_g of K disjoint sets of consecutive seeds (each song's dances "
                        "NAME__k split in K; their number must be a multiple of K): how much a figure moves "
                        "from one set of seeds to another (the report's seed_sets entry)")
    p.add_argument("--sigma", type=float, default=0.05, help="BAS Gaussian sigma in seconds (default 0.05)")
    p.add_argument("--tolerance", type=float, default=0.1,
                   help="beat hit tolerance in seconds for coverage / hit rate (default 0.1)")
    p.add_argument("--segment-seconds", type=float, default=10.0,
                   help="FID_k / FID_g segment length in seconds; 0 = whole dances (default 10)")
    p.add_argument("--fid-ref", choices=("ref", "train", "all"), default=None,
                   help="FID reference set (default: train with --data, else ref)")
    p.add_argument("--bug-compatible", action="store_true",
                   help="reproduce the public reference feature code (acceleration bug, 1/120 s frame time)")
    p.add_argument("--classifier", metavar="DIR", default=None,
                   help="style classifier checkpoint (default: the one shipped with dancekit)")
    p.add_argument("--no-style", action="store_true", help="skip the style-classifier metrics")
    p.add_argument("--preset", default=None, help="feature preset whose beat_times to use (default revolution)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the random pairs of Diversity; with --compose / --music: of the start chords and "
                        "the metronome phases (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    mus = p.add_argument_group("music (--compose, --music)")
    mus.add_argument("--clip-lengths", default="2,5,25,whole",
                     help="BCS / BHS clip lengths in seconds, comma-separated; whole = whole dances "
                          "(default 2,5,25,whole)")
    mus.add_argument("--render", choices=("builtin", "fluidsynth", "auto"), default="builtin",
                     help="MIDI → audio for MIDI without a WAV beside it (default builtin)")
    mus.add_argument("--no-baselines", action="store_true", help="score the composed music only")
    p.set_defaults(func=run)
    return p


def _clip_lengths(text: str) -> tuple[float | None, ...]:
    out: list[float | None] = []
    for part in text.split(","):
        part = part.strip()
        try:
            out.append(None if part == "whole" else float(part))
        except ValueError:
            raise ParameterError(f"--clip-lengths: {part!r} is neither a number of seconds nor 'whole'") from None
    return tuple(out)


def run_music(args: argparse.Namespace) -> int:
    from dancekit.evaluation.music import (
        MusicSettings,
        compose_split,
        evaluate_music,
        format_music_markdown,
        music_table,
        write_report,
    )

    if args.data is None:
        raise ParameterError("--compose and --music need --data (the prepared dataset whose real music is the reference)")
    if args.ref is not None or args.pred is not None or args.seeds is not None or args.genre is not None \
            or args.precision is not None or args.first_seed is not None:
        raise ParameterError("--ref, --seeds, --first-seed, --genre and --precision go with --pred / --checkpoint, "
                             "not with --compose / --music")
    if args.seed_sets is not None or args.ablate_stages:
        raise ParameterError("--seed-sets and --ablate-stages score dances: they go with --checkpoint / --pred, "
                             "not with --compose / --music")
    settings = MusicSettings(clip_lengths=_clip_lengths(args.clip_lengths), render=args.render, seed=args.seed,
                             baselines=not args.no_baselines)
    say = None if args.quiet else (lambda m: print(m, flush=True))
    out = Path(args.output)
    if args.compose is not None:
        gen = compose_split(args.compose, args.data, out / "music", split=args.split, seed=args.seed,
                            render=args.render, progress=say)
        report = evaluate_music(args.data, music=out / "music", split=args.split, settings=settings,
                                label=f"composed ({args.compose})", progress=say)
        report["generation"] = gen
        print(f"composed {gen['seconds']:.0f} s of music in {gen['elapsed_s']:.1f} s")
        path = out / "report.json"
        from dancekit._io import atomic_path

        with atomic_path(out / "table.md") as tmp:
            tmp.write_text(music_table(report) + "\n")
    else:
        if not out.parent.exists():
            raise ParameterError(f"output folder does not exist: {out.parent}")
        report = evaluate_music(args.data, music=args.music, split=args.split, settings=settings,
                                label=f"composed ({args.music})", progress=say)
        path = out
    write_report(report, path)
    print(format_music_markdown(report), end="")
    print(f"report: {path}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.compose is not None or args.music is not None:
        return run_music(args)
    from dancekit.evaluation import EvalSettings, evaluate_checkpoint, evaluate_dirs, format_markdown

    if args.segment_seconds < 0:
        raise ParameterError(f"--segment-seconds must be >= 0, got {args.segment_seconds}")
    settings = EvalSettings(
        sigma=args.sigma,
        tolerance=args.tolerance,
        segment_seconds=args.segment_seconds or None,
        bug_compatible=args.bug_compatible,
        fid_reference=args.fid_ref,
        seed=args.seed,
    )
    classifier = None if args.no_style else (args.classifier or "default")
    out = Path(args.output)
    if args.checkpoint is not None:
        if args.data is None:
            raise ParameterError("--checkpoint needs --data (the prepared dataset whose songs are danced)")
        if args.ref is not None or args.preset is not None:
            raise ParameterError("--ref and --preset go with --pred; --checkpoint scores against --data")
        first, seeds = seed_run(args.seeds, verb="evaluate", default=5, first_seed=args.first_seed)
        _check_seed_sets(args.seed_sets, seeds)
        report = evaluate_checkpoint(args.checkpoint, args.data, out, split=args.split, seeds=seeds,
                                     genre=args.genre or "auto", settings=settings, classifier=classifier,
                                     progress=not args.quiet, beat_sync=args.beat_sync != "off",
                                     precision=args.precision or "fp32", first_seed=first,
                                     seed_sets=args.seed_sets, ablate_stages=args.ablate_stages)
        g = report["generation"]
        print(f"generated {g['seconds']:.0f} s of dance in {g['elapsed_s']:.1f} s "
              f"({g['elapsed_s'] / max(g['seconds'], 1e-9) * 60:.2f} s per minute)")
        print(format_markdown(report), end="")
        _print_stages(report)
        print(f"report: {out / 'report.json'}")
        return 0
    if args.ref is None:
        raise ParameterError("--pred needs --ref (the real dances)")
    if args.seeds is not None or args.genre is not None or args.beat_sync is not None or args.precision is not None \
            or args.first_seed is not None or args.ablate_stages:
        raise ParameterError("--seeds, --first-seed, --genre, --beat-sync, --precision and --ablate-stages go with "
                             "--checkpoint")
    _check_seed_sets(args.seed_sets, None)
    if not out.parent.exists():
        raise ParameterError(f"output folder does not exist: {out.parent}")
    report = evaluate_dirs(args.pred, args.ref, data=args.data, audio_dir=args.audio, classifier=classifier,
                           settings=settings, preset=args.preset, split=args.split, seed_sets=args.seed_sets)
    print(format_markdown(report), end="")
    _print_stages(report)
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    print(f"report: {out}")
    return 0


def _check_seed_sets(sets: int | None, seeds: int | None) -> None:
    """``--seed-sets K``: at least 1, and a divisor of ``--seeds`` when the seeds are known before dancing."""
    if sets is None:
        return
    if sets < 1:
        raise ParameterError(f"--seed-sets must be at least 1, got {sets}")
    if seeds is not None and seeds % sets:
        raise ParameterError(f"--seed-sets {sets}: {seeds} seeds (--seeds) is not a multiple of {sets}")


def _print_stages(report: dict) -> None:
    """The beat-sync comparison, the seed distance, the seed sets and the stage ablation of a report."""
    from dancekit.evaluation.ablation import format_seed_sets, format_stage_ablation

    if report.get("stage_ablation"):
        print("FID after each stage (the dances of the split danced again with the stages off, then finished):")
        print(format_stage_ablation(report["stage_ablation"]), end="")
    if report.get("seed_sets"):
        print(format_seed_sets(report["seed_sets"]), end="")
    bs = report.get("beat_sync")
    if bs:
        b, a = bs["before"], bs["after"]
        print(f"beat sync: BAS {b['bas_bailando']:.4f} -> {a['bas_bailando']:.4f}, beat hit rate "
              f"{b['beat_hit_rate']:.3f} -> {a['beat_hit_rate']:.3f} (before -> after the warp, {a['n_dances']} dances)")
    sd = report.get("seed_distance")
    if sd and sd.get("pairs", {}).get("seed"):
        conv = sd["converged_after_s"]
        when = "never" if conv is None else f"after {conv:g} s"
        print(f"seeds: mean pose distance between two seeds' dances {sd['seed_mean_cm']:.1f} cm "
              f"(after 2 s: {sd['seed_after_2s_cm']:.1f} cm), between two songs' dances {sd['song_mean_cm']:.1f} cm; "
              f"below half the between-song distance to the end: {when}")
