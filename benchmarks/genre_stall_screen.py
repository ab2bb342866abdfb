"""Stall screen: does a genre model's decoder stand still on some songs? (issue 15, twelfth session)

    PYTHONPATH=src python benchmarks/genre_stall_screen.py runs/m/ck_L19 revolution --data data/tang2018 \
        --split val [--genres waltz,rumba,chacha,tango,none] [--seeds 5] [--bound 0.2] [--fid] [--skip DANCE_W_11]

For every checkpoint, every genre model (``none``: the base model alone) is forced on every song of the split
(``genre=G``) for seeds 0..N-1, and the **raw decoder output** (``cleanup=False, beat_sync=False``: none of
the pipeline's stages, the clean-up, smoothing, energy lift, foot lock or warp, is run) is scored by its
stillness share (1-s windows whose mean body-relative joint speed is under 0.10 m/s,
:func:`dancekit.metrics.stability.stillness_share`).

Why: a fine-tuned genre model can settle into a still pose on a song it does not know and stay there for most of
the song (the larger model's 400-step fine-tunes: 0.86 of the windows still on a validation song, 0.91-0.93 on
test songs). The pipeline's
stages hide part of it (the energy lift and the foot lock add motion), so the finished dances show it as a few
per cent of stillness on one seed, which looks like noise on 5 validation songs. Forcing every genre model on
every song shows it directly. The default's genre models never exceed 0.14 here on the validation and test songs.

Prints one line per (checkpoint, genre): each song's stillness per seed, the worst value and a verdict against
``--bound`` (default 0.2). With ``--fid``, also the finished dances (every default stage) of the same forced genre
and seeds: FID_k / FID_g against the split ``train`` of ``--data`` (10-s segments), pooled and per song (FID_g).
``--skip`` leaves songs out (the thirteenth session left out W_11, which the base dances alone).

The thirteenth session's held-out check (round 27) ran it on a copy of the prepared data whose ``splits.json``
moves six training waltzes to ``val`` (``data/cvw``), for waltz models fine-tuned without them:

    PYTHONPATH=src python benchmarks/genre_stall_screen.py runs/cv/ck_l20r --data data/cvw --split val \
        --genres waltz --fid
"""

from __future__ import annotations

import argparse

import bench_stages  # benchmarks/ is on the path when run as a script
import numpy as np

from dancekit.data import PreparedData
from dancekit.metrics.stability import stillness_share
from dancekit.pipelines import load_pipeline


def raw_stillness(pipe, data: PreparedData, name: str, *, genre: str, seeds: int) -> list[float]:
    """Stillness share of the raw decoder output of seeds 0..seeds-1 on the song of dance ``name``."""
    ref = data.audio(name)
    results = pipe.dances(ref.path, seeds=list(range(seeds)), start=ref.start, end=ref.end, genre=genre,
                          cleanup=False, beat_sync=False)  # the decoder's output, no stage run
    return [stillness_share(r.motion.to_positions(), fps=r.motion.fps, skeleton=r.motion.skeleton) for r in results]


def forced_fid(pipe, data: PreparedData, names: list[str], ref_p: list[np.ndarray], *, genre: str, seeds: int,
               cache: dict) -> tuple[dict[str, float], dict[str, float]]:
    """Pooled FID_k / FID_g and per-song FID_g of the finished dances (every default stage) of ``genre`` forced
    on the songs ``names``, seeds 0..seeds-1, against ``ref_p`` (the ``train`` split's dances, ``(T, J, 3)``
    each; 10-s segments). ``cache`` keeps the reference's feature sets between calls."""
    sk, fps = data.skeleton, data.fps
    pooled, per = [], {}
    for n in names:
        a = data.audio(n)
        ps = [np.asarray(r.motion.to_positions())
              for r in pipe.dances(a.path, seeds=list(range(seeds)), start=a.start, end=a.end, genre=genre)]
        pooled += ps
        per[n] = bench_stages.fids(ps, ref_p, fps, sk, cache)["fid_g"]
    return bench_stages.fids(pooled, ref_p, fps, sk, cache), per


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoints", nargs="+", help="checkpoint folders or model names")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    ap.add_argument("--genres", default="waltz,rumba,chacha,tango,none")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--bound", type=float, default=0.2)
    ap.add_argument("--fid", action="store_true", help="also FID of the finished forced-genre dances")
    ap.add_argument("--skip", action="append", default=[], help="a dance name to leave out (repeatable)")
    args = ap.parse_args()
    data = PreparedData(args.data)
    names = [n for n in data.names(args.split) if n not in args.skip]
    cache: dict = {}
    ref_p = [np.asarray(data.motion(n).to_positions()) for n in data.names("train")] if args.fid else []
    for ck in args.checkpoints:
        pipe = load_pipeline(ck)
        for genre in args.genres.split(","):
            if genre != "none" and genre not in pipe.genres:
                continue
            rows = {n: raw_stillness(pipe, data, n, genre=genre, seeds=args.seeds) for n in names}
            worst = max(max(v) for v in rows.values())
            songs = " | ".join(f"{n.removeprefix('DANCE_')} " + "/".join(f"{x:.2f}" for x in v) for n, v in rows.items())
            verdict = "stalls" if worst > args.bound else "ok"
            print(f"{ck} {genre:6s} worst {worst:.2f} {verdict}: {songs}", flush=True)
            if args.fid:
                f, per = forced_fid(pipe, data, names, ref_p, genre=genre, seeds=args.seeds, cache=cache)
                print(f"{ck} {genre:6s} forced FID_k {f['fid_k']:.2f} FID_g {f['fid_g']:.2f}; per song FID_g "
                      + " ".join(f"{n.removeprefix('DANCE_')} {v:.1f}" for n, v in per.items()), flush=True)


if __name__ == "__main__":
    main()
