"""Summarise genre-steering runs of ``benchmarks/m2d_eval_prepared.py`` against the acceptance rule of
issue 13 (docs/BENCHMARKS.md, "Genre steering with the pipeline's stages").

    PYTHONPATH=src python benchmarks/genre_steering_summary.py runs/gv/st_G1 runs/gv/ev_G1 [--data data/tang2018]

``ST`` holds ``steering.json`` (``--steering``), ``EV`` holds ``report.json`` and ``pred/`` (``--genre true``,
any seeds). Per song of EV: the mean over its dances of the jitter and smoothed energy (the metrics of
``dancekit evaluate``: 5-frame moving average) over the song's real dance, and the largest stillness share;
then whether the rule holds: read-back >= 0.75, jitter <= 1.2x and energy >= 0.6x real on every song,
stillness <= 5 % on every dance, FID_k < 100.1 and FID_g < 45.2 (half the mean-pose baseline's).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from dancekit.data import PreparedData
from dancekit.evaluation.score import EvalSettings, dance_metrics

FID_K_MAX, FID_G_MAX = 100.1, 45.2


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("steering")
    p.add_argument("evaluation")
    p.add_argument("--data", default="data/tang2018")
    args = p.parse_args()
    st = json.loads((Path(args.steering) / "steering.json").read_text())
    ev = json.loads((Path(args.evaluation) / "report.json").read_text())
    data, settings = PreparedData(args.data), EvalSettings()
    songs: dict[str, list[dict]] = {}
    for key, row in ev["per_dance"].items():
        songs.setdefault(key.split("#")[0], []).append(row)
    jit, en, still = {}, {}, 0.0
    for name, rows in songs.items():
        m = data.motion(name)
        real = dance_metrics(m.to_positions(), fps=m.fps, skeleton=m.skeleton, music_beats=None, settings=settings)
        jit[name] = float(np.mean([r["jitter_speed"] for r in rows])) / real["jitter_speed"]
        en[name] = float(np.mean([r["smoothed_energy"] for r in rows])) / real["smoothed_energy"]
        still = max(still, max(r["stillness_share"] for r in rows))
    m = ev["metrics"]
    ok = {"read_back": st["read_back"] >= 0.75, "jitter": max(jit.values()) <= 1.2, "energy": min(en.values()) >= 0.6,
          "stillness": still <= 0.05, "fid_k": m["fid_k"] < FID_K_MAX, "fid_g": m["fid_g"] < FID_G_MAX}
    print(f"read back {st['read_back']:.2f} (" + " / ".join(f"{v:.1f}" for v in st["read_back_per_genre"].values())
          + f") | FID_k {m['fid_k']:.1f} FID_g {m['fid_g']:.1f} | jitter max {max(jit.values()):.2f} (mean ratio "
          f"{m['jitter_speed_ratio']:.2f}) energy min {min(en.values()):.2f} (mean ratio "
          f"{m['smoothed_energy_ratio']:.2f}) stillness max {still:.3f} | style ACC {m.get('style_acc', float('nan')):.2f}")
    print("   per song jitter " + ", ".join(f"{k[6:]} {v:.2f}" for k, v in jit.items())
          + " | energy " + ", ".join(f"{k[6:]} {v:.2f}" for k, v in en.items()))
    print("   rule: " + ", ".join(f"{k} {'ok' if v else 'FAIL'}" for k, v in ok.items())
          + f" -> {'QUALIFIES' if all(ok.values()) else 'fails'}")


if __name__ == "__main__":
    main()
