"""Score a Music2Dance model on a split with the prepared dataset's music features (no audio decoding).

    PYTHONPATH=src python benchmarks/m2d_eval_prepared.py music2dance runs/ev_m2d --split test --seeds 5 --genre true
    PYTHONPATH=src python benchmarks/m2d_eval_prepared.py music2dance runs/steer_m2d --steering

``dancekit evaluate --checkpoint`` extracts each song's features from its audio file, which dominated the
time on the loaded shared machine (about 8 CPU-s for 10 s of mp3 against 0.8 CPU-s for the five dances).
This script dances the same slices of the same songs from the prepared ``features_music2dance.npz`` (the
same preset and fps, computed by ``dancekit prepare`` from the same audio), writes ``OUT/pred/NAME__k.npz``
and scores them with :func:`dancekit.evaluation.evaluate_dirs` exactly as ``dancekit evaluate --pred`` does
(``OUT/report.json``). ``--steering``: every song danced as every genre (seed 0) and read back by the style
classifier, as ``dancekit steering`` does (``OUT/steering.json``). ``--foot-constraint``: the dances are
post-processed by the embedded foot model first.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from dancekit.data import PreparedData
from dancekit.evaluation import evaluate_dirs
from dancekit.evaluation.generate import requested_genre
from dancekit.evaluation.score import SAMPLE_SEP
from dancekit.motion import write_motion
from dancekit.pipelines.music2dance import Music2DancePipeline


class PreparedPipe:
    """A Music2Dance pipeline whose songs are the dataset's dances: ``dances(path, start=...)`` takes the
    prepared features of the dance whose audio slice that is."""

    def __init__(self, pipe: Music2DancePipeline, data: PreparedData, split: str, genre_scale: float | None = None,
                 temperature: float | None = None):
        self.pipe, self.data, self.genres = pipe, data, pipe.genres
        self.genre_scale, self.temperature = genre_scale, temperature
        self.by_audio = {}
        for n in data.names(split):
            a = data.audio(n)
            self.by_audio[(str(a.path), a.start)] = n

    def dances(self, path, *, seeds, genre=None, start=None, end=None):
        name = self.by_audio[(str(path), start)]
        music = self.data.features(name, self.pipe.preset)["features"]
        return self.pipe.dances(path, seeds=list(seeds), genre=genre, music=music, genre_scale=self.genre_scale,
                                temperature=self.temperature)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("model")
    p.add_argument("out")
    p.add_argument("--data", default="data/tang2018")
    p.add_argument("--split", default="test")
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--genre", default="true", help="true (each song's own genre), none, or a genre name")
    p.add_argument("--steering", action="store_true")
    p.add_argument("--foot-constraint", action="store_true")
    p.add_argument("--genre-scale", type=float, default=None, help="guidance of the dance type (default: the "
                   "checkpoint's)")
    p.add_argument("--temperature", type=float, default=None, help="sampling temperature (default: the checkpoint's)")
    p.add_argument("--steer-seeds", type=int, default=1, help="--steering: dances per (song, genre) pair")
    p.add_argument("--sampling", default=None, metavar="JSON",
                   help='sampling settings instead of the checkpoint\'s, e.g. \'{"temperature": 0.8, '
                        '"noise_correlation": 0.95, "smooth_sigma": 2}\' (the embedded model\'s, for a run '
                        'folder that has none)')
    args = p.parse_args()
    torch.set_num_threads(1)
    data = PreparedData(args.data)
    m2d = Music2DancePipeline.from_pretrained(args.model)
    for key, value in json.loads(args.sampling or "{}").items():
        if key not in ("temperature", "noise_correlation", "smooth_sigma", "genre_scale"):
            raise SystemExit(f"--sampling: unknown setting {key!r}")
        setattr(m2d, key, float(value))
    pipe = PreparedPipe(m2d, data, args.split, genre_scale=args.genre_scale, temperature=args.temperature)
    out = Path(args.out)
    t0 = time.perf_counter()
    if args.steering:
        from dancekit.evaluation.steering import steering
        from dancekit.pipelines import StylePipeline

        report = steering(pipe, data, StylePipeline.from_pretrained("style"), split=args.split, seeds=args.steer_seeds,
                          progress=False)
        report["genre_scale"] = pipe.pipe.genre_scale if args.genre_scale is None else args.genre_scale
        out.mkdir(parents=True, exist_ok=True)
        (out / "steering.json").write_text(json.dumps(report, indent=1))
        print(f"read back {report['read_back']:.3f} of {report['n']} (song, genre) pairs; "
              f"{time.perf_counter() - t0:.0f} s", report["read_back_per_genre"])
        return
    fix = None
    if args.foot_constraint:
        from dancekit.pipelines.foot_constraint import load_foot_constraint

        fix = load_foot_constraint()
    pred = out / "pred"
    pred.mkdir(parents=True, exist_ok=True)
    for name in data.names(args.split):
        a = data.audio(name)
        rows = pipe.dances(a.path, seeds=range(args.seeds), genre=requested_genre(args.genre, data.genre(name)),
                           start=a.start, end=a.end)
        for k, r in enumerate(rows):
            motion = r.motion if fix is None else fix(r.motion)
            write_motion(pred / (f"{name}{SAMPLE_SEP}{k}.npz" if args.seeds > 1 else f"{name}.npz"), motion)
    gen = time.perf_counter() - t0
    report = evaluate_dirs(pred, args.data, data=args.data, split=args.split)
    report["generation"] = {"checkpoint": args.model, "split": args.split, "seeds": args.seeds, "genre": args.genre,
                            "features": "prepared", "foot_constraint": bool(fix), "elapsed_s": round(gen, 1),
                            "sampling": {k: getattr(m2d, k) for k in ("temperature", "noise_correlation",
                                                                     "smooth_sigma", "genre_scale")},
                            "genre_sampling": m2d.genre_sampling}
    (out / "report.json").write_text(json.dumps(report, indent=1))
    m = report["metrics"]
    print(f"{args.model} {args.split}: generated in {gen:.0f} s; " + ", ".join(
        f"{k} {m[k]:.4g}" for k in ("fid_k", "fid_g", "stillness_share", "smoothed_energy_ratio",
                                    "jitter_speed_ratio", "foot_skating_ratio", "style_acc",
                                    "style_multimodality", "bas_bailando")))


if __name__ == "__main__":
    main()
