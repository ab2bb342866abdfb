"""Measure the tang2018 rest offsets and side evidence (run once; numbers are hard-coded in skeleton.py).

Usage::

    python -m dancekit.motion._tang2018_rest ../shared/data/tang2018

Rest offsets: for every bone of the ``tang2018`` tree, the bone vector of
every frame is expressed in a per-frame body frame (x = left = horizontal part
of (joint 16 - joint 7) + (joint 12 - joint 3), y = up, z = forward = left x
up); the mean of these vectors gives the direction, rescaled to the mean bone
length. Also prints the per-bone length standard deviation, and the fraction
of frames in which joints 16 (hip) and 12 (shoulder) lie on the left side by
two independent facing estimates (feet: toe markers minus ankles; knees: knee
minus the hip-ankle midpoint), left = up x forward.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from dancekit.motion.formats.tang2018 import read_tang2018
from dancekit.motion.skeleton import get_skeleton

__all__ = ["measure_rest_offsets", "side_evidence"]

_UP = np.array([0.0, 1.0, 0.0])


def _unit_h(v: np.ndarray) -> np.ndarray:
    v = v.copy()
    v[..., 1] = 0.0
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def measure_rest_offsets(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean-pose offsets (23, 3), mean bone lengths (23,) and their std (23,) from positions (T, 23, 3) in cm."""
    sk = get_skeleton("tang2018")
    p = np.asarray(positions, dtype=np.float64)
    left = _unit_h((p[:, 16] - p[:, 7]) + (p[:, 12] - p[:, 3]))
    fwd = np.cross(left, _UP)
    offsets = np.zeros((23, 3))
    mean_len = np.zeros(23)
    std_len = np.zeros(23)
    for j, par in enumerate(sk.parents):
        if par < 0:
            continue
        v = p[:, j] - p[:, par]
        length = np.linalg.norm(v, axis=-1)
        body = np.stack([(v * left).sum(-1), v[:, 1], (v * fwd).sum(-1)], axis=-1).mean(0)
        offsets[j] = body / np.linalg.norm(body) * length.mean()
        mean_len[j], std_len[j] = length.mean(), length.std()
    return offsets, mean_len, std_len


def side_evidence(positions: np.ndarray) -> dict[str, float]:
    """Fractions of frames where the 16-20 leg / 12-15 arm are on the left, by feet and by knees."""
    p = np.asarray(positions, dtype=np.float64)
    fwd_feet = _unit_h((p[:, 11] + p[:, 20]) / 2 - (p[:, 9] + p[:, 18]) / 2)
    knee = (p[:, 8] - (p[:, 7] + p[:, 9]) / 2) + (p[:, 17] - (p[:, 16] + p[:, 18]) / 2)
    fwd_knee = _unit_h(knee)
    out = {}
    for name, fwd in (("feet", fwd_feet), ("knees", fwd_knee)):
        left = np.cross(_UP, fwd)
        out[f"hip16_left_by_{name}"] = float(((p[:, 16] - p[:, 7]) * left).sum(-1).__gt__(0).mean())
        out[f"shoulder12_left_by_{name}"] = float(((p[:, 12] - p[:, 3]) * left).sum(-1).__gt__(0).mean())
    return out


def main(root: str) -> None:  # pragma: no cover - a measurement script
    folders = sorted(f for f in Path(root).iterdir() if f.is_dir() and f.name.startswith("DANCE_"))
    all_pos = []
    for f in folders:
        m, _ = read_tang2018(f)
        ev = side_evidence(m.positions)
        print(f.name, " ".join(f"{k} {v:.3f}" for k, v in ev.items()))
        all_pos.append(m.positions)
    p = np.concatenate(all_pos)
    off, mean_len, std_len = measure_rest_offsets(p)
    sk = get_skeleton("tang2018")
    print(f"{len(folders)} dances, {len(p)} frames")
    for j, par in enumerate(sk.parents):
        if par >= 0:
            print(f"{j:2d} {sk.joint_names[j]:15s} <- {sk.joint_names[par]:15s} offset "
                  f"[{off[j, 0]:7.2f}, {off[j, 1]:7.2f}, {off[j, 2]:7.2f}]  len {mean_len[j]:6.2f} std {std_len[j]:5.2f}")


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/tang2018")
