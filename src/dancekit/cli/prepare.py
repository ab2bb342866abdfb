"""``dancekit prepare tang2018|pairs|aistpp|online SRC -o DIR``: paired dataset preparation.

``online``: a copy of a prepared dataset ``SRC`` with its features as a live session computes them
(:mod:`dancekit.data.online`), to train a model for ``dancekit live``.

``pairs``: a folder of the user's songs and motion files paired by name (:mod:`dancekit.data.pairs`);
``aistpp``: the AIST++ release layout (:mod:`dancekit.data.aistpp`). Broken or unmatched files are skipped
and listed in ``DIR/report.json`` and on stdout.
"""

from __future__ import annotations

import argparse
import time


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "prepare",
        help="prepare a paired music+dance dataset for training and evaluation",
        description="Write aligned music features (every preset), motion (positions + IK rotations), "
        "genre labels and whole-dance train/val/test splits.",
    )
    p.add_argument("source", choices=["tang2018", "pairs", "aistpp", "online"],
                   help="dataset kind: tang2018; pairs (songs + npz/BVH/AIST++ pkl/OpenPose motions paired by name); "
                        "aistpp (the AIST++ release: motions/*.pkl, wavs/, splits/, ignore_list.txt); online (a "
                        "prepared dataset copied with --presets' features as `dancekit live` computes them; default "
                        "preset revolution)")
    p.add_argument("src", help="source folder (e.g. ../shared/data/tang2018)")
    p.add_argument("-o", "--out", required=True, help="output folder (replaced when complete)")
    p.add_argument("--fps", type=float, default=25.0, help="motion and feature frame rate (default 25)")
    p.add_argument("--presets", default=None,
                   help="comma-separated feature presets (default revolution,music2dance,dual; online: revolution)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split (default 0)")
    p.add_argument("--workers", type=int, default=1,
                   help="pairs, aistpp, online: processes preparing pairs (default 1)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dancekit.data import PreparedData, prepare_tang2018

    t0 = time.perf_counter()
    default = "revolution" if args.source == "online" else "revolution,music2dance,dual"
    presets = tuple(p.strip() for p in (args.presets or default).split(",") if p.strip())
    report = None
    if args.source == "online":
        from dancekit.data.online import prepare_online

        if args.fps != 25.0:
            from dancekit.errors import ParameterError

            raise ParameterError("--fps does not apply to `prepare online` (the source dataset's rate is kept)")
        out = prepare_online(args.src, args.out, presets=presets, workers=args.workers)
    elif args.source == "pairs":
        from dancekit.data.pairs import prepare_pairs

        out, report = prepare_pairs(args.src, args.out, fps=args.fps, presets=presets, seed=args.seed,
                                    workers=args.workers)
    elif args.source == "aistpp":
        from dancekit.data.aistpp import prepare_aistpp

        out, report = prepare_aistpp(args.src, args.out, fps=args.fps, presets=presets, workers=args.workers)
    else:
        out = prepare_tang2018(args.src, args.out, fps=args.fps, presets=presets, seed=args.seed)
    data = PreparedData(out)
    sizes = ", ".join(f"{k} {len(data.names(k))}" for k in ("train", "val", "test"))
    print(f"prepared {len(data.names())} dances into {out} ({sizes}) in {time.perf_counter() - t0:.1f} s")
    if report is not None and report["skipped"]:
        print(f"skipped {len(report['skipped'])} (listed in {out / 'report.json'}):")
        for item in report["skipped"]:
            print(f"  {item['file']}: {item['reason']}")
    return 0
