"""Why the Foot Constraint Model (``--foot-constraint``) does not lower foot skating (issue 13 / 15): evidence.

    PYTHONPATH=src python benchmarks/fcm_why.py --data data/tang2018 --raw runs/feet_raw

On the validation songs only. (1) The training corruption: the real validation dances with the simulated
sliding of ``foot_constraint_step`` (lower-body + toe columns Gaussian-smoothed, σ = smooth_sigma frames,
plus noise_std Gaussian noise, in normalised units, the root's path kept) — how much do they skate, against
the clean dances? (2) What the embedded model changes on generated dances (cleaned up): foot skating before /
after, how far it moves the feet (cm), and in the skating frames how much of the foot's horizontal velocity
is the root's (the body gliding over the floor, which the model may not change: keep_root_path).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import bench_feet
import numpy as np
import torch

from dancekit.data import PreparedData
from dancekit.metrics import foot_skating
from dancekit.models.foot_constraint import gaussian_smooth
from dancekit.motion import get_skeleton
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta
from dancekit.pipelines import stages
from dancekit.pipelines.base import DanceResult
from dancekit.pipelines.foot_constraint import load_foot_constraint


def glide_share(p: np.ndarray, sk, fps: float) -> float:
    """In skating frames of the feet (contact as foot_skating: ≤ 5 cm over the lowest foot joint within ±1 s,
    slower than 1 m/s; skating: horizontal speed > 0.25 m/s), the mean share of the foot's horizontal velocity
    along the root's horizontal velocity (1: the foot moves with the body)."""
    m = p * sk.unit_scale
    feet = [sk.index(n) for n in sk.feet]
    v = np.gradient(m, axis=0) * fps
    vf, vr = v[:, feet][..., [0, 2]], v[:, sk.root][:, None, [0, 2]]
    h = m[:, feet, 1]
    from scipy.ndimage import minimum_filter1d

    floor = minimum_filter1d(h.min(axis=1), size=2 * int(fps) + 1, mode="nearest")[:, None]
    speed = np.linalg.norm(v[:, feet], axis=-1)
    hs = np.linalg.norm(vf, axis=-1)
    skate = (h - floor <= 0.05) & (speed < 1.0) & (hs > 0.25)
    along = (vf * vr).sum(-1) / np.maximum(hs**2, 1e-12)
    return float(np.clip(along[skate], -1, 2).mean()) if skate.any() else float("nan")


def _decode(fix, y: torch.Tensor, sk, fps: float, origin) -> np.ndarray:
    """(T, J, 3) positions of normalised rootdelta vectors (1, T, P)."""
    x = fix.stats.denormalize_dance(y[0].numpy()).astype(np.float64)
    return decode_rootdelta(x, sk, fps, origin=origin).to_positions()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--raw", required=True)
    args = ap.parse_args()
    data = PreparedData(args.data)
    sk = get_skeleton("tang2018")
    fix = load_foot_constraint()
    c = fix.model.config
    cols = list(c.lower_idx) + list(c.foot_idx)
    g = torch.Generator().manual_seed(0)
    print(f"FCM: smooth_sigma {c.smooth_sigma} frames, noise_std {c.noise_std}, keep_root_path {c.keep_root_path}")
    rows = []
    for n in data.names("val"):
        m = data.motion(n)
        x = encode_rootdelta(m)
        z = torch.from_numpy(fix.stats.normalize_dance(x))[None]
        bad = z.clone()
        bad[..., cols] = gaussian_smooth(z[..., cols], c.smooth_sigma) + c.noise_std * torch.randn(z[..., cols].shape, generator=g).to(z)
        R0 = m.rotations
        heading0 = float(np.arctan2(R0[0, sk.root, 0, 2], R0[0, sk.root, 2, 2]))
        tr0 = np.asarray(m.root_translation, np.float64)[0]
        origin = (tr0[0], tr0[2], heading0)
        clean, corrupt = (_decode(fix, y, sk, m.fps, origin) for y in (z, bad))
        with torch.no_grad():
            fixed = _decode(fix, fix.model(bad.float()).double(), sk, m.fps, origin)
        rows.append([foot_skating(q, fps=m.fps, skeleton=sk)["ratio"] for q in (clean, corrupt, fixed)])
    r = np.mean(rows, axis=0)
    print(f"real val dances, foot skating: clean {r[0]:.3f}, with the simulated sliding {r[1]:.3f}, "
          f"corrected by the FCM {r[2]:.3f}")
    for model in ("revolution", "music2dance"):
        out = []
        for f in sorted((Path(args.raw) / model / "val").glob("*.npz")):
            mo = bench_feet.load(f, sk)
            cleaned = stages.clean_up(DanceResult(motion=mo, model="x", seed=0)).motion
            p0 = np.asarray(cleaned.to_positions(), np.float64)
            p1 = np.asarray(fix(cleaned).to_positions(), np.float64)
            feet = [sk.index(n) for n in sk.feet]
            move = np.linalg.norm(p1[:, feet] - p0[:, feet], axis=-1).mean() * sk.unit_scale * 100
            move_rel = np.linalg.norm((p1[:, feet] - p1[:, sk.root:sk.root + 1]) - (p0[:, feet] - p0[:, sk.root:sk.root + 1]),
                                      axis=-1).mean() * sk.unit_scale * 100
            out.append([foot_skating(p0, fps=25, skeleton=sk)["ratio"], foot_skating(p1, fps=25, skeleton=sk)["ratio"],
                        move, move_rel, glide_share(p0, sk, 25.0)])
        o = np.mean(out, axis=0)
        print(f"{model} val ({len(out)} dances, cleaned up): skating {o[0]:.3f} -> {o[1]:.3f} with the FCM; "
              f"feet moved {o[2]:.2f} cm on average ({o[3]:.2f} cm relative to the root); in skating frames "
              f"{o[4]:.2f} of the foot's horizontal velocity is the root's")
    real_glide = np.nanmean([glide_share(np.asarray(data.motion(n).to_positions(), np.float64), sk, 25.0)
                             for n in data.names("val")])
    print(f"real val dances: in skating frames {real_glide:.2f} of the foot's horizontal velocity is the root's")


if __name__ == "__main__":
    main()
