"""Stall screen: does a genre model's decoder stand still on some songs? (issue 15, twelfth session)

    PYTHONPATH=src python benchmarks/genre_stall_screen.py runs/m/ck_L19 revolution --data data/tang2018 \
        --split val [--genres waltz,rumba,chacha,tango,none] [--seeds 5] [--bound 0.2]

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
``--bound`` (default 0.2).
"""

from __future__ import annotations

import argparse

from dancekit.data import PreparedData
from dancekit.metrics.stability import stillness_share
from dancekit.pipelines import load_pipeline


def raw_stillness(pipe, data: PreparedData, name: str, *, genre: str, seeds: int) -> list[float]:
    """Stillness share of the raw decoder output of seeds 0..seeds-1 on the song of dance ``name``."""
    ref = data.audio(name)
    results = pipe.dances(ref.path, seeds=list(range(seeds)), start=ref.start, end=ref.end, genre=genre,
                          cleanup=False, beat_sync=False)  # the decoder's output, no stage run
    return [stillness_share(r.motion.to_positions(), fps=r.motion.fps, skeleton=r.motion.skeleton) for r in results]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoints", nargs="+", help="checkpoint folders or model names")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    ap.add_argument("--genres", default="waltz,rumba,chacha,tango,none")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--bound", type=float, default=0.2)
    args = ap.parse_args()
    data = PreparedData(args.data)
    names = data.names(args.split)
    for ck in args.checkpoints:
        pipe = load_pipeline(ck)
        for genre in args.genres.split(","):
            if genre != "none" and genre not in pipe.genres:
                continue
            rows = {n: raw_stillness(pipe, data, n, genre=genre, seeds=args.seeds) for n in names}
            worst = max(max(v) for v in rows.values())
            songs = " | ".join(f"{n.removeprefix('DANCE_')} " + "/".join(f"{x:.2f}" for x in v) for n, v in rows.items())
            verdict = "stalls" if worst > args.bound else "ok"
            print(f"{ck} {genre:6s} worst {worst:.2f} {verdict}: {songs}")


if __name__ == "__main__":
    main()
