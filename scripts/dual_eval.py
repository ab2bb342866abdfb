"""Evaluation helpers of the dual-learning model (docs/DUAL.md): choices on validation, composing on test.

    python scripts/dual_eval.py beats --data data/tang2018 --split val CKPT [CKPT ...]
    python scripts/dual_eval.py compose --data data/tang2018 --split test CKPT -o runs/dual/compose_test
    python scripts/dual_eval.py dance --data data/tang2018 --split val CKPT [CKPT ...]
    python scripts/dual_eval.py diversity --split test CKPT_OR_PRED_DIR [...] --max-frames N
    python scripts/dual_eval.py diversity-ref --split test --max-frames N
    python scripts/dual_eval.py excerpts --split test CKPT --seconds 30 -o runs/ab/x_NAME

``beats``: G_D→M composes chroma + beats for every dance of the split (seed 0); for each beat-picking threshold,
the beat F1 (±0.1 s, mir_eval) of the picked beats against the real music's beats, the composed tempo
against the real tempo, and the notes accuracy of the composed chroma (dual paper) against the real chroma.
``compose``: the same on the split with the chosen threshold, plus the share of the dance's kinematic beats
within 0.1 s of the composed beats next to the same share for the real music, MIDI + WAV written per dance.
``dance``: G_M→D dances for every song of the split (seed 0): stillness, energy and jitter ratios against the
real dance (the issue's no-freezing criteria).
``diversity``: the dual paper's diversity over 5 start poses (and with the root subtracted); ``diversity-ref``:
the same measure for the real dances and the random_train baseline; ``excerpts``: Table 4 at a reduced budget
(5 start poses on the first seconds of each song, for ``dancekit evaluate --pred``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def _real_music(data, name):
    f = data.features(name, "dual")
    feats = np.asarray(f["features"], np.float64)
    return feats[:, 40:52], feats[:, 52], np.asarray(f["beat_times"], np.float64)


def _compose_all(ckpt, data, split, seed=0, max_frames=None):
    from dancekit.pipelines.dual import ComposePipeline

    pipe = ComposePipeline.from_pretrained(ckpt)
    out = {}
    for name in data.names(split):
        motion = data.motion(name)
        if max_frames:
            motion = motion.slice(0, max_frames)
        res = pipe(motion, seed=seed)
        out[name] = res
    return pipe, out


def _chroma_top1(chroma_pred, chroma_real):
    """Share of frames whose strongest pitch class matches the real music's."""
    n = min(len(chroma_pred), len(chroma_real))
    return float(np.mean(np.argmax(chroma_pred[:n], 1) == np.argmax(chroma_real[:n], 1)))


def _notes_accuracy(res, chroma_real, beat_real):
    """The dual paper's notes accuracy (:func:`dancekit.metrics.music.notes_accuracy`: melody = highest sounding
    pitch, both transposed to C major / A minor) of the composed MIDI against the real music's chroma + beats
    arranged by the same arranger (tang2018 has audio, not MIDI)."""
    from dancekit.audio.midi import arrange
    from dancekit.metrics.music import notes_accuracy

    n = min(len(res.chroma), len(chroma_real))
    ref = arrange(chroma_real[:n], beat_real[:n], fps=res.fps)
    return float(notes_accuracy(res.arrangement.midi, ref.midi, fps=res.fps))


def cmd_beats(args):
    from dancekit.audio.midi import pick_beats
    from dancekit.data.prepared import PreparedData
    from dancekit.metrics.music_beats import beat_f1, tempo_from_beats

    data = PreparedData(args.data)
    rows = []
    for ckpt in args.ckpt:
        pipe, comp = _compose_all(ckpt, data, args.split, max_frames=args.max_frames)
        for thr, gap in [(t, g) for t in args.thresholds for g in args.min_gaps]:
            f1, terr, nb, acc = [], [], [], []
            for name, res in comp.items():
                chroma, beat_col, real_beats = _real_music(data, name)
                real_beats = real_beats[real_beats < len(res.beat) / res.fps]
                beats = pick_beats(res.beat, fps=res.fps, threshold=thr, min_gap=gap)
                f1.append(beat_f1(beats, real_beats))
                t_real, t_gen = tempo_from_beats(real_beats), tempo_from_beats(beats)
                terr.append(abs(t_gen - t_real) / t_real if np.isfinite(t_gen) else np.nan)
                nb.append(len(beats) / (len(res.beat) / res.fps))
                acc.append(_chroma_top1(res.chroma, chroma))
            rows.append(dict(ckpt=str(ckpt), threshold=thr, min_gap=gap, beat_f1=float(np.nanmean(f1)),
                             tempo_rel_err=float(np.nanmean(terr)) if not np.all(np.isnan(terr)) else None,
                             beats_per_s=float(np.mean(nb)), chroma_top1=float(np.mean(acc)),
                             beat_max=float(max(r.beat.max() for r in comp.values()))))
            print(json.dumps(rows[-1]), flush=True)
    return rows


def cmd_dance(args):
    from dancekit.data.prepared import PreparedData
    from dancekit.metrics.stability import jitter, smoothed_energy, stillness_share
    from dancekit.motion.representations import decode_motion, encode_motion
    from dancekit.pipelines.dual import DualPipeline, moving_average

    data = PreparedData(args.data)
    for ckpt in args.ckpt:
        pipe = DualPipeline.from_pretrained(ckpt)
        per: dict = {k: {} for k in args.smooth}
        for name in data.names(args.split):
            real = data.motion(name)
            end = args.max_frames / real.fps if args.max_frames else None
            gen = pipe(data.audio(name).path, seed=args.seed, end=end, smooth_frames=1).motion
            x = encode_motion(gen, "rot6d")
            n = min(gen.num_frames, real.num_frames)
            rp = real.to_positions()[:n]
            kw = dict(fps=gen.fps, skeleton=gen.skeleton)
            for k in args.smooth:
                gp = decode_motion(moving_average(x, k), gen.skeleton, gen.fps, "rot6d").to_positions()[:n]
                per[k][name] = dict(stillness=stillness_share(gp, **kw),
                                    energy_ratio=smoothed_energy(gp, **kw) / smoothed_energy(rp, **kw),
                                    jitter_ratio=jitter(gp, **kw)["speed_residual"] / jitter(rp, **kw)["speed_residual"])
        for k in args.smooth:
            agg = {m: float(np.mean([v[m] for v in per[k].values()])) for m in ("stillness", "energy_ratio",
                                                                               "jitter_ratio")}
            agg["stillness_max"] = float(max(v["stillness"] for v in per[k].values()))
            print(json.dumps(dict(ckpt=str(ckpt), split=args.split, smooth_frames=k, **agg, per_song=per[k])),
                  flush=True)


def _diversity(dances, root: int) -> tuple[float, float]:
    """Mean pairwise mean joint distance between ``dances`` ((T, J, 3) each, cropped to the shortest): as they
    are, and with each frame's root subtracted (the pose alone, without where the dancer stands)."""
    from itertools import combinations

    from dancekit.metrics.distance import mean_joint_distance

    n = min(len(d) for d in dances)
    dances = [np.asarray(d[:n], np.float64) for d in dances]
    local = [d - d[:, root: root + 1] for d in dances]
    return (float(np.mean([mean_joint_distance(a, b) for a, b in combinations(dances, 2)])),
            float(np.mean([mean_joint_distance(a, b) for a, b in combinations(local, 2)])))


def cmd_diversity(args):
    """The dual paper's diversity (§4.3): mean pairwise mean joint distance (cm) between the 5 dances of one
    song from seeds 0..4 (for the dual model: 5 start poses drawn from the pool), first ``--max-frames``
    frames, averaged over the split's songs; also with the root subtracted per frame (``diversity_local_cm``).
    ``ckpt`` may be a dual model, or a folder of ``NAME__k.npz`` dances (e.g. ``dancekit evaluate``'s pred/)."""
    from dancekit.data.prepared import PreparedData
    from dancekit.motion.formats import read_motion

    data = PreparedData(args.data)
    n = args.max_frames or 500
    for ckpt in args.ckpt:
        folder = Path(ckpt)
        per, per_local = {}, {}
        pipe = None
        for name in data.names(args.split):
            if (folder / f"{name}__0.npz").exists():
                motions = [read_motion(folder / f"{name}__{k}.npz") for k in range(5)]
            else:
                if pipe is None:
                    from dancekit.pipelines.dual import DualPipeline

                    pipe = DualPipeline.from_pretrained(ckpt)
                motions = [r.motion for r in pipe.dances(data.audio(name).path, seeds=list(range(5)),
                                                         end=n / pipe.fps)]
            root = motions[0].skeleton.root
            per[name], per_local[name] = _diversity([m.to_positions()[:n] for m in motions], root)
        print(json.dumps(dict(ckpt=str(ckpt), frames=n, diversity_cm=float(np.mean(list(per.values()))),
                              diversity_local_cm=float(np.mean(list(per_local.values()))), per_song=per,
                              per_song_local=per_local)), flush=True)


def cmd_diversity_ref(args):
    """Diversity of the references, measured like :func:`cmd_diversity`: ``real`` = the real dances of the
    split against each other (mean over pairs of different songs, cropped to the shorter), ``random_train`` =
    for each song 5 random training dances (the ``random_train`` baseline with seeds 0..4, cropped or looped
    to the song's length, :func:`dancekit.evaluation.baselines.make_baselines`)."""
    import tempfile

    from dancekit.data.prepared import PreparedData
    from dancekit.evaluation.baselines import make_baselines
    from dancekit.motion.formats import read_motion

    data = PreparedData(args.data)
    n = args.max_frames or 500
    names = data.names(args.split)
    root = data.skeleton.root
    real = [data.motion(name).to_positions()[:n] for name in names]
    from itertools import combinations

    pairs = [_diversity([a, b], root) for a, b in combinations(real, 2)]
    print(json.dumps(dict(reference="real", frames=n, diversity_cm=float(np.mean([p[0] for p in pairs])),
                          diversity_local_cm=float(np.mean([p[1] for p in pairs])))), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folders = [make_baselines(args.data, Path(tmp) / str(k), seed=k)["random_train"] for k in range(5)]
        per, per_local = {}, {}
        for name in names:
            dances = [read_motion(f / f"{name}.npz").to_positions()[:n] for f in folders]
            per[name], per_local[name] = _diversity(dances, root)
    print(json.dumps(dict(reference="random_train", frames=n, diversity_cm=float(np.mean(list(per.values()))),
                          diversity_local_cm=float(np.mean(list(per_local.values()))), per_song=per,
                          per_song_local=per_local)), flush=True)


def cmd_excerpts(args):
    """Table 4 at a reduced budget: G_M→D dances the first ``--seconds`` s of every song of the split from 5
    start poses (seeds 0..4, one batch, beat sync off) into ``OUT/pred/NAME__k.npz``, and the real dances cut
    the same way go to ``OUT/ref/NAME.npz``; then ``dancekit evaluate --pred OUT/pred --ref OUT/ref --data DATA``
    scores them and ``diversity OUT/pred`` measures the diversity over the start poses."""
    import time

    from dancekit.data.prepared import PreparedData
    from dancekit.motion import write_motion
    from dancekit.pipelines.dual import DualPipeline

    data = PreparedData(args.data)
    out = Path(args.out)
    for sub in ("pred", "ref"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    pipe = DualPipeline.from_pretrained(args.ckpt[0])
    t0, seconds = time.perf_counter(), 0.0
    for name in data.names(args.split):
        audio, real = data.audio(name), data.motion(name)
        n = min(real.num_frames, int(round(args.seconds * real.fps)))
        write_motion(out / "ref" / f"{name}.npz", real.slice(0, n))
        start = audio.start or 0.0
        end = start + n / real.fps
        for k, r in enumerate(pipe.dances(audio.path, seeds=list(range(5)), start=start, end=end, beat_sync=False)):
            write_motion(out / "pred" / f"{name}__{k}.npz", r.motion.slice(0, min(n, r.motion.num_frames)))
        seconds += 5 * n / real.fps
        print(name, n, f"{time.perf_counter() - t0:.1f} s", flush=True)
    print(json.dumps(dict(ckpt=args.ckpt[0], seconds_danced=seconds, elapsed_s=time.perf_counter() - t0)), flush=True)


def cmd_ablate(args):
    """Table 4 at a reduced budget: the first ``--max-frames`` frames of each dance of the split (seed 0).
    G_M→D: FD (mean joint distance to the real dance, cm), stillness, energy and jitter ratios, beats alignment
    (hit rate at 0.2 s); G_D→M: notes accuracy, beat F1 against the real beats, chroma L1."""
    from dancekit.audio.midi import pick_beats
    from dancekit.data.prepared import PreparedData
    from dancekit.metrics.beat import beat_metrics
    from dancekit.metrics.distance import mean_joint_distance
    from dancekit.metrics.music import chroma_l1
    from dancekit.metrics.music_beats import beat_f1
    from dancekit.metrics.stability import jitter, smoothed_energy, stillness_share
    from dancekit.pipelines.dual import ComposePipeline, DualPipeline

    data = PreparedData(args.data)
    n = args.max_frames or 500
    for ckpt in args.ckpt:
        dance_pipe = DualPipeline.from_pretrained(ckpt)
        gens = dance_pipe.model.config.generators
        rows: dict = {}
        for name in data.names(args.split):
            real = data.motion(name).slice(0, n)
            rp = real.to_positions()
            chroma, beat_col, real_beats = _real_music(data, name)
            real_beats = real_beats[real_beats < n / real.fps]
            r: dict = {}
            if gens in ("both", "m2d"):
                gen = dance_pipe(data.audio(name).path, seed=args.seed, end=n / real.fps).motion
                gp = gen.to_positions()[: len(rp)]
                kw = dict(fps=gen.fps, skeleton=gen.skeleton)
                r.update(fd_cm=mean_joint_distance(gp, rp), stillness=stillness_share(gp, **kw),
                         energy_ratio=smoothed_energy(gp, **kw) / smoothed_energy(rp, **kw),
                         jitter_ratio=jitter(gp, **kw)["speed_residual"] / jitter(rp, **kw)["speed_residual"],
                         beats_alignment=beat_metrics(gp, real_beats, fps=gen.fps)["beat_hit_rate_dual"])
            if gens in ("both", "d2m"):
                res = ComposePipeline.from_pretrained(ckpt)(real, seed=args.seed)
                beats = pick_beats(res.beat, fps=res.fps)
                r.update(notes_acc=_notes_accuracy(res, chroma[:n], beat_col[:n]),
                         beat_f1=beat_f1(beats, real_beats) if len(beats) else 0.0,
                         chroma_l1=chroma_l1(res.chroma, chroma[:n]))
            rows[name] = r
        keys = sorted({k for r in rows.values() for k in r})
        mean = {k: float(np.nanmean([r[k] for r in rows.values()])) for k in keys}
        mean["stillness_max"] = max(r.get("stillness", 0.0) for r in rows.values())
        print(json.dumps(dict(ckpt=str(ckpt), frames=n, **mean, per_song=rows)), flush=True)


def _share(kin, music_beats, tol=0.1):
    """Share of the kinematic beats ``kin`` (s) within ``tol`` s of a music beat."""
    if len(kin) == 0 or len(music_beats) == 0:
        return float("nan")
    return float(np.mean(np.min(np.abs(kin[:, None] - np.asarray(music_beats)[None]), 1) <= tol))


def cmd_compose(args):
    from dancekit.audio.midi import pick_beats
    from dancekit.data.prepared import PreparedData
    from dancekit.metrics.music import chroma_l1
    from dancekit.metrics.music_beats import beat_f1, tempo_from_beats
    from dancekit.motion.analysis import kinematic_beats

    data = PreparedData(args.data)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    pipe, comp = _compose_all(args.ckpt[0], data, args.split, seed=args.seed)
    rows = {}
    for name, res in comp.items():
        chroma, beat_col, real_beats = _real_music(data, name)
        files = res.write(out_dir, stem=name)
        beats = np.asarray(res.arrangement.beat_times)
        motion = data.motion(name)
        kin = np.asarray(kinematic_beats(motion.to_positions(), fps=motion.fps), np.float64)

        t_real, t_gen = tempo_from_beats(real_beats), float(res.arrangement.tempo)
        rows[name] = dict(notes_acc=_notes_accuracy(res, chroma, beat_col), chroma_top1=_chroma_top1(res.chroma, chroma),
                          chroma_l1=chroma_l1(res.chroma, chroma), tempo=t_gen, tempo_real=t_real,
                          tempo_rel_err=abs(t_gen - t_real) / t_real,
                          beat_f1_real=beat_f1(beats, real_beats),
                          picked=len(pick_beats(res.beat, fps=res.fps, threshold=0.5)),
                          kin_share_composed=_share(kin, beats), kin_share_real=_share(kin, real_beats),
                          files=[str(p) for p in files.values()])
        print(name, json.dumps(rows[name]), flush=True)
    keys = [k for k, v in next(iter(rows.values())).items() if isinstance(v, float | int)]
    mean = {k: float(np.nanmean([r[k] for r in rows.values()])) for k in keys}
    print("mean", json.dumps(mean), flush=True)
    (out_dir / "compose_metrics.json").write_text(json.dumps({"per_dance": rows, "mean": mean}, indent=1))


def main(argv=None):
    import torch

    torch.set_num_threads(1)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for cmd in ("beats", "dance", "compose", "diversity", "diversity-ref", "excerpts", "ablate"):
        p = sub.add_parser(cmd)
        p.add_argument("ckpt", nargs="*")
        p.add_argument("--data", default="data/tang2018")
        p.add_argument("--split", default="val")
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--thresholds", type=float, nargs="+", default=[0.3, 0.4, 0.5, 0.6])
        p.add_argument("-o", "--out", default="runs/dual/compose")
        p.add_argument("--min-gaps", type=float, nargs="+", default=[0.25], help="beat picking gaps (beats)")
        p.add_argument("--smooth", type=int, nargs="+", default=[1, 3, 5], help="moving averages to try (dance)")
        p.add_argument("--max-frames", type=int, default=None, help="score the first frames of each dance only")
        p.add_argument("--seconds", type=float, default=30.0, help="excerpts: seconds from each song's start")
    args = ap.parse_args(argv)
    {"beats": cmd_beats, "dance": cmd_dance, "compose": cmd_compose, "diversity": cmd_diversity,
     "diversity-ref": cmd_diversity_ref, "excerpts": cmd_excerpts, "ablate": cmd_ablate}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
