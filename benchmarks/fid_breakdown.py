"""Where a model's FID_k comes from (issue 15): the AIST++ kinetic features of its dances against the training
dances, per feature and joint. Validation songs by default (choices are made there; never tune on the test split).

    PYTHONPATH=src python benchmarks/fid_breakdown.py runs/tune_v2/3_0.3_0_0/pred --data data/tang2018 [--split val]

FID = ‖μ_p − μ_r‖² + tr(Σ_p + Σ_r − 2(Σ_p Σ_r)^½) on features z-scored with the training dances' statistics
(as ``dancekit evaluate``); printed: the two terms, the mean term's share per feature kind (horizontal / vertical
kinetic energy, energy expenditure), the joints that contribute most, and the per-kind ratio of the prediction's
mean raw feature to the real (validation) dances' (below 1: calmer than real).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy import linalg

from dancekit.data import PreparedData
from dancekit.evaluation.score import SAMPLE_SEP
from dancekit.metrics import fid as fid_mod
from dancekit.motion import read_motion

KINDS = ("KE_h", "KE_v", "EE")


def fid_terms(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    mu = float(((a.mean(0) - b.mean(0)) ** 2).sum())
    s1, s2 = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    root = linalg.sqrtm(s1 @ s2).real
    return mu, float(np.trace(s1 + s2 - 2 * root))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pred")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    args = ap.parse_args()
    data = PreparedData(args.data)
    sk, fps = data.skeleton, data.fps
    names = data.names(args.split)
    ref = [data.motion(n).to_positions() for n in data.names("train")]
    real = [data.motion(n).to_positions() for n in names]
    pred = [read_motion(p).to_positions() for p in sorted(Path(args.pred).glob(f"*{SAMPLE_SEP}*.npz"))]
    sets = {k: fid_mod.feature_sets(v, fps=fps, skeleton=sk, kind="kinetic", segment_seconds=10.0)
            for k, v in (("ref", ref), ("real", real), ("pred", pred))}
    r_z, real_z, pred_z, keep = fid_mod.normalize_features(sets["ref"], sets["real"], sets["pred"])
    J = sk.num_joints
    kind = np.tile(np.arange(3), J)[keep]
    joint = np.repeat(np.arange(J), 3)[keep]
    for label, z in (("real " + args.split, real_z), ("pred", pred_z)):
        mu, cov = fid_terms(z, r_z)
        print(f"{label}: FID_k {mu + cov:.2f} = mean term {mu:.2f} + covariance term {cov:.2f} ({len(z)} segments)")
    d = (pred_z.mean(0) - r_z.mean(0)) ** 2
    for k, name in enumerate(KINDS):
        print(f"  mean term from {name}: {d[kind == k].sum():.2f}")
    top = np.argsort(d)[::-1][:8]
    print("  largest mean-term features:", ", ".join(
        f"{sk.joint_names[joint[i]]}/{KINDS[kind[i]]} {d[i]:.2f} (z {pred_z.mean(0)[i] - r_z.mean(0)[i]:+.2f})"
        for i in top))
    raw_p, raw_r = sets["pred"].mean(0), sets["real"].mean(0)
    for k, name in enumerate(KINDS):
        sel = np.arange(3 * J) % 3 == k
        print(f"  {name}: pred / real {args.split} mean raw feature {raw_p[sel].sum() / raw_r[sel].sum():.2f}; "
              f"segment std ratio {sets['pred'][:, sel].sum(1).std() / sets['real'][:, sel].sum(1).std():.2f}")


if __name__ == "__main__":
    main()
