"""Per song and per seed, the quality guards of issue 15 on `dancekit evaluate` output folders, and the fifth
attempt's rule (issue 15, branch ``variety5``) applied to them.

    PYTHONPATH=src python benchmarks/variety_seed_guards.py runs/val_today runs/val_cand1 ... \
        --data data/tang2018 --split val --base runs/val_today [--checkpoint runs/val_cand1=/tmp/cand1] [--json OUT]

Each folder is an ``evaluate`` output (``report.json`` and ``pred/NAME__k.npz``). Per dance: stillness share,
smoothed energy / the song's real dance, jitter (speed removed by a 5-frame average, m/s) / the song's real dance,
and the genre the seed danced (from the checkpoint given with ``--checkpoint FOLDER=CKPT``: its classifier's
posterior and its genre draw, :func:`dancekit.pipelines.revolution.draw_genre`).

The rule (fixed by the lead at 13:20 UTC before any number): a setting qualifies when style multimodality ≥ 30,
FID_k ≤ 1.05 × the base's, FID_g ≤ the base's, and on every song and every seed jitter / real ≤ 1.15, energy /
real ≥ 0.6 and stillness ≤ 0.05. Among qualifiers the highest multimodality.

Today's default already fails some of these per-song guards on the validation songs (W_11, danced calmly
because the pipeline does not hear music in it, is the same for every setting), so a second verdict is printed
("as today"): a guard that the base's worst seed already fails on a song is met there when the candidate's
worst seed is no worse than the base's (the fourth attempt's max(bound, baseline) form); every other song and
guard keeps the literal bound.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from dancekit.data import PreparedData
from dancekit.evaluation.score import _read_dir, group_predictions
from dancekit.metrics import stability
from dancekit.motion import read_motion

LETTER = {"waltz": "w", "rumba": "r", "chacha": "c", "tango": "t", None: "-"}


def guards(m) -> tuple[float, float, float]:
    """(stillness share, smoothed energy m/s, jitter m/s) of a motion."""
    p = np.asarray(m.to_positions(), np.float64)
    return (stability.stillness_share(p, fps=m.fps, skeleton=m.skeleton),
            stability.smoothed_energy(p, fps=m.fps, skeleton=m.skeleton),
            stability.jitter(p, fps=m.fps, skeleton=m.skeleton)["speed_residual"])


def genres_danced(checkpoint: str, data: PreparedData, names: list[str], seeds: int) -> dict[str, str]:
    """Song → the letters of the genres seeds 0..seeds-1 dance with the checkpoint (``-``: the model alone)."""
    from dancekit.features import MUSIC_BEAT_STRENGTH
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.base import song_feature_set
    from dancekit.pipelines.revolution import draw_genre

    pipe = load_pipeline(checkpoint)
    out = {}
    for name in names:
        ref = data.audio(name)
        strength = song_feature_set(ref.path, fps=pipe.fps, preset=pipe.preset, hop_length=pipe.hop_length,
                                    start=ref.start, end=ref.end).beat_strength
        if strength < MUSIC_BEAT_STRENGTH:
            out[name] = "(calm)"
            continue
        probs = pipe.read_genre(ref.path, start=ref.start, end=ref.end)
        out[name] = "".join(LETTER[draw_genre(probs, seed=s, draw=pipe.genre_draw)[0]] for s in range(seeds))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+", help="dancekit evaluate output folders")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    ap.add_argument("--base", help="the folder of today's default (the rule's FID reference)")
    ap.add_argument("--checkpoint", action="append", default=[], help="FOLDER=CKPT: the checkpoint a folder danced")
    ap.add_argument("--json", help="write every per-dance number here")
    ap.add_argument("--rows", help="write one line per folder here for benchmarks/plot_variety.py (spec: its name "
                                   "without the 'val_' prefix)")
    args = ap.parse_args()
    data = PreparedData(args.data)
    names = data.names(args.split)
    real = {n: guards(data.motion(n)) for n in names}
    ckpts = dict(c.split("=", 1) for c in args.checkpoint)
    base = json.loads((Path(args.base) / "report.json").read_text())["metrics"] if args.base else None
    dump = {}
    base_worst = {}
    if args.base:
        for name, paths in group_predictions(_read_dir(Path(args.base) / "pred", "generated")).items():
            g = np.array([guards(read_motion(p)) for p in paths])
            base_worst[name] = (g[:, 0].max(), g[:, 1].min() / real[name][1], g[:, 2].max() / real[name][2])
    for run in args.runs:
        rep = json.loads((Path(run) / "report.json").read_text())["metrics"]
        groups = group_predictions(_read_dir(Path(run) / "pred", "generated"))
        seeds = max(len(v) for v in groups.values())
        danced = genres_danced(ckpts[run], data, names, seeds) if run in ckpts else {}
        why, rows, soft = [], {}, []
        for name, paths in sorted(groups.items()):
            g = np.array([guards(read_motion(p)) for p in paths])  # (seeds, 3)
            st, en, ji = g[:, 0], g[:, 1] / real[name][1], g[:, 2] / real[name][2]
            rows[name] = {"stillness": st.tolist(), "energy_ratio": en.tolist(), "jitter_ratio": ji.tolist(),
                          "genres": danced.get(name, "")}
            short = name.replace("DANCE_", "")
            print(f"{run} {short:5s} {danced.get(name, ''):6s} jitter/real " + " ".join(f"{v:.2f}" for v in ji)
                  + " | energy/real " + " ".join(f"{v:.2f}" for v in en)
                  + " | stillness " + " ".join(f"{v:.3f}" for v in st))
            why += [f"jitter {short}"] if ji.max() > 1.15 else []
            why += [f"energy {short}"] if en.min() < 0.6 else []
            why += [f"stillness {short}"] if st.max() > 0.05 else []
            if name in base_worst:
                bs, be, bj = base_worst[name]
                soft += [f"jitter {short}"] if ji.max() > max(1.15, bj) + 1e-12 else []
                soft += [f"energy {short}"] if en.min() < min(0.6, be) - 1e-12 else []
                soft += [f"stillness {short}"] if st.max() > max(0.05, bs) + 1e-12 else []
        mm = rep["style_multimodality"]
        overall = ["multimodality"] if mm < 30 else []
        if base is not None:
            overall += ["FID_k"] if rep["fid_k"] > 1.05 * base["fid_k"] else []
            overall += ["FID_g"] if rep["fid_g"] > base["fid_g"] else []
        why += overall
        soft += overall
        print(f"{run} ALL: FID_k {rep['fid_k']:.2f} FID_g {rep['fid_g']:.2f} multimodality {mm:.2f} "
              f"stillness {rep['stillness_share']:.3f} energy {rep['smoothed_energy_ratio']:.3f} "
              f"jitter {rep['jitter_speed_ratio']:.3f} -> literal: " + ("QUALIFIES" if not why else "no: " + ", ".join(why))
              + "; as today: " + ("QUALIFIES" if not soft else "no: " + ", ".join(soft)))
        dump[run] = {"metrics": {k: rep[k] for k in ("fid_k", "fid_g", "style_multimodality", "stillness_share",
                                                     "smoothed_energy_ratio", "jitter_speed_ratio")},
                     "songs": rows, "fails": why, "fails_as_today": soft}
    if args.json:
        Path(args.json).write_text(json.dumps(dump, indent=1))
    if args.rows:
        with open(args.rows, "w") as out:
            for run, d in dump.items():
                spec = Path(run).name.removeprefix("val_")
                out.write(json.dumps({"spec": spec, **d["metrics"], "qualifies": not d["fails_as_today"]}) + "\n")


if __name__ == "__main__":
    main()
