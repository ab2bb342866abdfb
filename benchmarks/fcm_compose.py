"""Compose a contact-gated Foot Constraint Model from two trained ones (issue 13, ``compose_gated``).

    PYTHONPATH=src python benchmarks/fcm_compose.py --plant runs/fc_N/model --swing runs/fc_H/model \
        --out runs/fcm_gate/NH [--gate-frames 5] [--gate-root any|swing] [--strength 1] [--swing-strength 1]

``--swing none``: no increment off contact. The folder is a foot_constraint checkpoint (``gate=True``) that
``benchmarks/fcm_eval.py --fcm NAME=FOLDER`` and ``dancekit dance --foot-constraint FOLDER`` take.
"""

from __future__ import annotations

import argparse

from dancekit.pipelines.foot_constraint import compose_gated


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--plant", required=True)
    ap.add_argument("--swing", required=True, help="a foot model folder, or none")
    ap.add_argument("--out", required=True)
    ap.add_argument("--gate-frames", type=int, default=5)
    ap.add_argument("--gate-root", default="any", choices=("any", "swing"))
    ap.add_argument("--strength", type=float, default=1.0)
    ap.add_argument("--swing-strength", type=float, default=1.0)
    a = ap.parse_args()
    out = compose_gated(a.plant, None if a.swing == "none" else a.swing, a.out, gate_frames=a.gate_frames,
                        gate_root=a.gate_root, strength=a.strength, swing_strength=a.swing_strength)
    print(out)


if __name__ == "__main__":
    main()
