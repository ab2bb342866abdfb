"""Choose the default model's seed variety on the validation songs (issue 15). Never run on the test split.

For each setting, every validation song is danced with ``--seeds`` seeds exactly as ``dancekit evaluate``
dances it (genre read from the music, the genre model, clean-up and beat sync on), the seeds of a song in
one batch (one generator per row: the same draws as one call per seed), and the folder is scored with
``evaluate_dirs``: FID_k / FID_g, multimodality (style features) and the seed-to-seed distance.

    PYTHONPATH=src python benchmarks/tune_variety.py --data data/tang2018 --seeds 5 -o runs/tune_variety \\
        --grid "2:0.5:0" "4:1:0" "3:0:0.5" ...      # phrase_s:state_noise:latent_noise[:dance_latent[:style[:share]]]

``--genre-draw "τ:w[:s0[:ρ]]" ...`` (issue 15, third and fourth attempts) lets the seed draw the genre model (the
checkpoint's ``"sampling"`` keys ``genre_temperature`` τ, ``genre_alone`` w, ``genre_draw_seed0`` s0 ∈ {0, 1},
``genre_min_ratio`` ρ: only genres with p ≥ ρ · max p are drawn): every grid
setting is then danced once per draw setting through ``pipe.dances`` (what ``dancekit evaluate`` calls), and the
row records the genre each seed danced.

``--model FOLDER`` tunes another checkpoint than the embedded default (e.g. a fine-tuned candidate with a style
latent, ``style_dim > 0``: the 5th and 6th grid fields are the style temperature and its per-dance share).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from dancekit.data import PreparedData
from dancekit.evaluation.score import SAMPLE_SEP, evaluate_dirs
from dancekit.models.revolution import SeedVariety
from dancekit.motion import write_motion
from dancekit.motion.representations import decode_motion
from dancekit.pipelines import load_pipeline
from dancekit.pipelines.base import DanceResult, clean_motion
from dancekit.pipelines.revolution import GenreDraw
from dancekit.pipelines.stages import Song, finish


def dance_batch(pipe, path, *, seeds, start, end, variety, stages=True):
    """The seeds' dances of one song, as ``pipe(path, seed=k)`` with ``pipe.variety = variety``."""
    probs = pipe.read_genre(path, start=start, end=end)
    genre = max(probs, key=probs.get) if probs else None
    p = pipe.genre_pipeline(genre) if genre is not None and pipe.genre_models else pipe
    x = torch.from_numpy(p.features(path, start=start, end=end))[None].expand(len(seeds), -1, -1)
    gens = [torch.Generator().manual_seed(int(s)) for s in seeds]
    y = p.model.generate(x, generator=gens, variety=variety)
    out = []
    for k, seed in enumerate(seeds):
        motion = clean_motion(decode_motion(p.stats.denormalize_dance(y[k].numpy()), p.skeleton, p.fps,
                                            p.representation))
        res = DanceResult(motion=motion, model=pipe.folder, seed=int(seed), genre_requested="auto", genre=genre,
                          genre_probs=probs, danced_by=p.folder)
        config = pipe.stage_options(beat_sync=stages, cleanup=stages)
        out.append(finish(res, Song(path, start, end), config))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--seed-list", type=int, nargs="+", default=None,
                    help="dance these seeds (default: 0 .. SEEDS-1); the first is the one the between-song distance uses")
    ap.add_argument("--split", default="val")
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--clip", type=float, default=None, help="dance only the first CLIP seconds (openings)")
    ap.add_argument("--grid", nargs="+", default=["0:0:0"],
                    help="phrase_s:state_noise:latent_noise[:dance_latent[:style[:style_share]]]")
    ap.add_argument("--stages", choices=("on", "off"), default="on",
                    help="off: the model's raw dances (no clean-up, smoothing, foot lock, beat sync)")
    ap.add_argument("--genre-models", choices=("on", "off"), default="on",
                    help="off: the model itself dances every song (not its genre models)")
    ap.add_argument("--genre-draw", nargs="+", default=None,
                    help="τ:w[:s0[:ρ]] genre draws (genre_temperature, genre_alone, genre_draw_seed0, "
                         "genre_min_ratio); danced by pipe.dances")
    ap.add_argument("--model", default=None, help="checkpoint folder or embedded name (default: the default model)")
    args = ap.parse_args()
    if args.split == "test":
        raise SystemExit("tune on the validation songs; score the test split with dancekit evaluate")
    data = PreparedData(args.data)
    pipe = load_pipeline(args.model) if args.model else load_pipeline()
    if args.genre_models == "off":
        pipe.genre_models = {}
    out = Path(args.out)
    rows = []
    seed_list = list(range(args.seeds)) if args.seed_list is None else args.seed_list
    draws = [None] if args.genre_draw is None else args.genre_draw
    for spec, draw_spec in [(g, d) for g in args.grid for d in draws]:
        phrase_s, a, sigma, tau, style, share = ([float(v) for v in spec.split(":")] + [0.0] * 3)[:6]
        variety = SeedVariety(phrase=int(round(phrase_s * pipe.fps)), state_noise=a, latent_noise=sigma,
                              dance_latent=tau, style=style, style_share=share)
        label = spec if draw_spec is None else f"{spec}_g{draw_spec}"
        pred = out / label.replace(":", "_") / "pred"
        pred.mkdir(parents=True, exist_ok=True)
        drawn: dict[str, list] = {}
        t0 = time.perf_counter()
        for name in data.names(args.split):
            ref = data.audio(name)
            end = ref.end if args.clip is None else (ref.start or 0.0) + args.clip
            if draw_spec is None:
                results = dance_batch(pipe, ref.path, seeds=seed_list, start=ref.start, end=end,
                                      variety=variety, stages=args.stages == "on")
            else:
                g_tau, g_alone, g_s0, g_rho = ([float(v) for v in draw_spec.split(":")] + [0.0, 0.0])[:4]
                pipe.variety, pipe.genre_draw = variety, GenreDraw(temperature=g_tau, alone=g_alone,
                                                                   seed0=bool(g_s0), min_ratio=g_rho)
                results = pipe.dances(ref.path, seeds=seed_list, start=ref.start, end=end,
                                      beat_sync=args.stages == "on", cleanup=args.stages == "on")
                drawn[name] = [r.genre or "alone" for r in results]
            for k, res in enumerate(results):
                write_motion(pred / f"{name}{SAMPLE_SEP}{k}.npz", res.motion)
        gen_s = time.perf_counter() - t0
        rep = evaluate_dirs(pred, args.data, data=args.data, split=args.split)
        (pred.parent / "report.json").write_text(json.dumps(rep))
        sd = rep["seed_distance"]
        n = min(len(sd["seed_cm"]), len(sd["song_cm"]))
        ratio = np.asarray(sd["seed_cm"][:n]) / np.maximum(np.asarray(sd["song_cm"][:n]), 1e-9)
        row = {"spec": label, "genres_danced": drawn, "model": args.model or "default", "stages": args.stages, "genre_models": args.genre_models, "fid_k": rep["metrics"]["fid_k"] if "metrics" in rep else rep.get("fid_k"),
               "gen_s": round(gen_s, 1)}
        flat = rep.get("metrics", rep)
        for key in ("fid_k", "fid_g", "style_multimodality", "style_diversity", "style_fid", "style_acc",
                    "jitter_speed_ratio", "foot_skating_ratio", "stillness_share", "smoothed_energy_ratio",
                    "bas_bailando"):
            row[key] = flat.get(key)
        row.update(seed_mean_cm=sd["seed_mean_cm"], song_mean_cm=sd["song_mean_cm"],
                   seed_over_song_min=float(ratio.min()) if n else None,
                   seconds_below_half=int((ratio < 0.5).sum()), seconds=n,
                   converged_after_s=sd["converged_after_s"])
        rows.append(row)
        print(json.dumps(row), flush=True)
        (out / "rows.jsonl").open("a").write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
