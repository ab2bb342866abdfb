"""Apply the fourth attempt's rule (issue 15, branch ``variety4``) to a ``tune_variety.py --genre-draw`` run on the
validation songs, and print one markdown row per setting.

    PYTHONPATH=src python benchmarks/select_genre_draw.py runs/tune_v4 --data data/tang2018 --base "3:0.3:0:0_g0:0"

The rule (fixed before the grid was measured): a setting qualifies when FID_k and FID_g are each ≤ 1.10 × the
baseline's (the draw off, same run), pooled stillness ≤ 0.05, pooled smoothed energy ≥ 0.6 × real, and on every
validation song the worst seed's jitter / that song's real dance ≤ max(1.2, the baseline's worst seed's on that
song); among qualifiers the largest style multimodality wins. Rows whose spec is listed in ``--reference`` are
shown but never chosen (e.g. the third attempt's draw, ρ = 0).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from variety_per_song import guards  # benchmarks/ is on the path when run as a script

from dancekit.data import PreparedData
from dancekit.evaluation.score import _read_dir, group_predictions
from dancekit.motion import read_motion


def per_song(pred: Path, real: dict) -> dict[str, tuple[float, float, float]]:
    """Song → (worst seed's stillness, lowest energy / real, highest jitter / real)."""
    out = {}
    for name, paths in sorted(group_predictions(_read_dir(pred, "generated")).items()):
        g = np.array([guards(read_motion(p)) for p in paths])
        out[name] = (float(g[:, 0].max()), float(g[:, 1].min() / real[name][1]), float(g[:, 2].max() / real[name][2]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("run", help="a tune_variety.py output folder (rows.jsonl and one folder per row)")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    ap.add_argument("--base", required=True, help="the spec of the baseline row (the draw off)")
    ap.add_argument("--reference", nargs="*", default=[], help="specs shown but never chosen")
    args = ap.parse_args()
    if args.split == "test":
        raise SystemExit("choose on the validation songs")
    data = PreparedData(args.data)
    real = {n: guards(data.motion(n)) for n in data.names(args.split)}
    run = Path(args.run)
    rows = {}
    for line in (run / "rows.jsonl").read_text().splitlines():
        r = json.loads(line)
        rows[r["spec"]] = r  # a later row of the same spec replaces an earlier one
    songs = {spec: per_song(run / spec.replace(":", "_") / "pred", real) for spec in rows}
    base, base_songs = rows[args.base], songs[args.base]
    best = None
    print("| setting | FID_k | FID_g | multimodality | stillness | energy / real | s below half | worst jitter / real per song "
          "| genres danced | qualifies |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- | --- |")
    for spec, r in rows.items():
        why = []
        if r["fid_k"] > 1.10 * base["fid_k"]:
            why.append("FID_k")
        if r["fid_g"] > 1.10 * base["fid_g"]:
            why.append("FID_g")
        if r["stillness_share"] > 0.05:
            why.append("stillness")
        if r["smoothed_energy_ratio"] < 0.6:
            why.append("energy")
        for name, (_, _, jit) in songs[spec].items():
            if jit > max(1.2, base_songs[name][2]) + 1e-12:
                why.append(f"jitter {name.replace('DANCE_', '')}")
        ok = not why and spec != args.base and spec not in args.reference
        if ok and (best is None or r["style_multimodality"] > rows[best]["style_multimodality"]):
            best = spec
        jit = " ".join(f"{v[2]:.2f}" for v in songs[spec].values())
        danced = " ".join("".join("-" if g == "alone" else g[0] for g in v) for v in r["genres_danced"].values())
        verdict = "baseline" if spec == args.base else ("reference" if spec in args.reference else
                                                       ("yes" if not why else "no: " + ", ".join(why)))
        print(f"| `{spec}` | {r['fid_k']:.1f} | {r['fid_g']:.1f} | {r['style_multimodality']:.1f} | "
              f"{r['stillness_share']:.3f} | {r['smoothed_energy_ratio']:.2f} | {r['seconds_below_half']} of "
              f"{r['seconds']} | {jit} | {danced} | {verdict} |")
    print(f"songs: {' '.join(n.replace('DANCE_', '') for n in base_songs)}; chosen: {best}")


if __name__ == "__main__":
    main()
