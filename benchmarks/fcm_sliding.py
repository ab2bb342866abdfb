"""How generated dances' feet slide, against the real dances and the Foot Constraint Model's training corruption
(issue 13): the statistics the corruption is chosen to match.

    PYTHONPATH=src python benchmarks/fcm_sliding.py --data data/tang2018 --raw runs/feet_raw [--grid]

On the validation songs only. Per dance, for the foot joints of ``dancekit.metrics.foot_skating`` (contact: ≤
5 cm over the local floor, slower than 1 m/s; skating: a contact faster than 0.25 m/s horizontally): the
skating ratio, the mean horizontal speed of the skating frames (m/s: the sliding amplitude), the mean length
of a run of consecutive skating frames (s: the sliding duration), and the share of the skating frames'
horizontal foot velocity along the root's (``fcm_why.glide_share``). Rows: the real validation dances, the
models' own dances (``benchmarks/feet_dances.py``, raw: what ``--foot-constraint`` is given), the real dances
with the paper's corruption (smoothing σ = 2 frames + noise 0.1) and, with ``--grid``, with the "glide"
corruption of ``foot_constraint_step`` (``glide_amp`` x unit-std noise smoothed over ``glide_sigma`` frames on
every lower-body column, normalised units) for a grid of amplitudes and correlation times.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import bench_feet
import fcm_why
import numpy as np
import torch
from scipy.ndimage import label, minimum_filter1d

from dancekit.data import PreparedData
from dancekit.models.foot_constraint import gaussian_smooth, unit_smooth_noise
from dancekit.motion import get_skeleton
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta, lower_body_cols, rootdelta_layout
from dancekit.pipelines.foot_constraint import load_foot_constraint


def sliding_stats(p: np.ndarray, sk, fps: float) -> dict[str, float]:
    """Skating ratio, mean skating speed (m/s) and mean skating run (s) of positions ``(T, J, 3)``."""
    m = p * sk.unit_scale
    feet = [sk.index(n) for n in sk.feet]
    v = np.gradient(m[:, feet], axis=0) * fps
    h = m[:, feet, 1]
    floor = minimum_filter1d(h.min(axis=1), size=2 * int(fps) + 1, mode="nearest")[:, None]
    hs = np.linalg.norm(v[..., [0, 2]], axis=-1)
    contact = (h - floor <= 0.05) & (np.linalg.norm(v, axis=-1) < 1.0)
    skate = contact & (hs > 0.25)
    runs = []
    for k in range(skate.shape[1]):
        lab, n = label(skate[:, k])
        runs += list(np.bincount(lab)[1:]) if n else []
    return {"ratio": float(skate.sum() / max(contact.sum(), 1)), "speed": float(hs[skate].mean()) if skate.any() else 0.0,
            "run_s": float(np.mean(runs) / fps) if runs else 0.0, "glide": fcm_why.glide_share(p, sk, fps)}


def corrupt(z: np.ndarray, kind: str, amp: float, sigma: float, lower: list[int], seed: int) -> np.ndarray:
    """Normalised features ``(T, P)`` with the training corruption on the lower-body columns."""
    g = torch.Generator().manual_seed(seed)
    x = torch.from_numpy(z)[None]
    out = x.clone()
    if kind == "paper":
        out[..., lower] = gaussian_smooth(x[..., lower], sigma) + amp * torch.randn(x[..., lower].shape, generator=g).to(x)
    else:
        out[..., lower] = x[..., lower] + amp * unit_smooth_noise(x[..., lower].shape, sigma, generator=g, dtype=x.dtype)
    return out[0].numpy()


def show(name: str, rows: list[dict]) -> None:
    r = {k: float(np.nanmean([row[k] for row in rows])) for k in rows[0]}
    print(f"{name:<34} skating {r['ratio']:.3f}  speed {r['speed']:.3f} m/s  run {r['run_s']:.3f} s  "
          f"root share {r['glide']:.2f}  ({len(rows)} dances)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--raw", required=True)
    ap.add_argument("--grid", action="store_true")
    args = ap.parse_args()
    data = PreparedData(args.data)
    sk = get_skeleton("tang2018")
    stats = load_foot_constraint().stats
    lower = list(lower_body_cols(sk))
    assert len(stats.dance_mean) == rootdelta_layout(sk).dim
    real = {n: data.motion(n) for n in data.names("val")}
    show("real (val)", [sliding_stats(np.asarray(m.to_positions(), np.float64), sk, m.fps) for m in real.values()])
    for model in ("revolution", "music2dance"):
        files = sorted((Path(args.raw) / model / "val").glob("*.npz"))
        show(f"{model} (val, raw)", [sliding_stats(np.asarray(bench_feet.load(f, sk).to_positions(), np.float64),
                                                   sk, 25.0) for f in files])
    grid = [("paper", 0.1, 2.0)]
    if args.grid:
        grid += [("glide", a, s) for s in (3.0, 6.0, 12.0) for a in (0.15, 0.3, 0.5)]
    for kind, amp, sigma in grid:
        rows = []
        for i, m in enumerate(real.values()):
            z = stats.normalize_dance(encode_rootdelta(m)).astype(np.float64)
            x = stats.denormalize_dance(corrupt(z, kind, amp, sigma, lower, i)).astype(np.float64)
            R0 = m.rotations
            origin = (float(m.root_translation[0, 0]), float(m.root_translation[0, 2]),
                      float(np.arctan2(R0[0, sk.root, 0, 2], R0[0, sk.root, 2, 2])))
            rows.append(sliding_stats(np.asarray(decode_rootdelta(x, sk, m.fps, origin=origin).to_positions(),
                                                 np.float64), sk, m.fps))
        show(f"real + {kind} amp {amp} sigma {sigma}", rows)


if __name__ == "__main__":
    main()
