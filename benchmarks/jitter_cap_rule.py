"""The lead's rule of 2026-11-24 16:04 UTC (issue 15, music2dance's jitter cap, second try) applied to a
``benchmarks/tune_energy.py ... --fid -o OUT.json`` report whose settings are named ``"none"`` (no cap) and
``"<before|after> s<scale> r<ρ>"``; prints the table of docs/BENCHMARKS.md and the chosen setting.

    python benchmarks/jitter_cap_rule.py OUT.json

Per song (seeds averaged): jitter ≤ 1.15× real, energy ≥ 0.6×, stillness ≤ 0.05 — where no cap already fails
energy or stillness on the song, "no worse than no cap" there (energy / stillness within 0.005 / 0.0005 of no
cap's, jitter ≤ max(1.15, no cap's)); pooled FID_k and FID_g each ≤ +5 % of no cap; beat hit rate, mean planted
ankle share and mean floor within-2-cm share (``bench_stages.physical``) each not lower by more than 0.02.
Among qualifying: the highest scale, then the higher ρ, then ``before`` over ``after``.
"""

from __future__ import annotations

import json
import sys


def fails(v: dict) -> bool:
    return v["energy_ratio"] < 0.6 or v["stillness"] > 0.05


def reasons(r: dict, none: dict) -> list[str]:
    why = []
    for s, n in none["per_song"].items():
        v, tag = r["per_song"][s], s.replace("DANCE_", "")
        if fails(n):
            if v["jitter_ratio"] > max(1.15, n["jitter_ratio"]):
                why.append(f"{tag} jitter {v['jitter_ratio']:.2f}")
            if v["energy_ratio"] < min(0.6, n["energy_ratio"]) - 0.005:
                why.append(f"{tag} energy {v['energy_ratio']:.3f} < no cap's {n['energy_ratio']:.3f}")
            if v["stillness"] > max(0.05, n["stillness"]) + 0.0005:
                why.append(f"{tag} stillness")
        else:
            if v["jitter_ratio"] > 1.15:
                why.append(f"{tag} jitter {v['jitter_ratio']:.2f}")
            if v["energy_ratio"] < 0.6:
                why.append(f"{tag} energy")
            if v["stillness"] > 0.05:
                why.append(f"{tag} stillness")
    for key, name in (("fid_k", "FID_k"), ("fid_g", "FID_g")):
        if r[key] > 1.05 * none[key]:
            why.append(f"{name} {r[key] / none[key] - 1:+.1%}")
    for key, name in (("hit_rate", "hit rate"), ("planted_foot_share", "planted"), ("floor_within_2cm", "within 2 cm")):
        if r[key] < none[key] - 0.02:
            why.append(f"{name} {r[key] - none[key]:+.3f}")
    return why


def main() -> None:
    report = json.load(open(sys.argv[1]))["report"]
    none = report["none"]
    songs = list(none["per_song"])
    print("| setting | " + " | ".join(s.replace("DANCE_", "") for s in songs)
          + " | FID_k | FID_g | hit rate | planted | within 2 cm | qualifies |")
    print("|---" * (len(songs) + 7) + "|")
    ok = []
    for name, r in report.items():
        why = reasons(r, none)
        cells = [f"{r['per_song'][s]['jitter_ratio']:.2f} / {r['per_song'][s]['energy_ratio']:.2f} / "
                 f"{r['per_song'][s]['stillness']:.3f}" for s in songs]
        fid = [f"{r[k]:.2f} ({(r[k] / none[k] - 1) * 100:+.1f} %)" for k in ("fid_k", "fid_g")]
        verdict = "(reference)" if name == "none" else "yes" if not why else "no: " + ", ".join(why)
        print(f"| {name} | " + " | ".join(cells + fid) + f" | {r['hit_rate']:.3f} | {r['planted_foot_share']:.3f} | "
              f"{r['floor_within_2cm']:.3f} | {verdict} |")
        if name != "none" and not why:
            place, scale, rho = name.split()
            ok.append((float(scale[1:]), float(rho[1:]), place == "before", name))
    print("chosen:", max(ok)[3] if ok else "none qualifies")


if __name__ == "__main__":
    main()
