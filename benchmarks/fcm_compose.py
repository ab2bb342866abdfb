"""Compose contact-gated Foot Constraint Models from trained ones (issue 13, ``compose_gated``).

    PYTHONPATH=src python benchmarks/fcm_compose.py --plant N=runs/fc_N/model --swing H=runs/fc_H/model none \
        --out runs/fcm_gate [--gate-frames 5 9] [--gate-root any swing] [--strength 1 0.75 0.5] [--swing-strength 1]

Every combination of the settings given is written to ``OUT/<plant>_<swing>_<root>_g<frames>_s<strength>_w<swing
strength>`` (a foot_constraint checkpoint, ``gate=True``); ``--swing none``: no increment off contact. The
last line printed is the ``NAME=FOLDER`` list for ``benchmarks/fcm_eval.py --fcm``.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

from dancekit.pipelines.foot_constraint import compose_gated


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--plant", nargs="+", required=True, help="NAME=FOLDER of foot models for contact frames")
    ap.add_argument("--swing", nargs="+", required=True, help="NAME=FOLDER of foot models for the rest, or none")
    ap.add_argument("--out", required=True)
    ap.add_argument("--gate-frames", type=int, nargs="+", default=[5])
    ap.add_argument("--gate-root", nargs="+", default=["any"], choices=("any", "swing"))
    ap.add_argument("--strength", type=float, nargs="+", default=[1.0])
    ap.add_argument("--swing-strength", type=float, nargs="+", default=[1.0])
    a = ap.parse_args()
    plants = dict(p.split("=", 1) for p in a.plant)
    swings = {s.split("=", 1)[0]: (s.split("=", 1)[1] if "=" in s else None) for s in a.swing}
    specs = []
    for (pn, pf), (sn, sf), root, frames, s, w in itertools.product(
            plants.items(), swings.items(), a.gate_root, a.gate_frames, a.strength, a.swing_strength):
        name = f"{pn}_{sn}_{root}_g{frames}_s{s:g}_w{w:g}"
        out = compose_gated(pf, sf, Path(a.out) / name, gate_frames=frames, gate_root=root, strength=s,
                            swing_strength=w)
        specs.append(f"{name}={out}")
    print(" ".join(specs))


if __name__ == "__main__":
    main()
