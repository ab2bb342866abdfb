"""Choose a pipeline stage's settings on the validation songs: one script, one sub-command per stage.

    PYTHONPATH=src:benchmarks python benchmarks/tune.py STAGE ARGS...

STAGE (each one's own help below and in its function's docstring):

- ``stages``    the warp's pair-rate bound and maximum shift, and the ground-contact window
- ``beatsync``  beat-warp variants on cached raw dances (why kinematic beats miss, and a grid)
- ``variety``   the default model's seed variety and genre draw (``"sampling"``)
- ``candidate`` a candidate checkpoint folder: a model folder with some ``config.json`` entries overridden

Every setting is a configuration override of an embedded model (a candidate folder, ``candidate``: its
``"stages"`` / ``"sampling"`` entries, checked by the typed stage configuration when the folder is loaded) or the
typed stage configuration passed to ``finish``; the raw dances of ``beatsync`` come from
``benchmarks/feet_dances.py``. Settings are chosen on ``val``; the test split is scored once with ``dancekit
evaluate``. This script replaces tune_stages.py, tune_beatsync.py, tune_variety.py and candidate_folder.py
(read at 264b8a3), with the same arguments after the stage name; the decided foot-lock and energy studies are read
at 264b8a3:benchmarks/tune_footlock.py and 264b8a3:benchmarks/tune_energy.py.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages
import numpy as np
import torch

from dancekit.checkpoints.hub import resolve_model
from dancekit.data import PreparedData
from dancekit.evaluation.score import SAMPLE_SEP, evaluate_dirs
from dancekit.metrics import jitter
from dancekit.metrics.beat import beat_metrics, kinematic_beats
from dancekit.models.revolution import SeedVariety
from dancekit.motion import get_skeleton, write_motion
from dancekit.motion.cleanup import contain_root_path, ground_contact
from dancekit.motion.representations import decode_motion
from dancekit.motion.timewarp import beat_warp, warp_bones, warp_motion
from dancekit.pipelines import load_pipeline, stages
from dancekit.pipelines.base import DanceResult, clean_motion
from dancekit.pipelines.config import read_stage_config
from dancekit.pipelines.revolution import GenreDraw
from dancekit.pipelines.stages import Song
from dancekit.pipelines.stages import finish as stages_finish

SK = get_skeleton("tang2018")
FPS = 25.0


# --- candidate: formerly candidate_folder.py ----------------------------------------------------------------
def candidate_folder(model: str, dst: str | Path, change: dict, *, merge: bool = True) -> Path:
    """``dst``: the folder of ``model`` (a name or a folder) with ``change`` applied to its ``config.json`` (each
    top-level object merged into the entry of that name, ``null`` inside it deleting a key; ``merge=False``:
    each entry replaced whole; a top-level ``null`` deletes the entry) and every other file linked."""
    src, dst = Path(resolve_model(model)), Path(dst)
    dst.mkdir(parents=True, exist_ok=False)
    for item in src.iterdir():
        if item.name != "config.json":
            (dst / item.name).symlink_to(item.resolve())
    config = json.loads((src / "config.json").read_text())
    for key, value in change.items():
        if merge and isinstance(value, dict) and isinstance(config.get(key), dict):
            merged = {**config[key], **value}
            config[key] = {k: v for k, v in merged.items() if v is not None}
        elif value is None:
            config.pop(key, None)
        else:
            config[key] = value
    (dst / "config.json").write_text(json.dumps(config, indent=2))
    return dst


def candidate_main() -> None:
    """A candidate checkpoint folder: a model folder with some ``config.json`` entries changed, every other file
linked (nothing copied but the config), for `dancekit evaluate --checkpoint FOLDER` on a grid of settings.

    PYTHONPATH=src python benchmarks/tune.py candidate revolution /tmp/cand1 \
        '{"sampling": {"genre_temperature": 2, "genre_alone": 0.25, "jitter_cap": 1.0}}'

The JSON's top-level objects are merged into the folder's entries of the same name (``null`` deletes a key).
    """
    dst = candidate_folder(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]))
    print(dst, json.dumps(json.loads((dst / "config.json").read_text()).get("sampling")))


# --- stages: formerly tune_stages.py ------------------------------------------------------------------------
def stages_main() -> None:
    """Choose the stage settings on the validation songs (issue 15): the warp's pair-rate bound and maximum
shift, and the ground-contact window. Never run on the test split.

    PYTHONPATH=src python benchmarks/tune.py stages --data data/tang2018 --seeds 3
    """
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    data = PreparedData(args.data)
    pipe = load_pipeline()
    sk, fps = pipe.skeleton, pipe.fps
    dances = []
    for name in data.names("val"):
        ref = data.audio(name)
        beats = stages.song_beats_for(ref.path, start=ref.start, end=ref.end)
        for k in range(args.seeds):
            raw = pipe(ref.path, seed=k, start=ref.start, end=ref.end, beat_sync=False, cleanup=False)
            dances.append((np.asarray(raw.motion.to_positions(), np.float64), beats.times))
    real = [bench_stages.physical(np.asarray(data.motion(n).to_positions(), np.float64), sk, fps)
            for n in data.names("val")]
    print("real val: floor median {:.2f} cm, within 2 cm {:.3f}".format(np.mean([r["floor_median_cm"] for r in real]),
                                                               np.mean([r["floor_within_2cm"] for r in real])))
    for window in (0.2, 0.3, 0.5):
        rows = [bench_stages.physical(ground_contact(contain_root_path(p, skeleton=sk, fps=fps), skeleton=sk,
                                                     fps=fps, window_s=window), sk, fps) for p, _ in dances]
        print("ground window {:.1f} s: floor median {:.2f} cm, within 2 cm {:.3f}".format(
            window, np.mean([r["floor_median_cm"] for r in rows]), np.mean([r["floor_within_2cm"] for r in rows])))
    cleaned = [(ground_contact(contain_root_path(p, skeleton=sk, fps=fps), skeleton=sk, fps=fps), b) for p, b in dances]
    base = [beat_metrics(p, b, fps=fps) for p, b in cleaned]
    jerk0 = np.mean([jitter(p, fps=fps, skeleton=sk)["jerk"] for p, _ in cleaned])
    print("unwarped: BAS {:.3f} hit {:.3f} jerk {:.1f}".format(np.mean([r["bas_bailando"] for r in base]),
                                                    np.mean([r["beat_hit_rate"] for r in base]), jerk0))
    for prc in (0.10, 0.13, 0.145):
        for shift in (0.4, 0.6, 1.0):
            out, jerks = [], []
            for p, b in cleaned:
                s, _ = beat_warp(p, music_beats=b, fps=fps, pair_rate_change=prc, max_shift=shift)
                w = warp_bones(p, skeleton=sk, source_frames=s)
                out.append(beat_metrics(w, b, fps=fps))
                jerks.append(jitter(w, fps=fps, skeleton=sk)["jerk"])
            print("pair bound {:.3f}, max shift {:.1f} s: BAS {:.3f} hit {:.3f} jerk {:.1f}".format(
                prc, shift, np.mean([r["bas_bailando"] for r in out]), np.mean([r["beat_hit_rate"] for r in out]),
                np.mean(jerks)), flush=True)


def where_beats(kin: np.ndarray, music: np.ndarray) -> dict[str, float]:
    """Where the kinematic beats of an unwarped dance lie against the music beats: the share within 0.1 s of a
    beat, the share nearer a half-beat than a beat, kinematic beats per music beat interval."""
    m = music[(music >= 0) & (music <= kin.max() + 1.0)] if len(kin) else music
    if len(kin) == 0 or len(m) < 2:
        return {"near": np.nan, "half": np.nan, "per_beat": np.nan}
    i = np.clip(np.searchsorted(m, kin) - 1, 0, len(m) - 2)
    phase = (kin - m[i]) / (m[i + 1] - m[i])  # 0 … 1 within the beat interval
    d = np.minimum(np.abs(kin[:, None] - m[None]).min(axis=1), 9.0)
    return {"near": float(np.mean(d <= 0.1)), "half": float(np.mean(np.abs(phase - 0.5) < 0.25)),
            "per_beat": len(kin) / max(len(m) - 1, 1)}


def beatsync_main() -> None:
    """Beat-sync settings on cached dances (issue 15, beat hit rate ≥ 0.6): why kinematic beats miss, and a grid.

    PYTHONPATH=src:benchmarks python benchmarks/tune.py beatsync music2dance val \
        '{"today": {}, "shift 0.4": {"max_shift": 0.4}}'

Arguments: model (an embedded model: its checkpoint's stages are applied as the pipeline does, the warp
excepted), split (val / test / song), a JSON object ``name -> beat_warp keyword arguments`` (``max_rate_change``,
``pair_rate_change``, ``max_shift``, ``smooth``, ``smooth_s``, ``between_tolerance``, ``max_rate_step``; ``null``
for the warp off), optionally ``--stage``: the variants
are ignored and the dances go through ``stages.finish`` as the pipeline runs it (the checkpoint's ``"beat_sync"``
entry read), next to beat sync off; ``--per-song``: also BAS, hit rate and jerk per song; ``--raw DIR``: the
dances' folder (default ``runs/feet_raw``); ``--json OUT``: every figure, unrounded, to ``OUT``. Dances: ``DIR/<model>/<split>/`` of ``benchmarks/feet_dances.py``.
Per variant: BAS, beat hit rate, kinematic beats per music beat, the share of kinematic beats matched by the warp,
mean jerk, foot skating, FID_k / FID_g against the training dances, the warp's rate steps (share of frames whose
rate changes by more than 1 % and 2 % from the frame before, the largest change); and for the unwarped dances where their
kinematic beats lie (the diagnosis). Choose settings on ``val`` only.
    """
    model, split = sys.argv[1], sys.argv[2]
    use_stage = "--stage" in sys.argv
    per_song = "--per-song" in sys.argv
    variants = {"stage": "stage"} if use_stage else json.loads(sys.argv[3])
    raw = sys.argv[sys.argv.index("--raw") + 1] if "--raw" in sys.argv else "runs/feet_raw"
    data = PreparedData("data/tang2018")
    files = sorted(Path(f"{raw}/{model}/{split}").glob("*__*.npz"))
    audio = bench_feet.song_audio(data, split)
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")]
    folder = bench_feet.model_folder(model)
    t0 = time.process_time()
    pre, beats = {}, {}
    for f in files:
        song = f.stem.rsplit("__", 1)[0]
        a = audio[song]
        if song not in beats:
            beats[song] = stages.song_beats_for(a[0], start=a[1], end=a[2])
        res = DanceResult(motion=bench_feet.load(f, SK), model=folder, seed=0)
        pre[f] = stages.finish(res, stages.Song(a[0], a[1], a[2]), read_stage_config(folder).switched(beat_sync=False))
    print(f"{model} {split}: {len(files)} dances, stages before the warp {time.process_time() - t0:.0f} s CPU", flush=True)
    diag = [where_beats(kinematic_beats(np.asarray(r.motion.to_positions(), np.float64), fps=FPS),
                        beats[f.stem.rsplit("__", 1)[0]].times) for f, r in pre.items()]
    print("unwarped kinematic beats: within 0.1 s of a beat {:.3f}, nearer the half-beat {:.3f}, per beat interval "
          "{:.2f}".format(*(np.nanmean([d[k] for d in diag]) for k in ("near", "half", "per_beat"))), flush=True)
    rows_out = {}
    for name, v in ({"off": None} | variants).items():
        t1 = time.process_time()
        rows, pos, matched, songs, steps = [], [], [], [], []
        for f, res in pre.items():
            song = f.stem.rsplit("__", 1)[0]
            b = beats[song]
            if v == "stage":
                a = audio[song]
                res = stages.beat_sync(res, a[0], start=a[1], end=a[2], beats=b)
            elif v is not None and b.has_beat:
                p = np.asarray(res.motion.to_positions(), np.float64)
                source, pairs = beat_warp(p, music_beats=b.times, fps=FPS, **v)
                n_k = len(kinematic_beats(p, fps=FPS, smooth=v.get("smooth")))
                matched.append(len(pairs) / max(n_k, 1))
                steps.append(np.abs(np.diff(source, 2)))  # the rate's change per frame
                if len(pairs):
                    res = DanceResult(motion=warp_motion(res.motion, source_frames=source), model=res.model, seed=0)
            p = np.asarray(res.motion.to_positions(), np.float64)
            row = bench_stages.dance_row(res.motion, None)
            bm = beat_metrics(p, b.times, fps=FPS, skeleton=SK)
            row.update(bas=bm["bas_bailando"], hit_rate=bm["beat_hit_rate"], coverage=bm["beat_coverage"])
            songs.append(song)
            rows.append(row)
            pos.append(p)
        m = bench_stages.mean_rows(rows)
        fd = bench_stages.fids(pos, reference, FPS, SK)
        st = np.concatenate(steps) if steps else np.zeros(0)
        out = {"bas": m["bas"], "hit": m["hit_rate"], "coverage": m["coverage"], "jerk": m["jerk"],
               "skating": m["foot_skating"], **fd, "matched": float(np.mean(matched)) if matched else np.nan,
               # rate steps (|rate[t+1] - rate[t]|, over every frame of the warped dances): share above 1 % and
               # 2 % per frame (1e-6 of slack: a step held at the bound counts as at it), the largest
               "step1": float(np.mean(st > 0.01 + 1e-6)) if len(st) else np.nan,
               "step2": float(np.mean(st > 0.02 + 1e-6)) if len(st) else np.nan,
               "stepmax": float(st.max()) if len(st) else np.nan}
        rows_out[name] = out
        print(f"{name:28s} BAS {out['bas']:.3f} hit {out['hit']:.3f} kin/music {out['coverage']:.2f} "
              f"matched {out['matched']:.2f} jerk {out['jerk']:.2f} skate {out['skating']:.4f} "
              f"FID_k {out['fid_k']:.2f} FID_g {out['fid_g']:.2f} steps>1% {out['step1']:.4f} >2% {out['step2']:.4f} "
              f"max {out['stepmax']:.4f} cpu {time.process_time() - t1:.0f}s", flush=True)
        if per_song:
            for song in dict.fromkeys(songs):
                ms = bench_stages.mean_rows([r for r, s in zip(rows, songs, strict=True) if s == song])
                print(f"    {song:26s} BAS {ms['bas']:.3f} hit {ms['hit_rate']:.3f} jerk {ms['jerk']:.2f}", flush=True)
    off = rows_out["off"]
    for name, out in rows_out.items():
        if name != "off":
            print(f"{name:28s} vs off: " + " ".join(f"{k} {100 * (out[k] / off[k] - 1):+.1f}%"
                                                    for k in ("fid_k", "fid_g", "jerk", "skating")))
    if "--json" in sys.argv:  # every figure unrounded
        Path(sys.argv[sys.argv.index("--json") + 1]).write_text(json.dumps(rows_out, indent=1))


# --- variety: formerly tune_variety.py ----------------------------------------------------------------------
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
        out.append(stages_finish(res, Song(path, start, end), config))
    return out


def variety_main() -> None:
    """Choose the default model's seed variety on the validation songs (issue 15). Never run on the test split.

For each setting, every validation song is danced with ``--seeds`` seeds exactly as ``dancekit evaluate``
dances it (genre read from the music, the genre model, clean-up and beat sync on), the seeds of a song in
one batch (one generator per row: the same draws as one call per seed), and the folder is scored with
``evaluate_dirs``: FID_k / FID_g, multimodality (style features) and the seed-to-seed distance.

    PYTHONPATH=src python benchmarks/tune.py variety --data data/tang2018 --seeds 5 -o runs/tune_variety \\
        --grid "2:0.5:0" "4:1:0" "3:0:0.5" ...      # phrase_s:state_noise:latent_noise[:dance_latent[:style[:share]]]

``--genre-draw "τ:w[:s0[:ρ]]" ...`` (issue 15, third and fourth attempts) lets the seed draw the genre model (the
checkpoint's ``"sampling"`` keys ``genre_temperature`` τ, ``genre_alone`` w, ``genre_draw_seed0`` s0 ∈ {0, 1},
``genre_min_ratio`` ρ: only genres with p ≥ ρ · max p are drawn): every grid
setting is then danced once per draw setting through ``pipe.dances`` (what ``dancekit evaluate`` calls), and the
row records the genre each seed danced.

``--model FOLDER`` tunes another checkpoint than the embedded default (e.g. a fine-tuned candidate with a style
latent, ``style_dim > 0``: the 5th and 6th grid fields are the style temperature and its per-dance share).
    """
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


COMMANDS = {"stages": stages_main, "beatsync": beatsync_main, "variety": variety_main, "candidate": candidate_main}


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        sys.exit(f"usage: tune.py {{{','.join(COMMANDS)}}} ARGS... (see benchmarks/tune.py)")
    stage = sys.argv.pop(1)
    sys.argv[0] = f"tune.py {stage}"
    COMMANDS[stage]()


if __name__ == "__main__":
    main()
