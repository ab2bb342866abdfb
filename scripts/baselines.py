"""Calibrating baselines for ``dancekit evaluate``: what do trivial "models" score?

    python scripts/baselines.py --data data/tang2018 --out runs/baselines

For every dance of the test split, writes one ``NAME.npz`` per baseline into ``OUT/<baseline>/``:

``ground_truth``     the real test dance itself
``mean_pose``        a frozen dance: the mean training pose (joints relative to the pelvis, averaged
                     in the body's heading frame), placed where and as the test dance starts
``random_train``     a random training dance (seeded): real motion, wrong music, cropped (or
                     looped) to the test dance's length
``nearest_music``    retrieval: the training dance whose mean ``revolution`` music features
                     (z-scored with the training statistics) are closest to the test song's,
                     cropped (or looped) to the test length

Each folder is then scored by the same code as ``dancekit evaluate --pred OUT/<baseline> --ref DATA
--data DATA`` (``OUT/<baseline>.json``); the combined markdown table goes to ``OUT/table.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from dancekit._io import atomic_dir, atomic_path
from dancekit.errors import DancekitError

BASELINES = ("ground_truth", "mean_pose", "random_train", "nearest_music")


def _fit_length(positions: np.ndarray, T: int, skeleton) -> np.ndarray:
    """Crop to ``T`` frames, or loop (each repeat continues horizontally from where the root stopped)."""
    out = [positions]
    n = len(positions)
    r, up = skeleton.root, skeleton.up_index
    while n < T:
        shift = out[-1][-1, r] - positions[0, r]
        shift[up] = 0.0  # keep heights
        out.append(positions + shift)
        n += len(positions)
    return np.concatenate(out)[:T]


def _mean_local_pose(data, names) -> np.ndarray:
    """Mean pose in the heading frame (J, 3), skeleton units."""
    from dancekit.metrics.style import _heading_axes

    sk = data.skeleton
    total, count = 0.0, 0
    for n in names:
        p = data.motion(n).to_positions().astype(np.float64)
        lat, up, fwd = _heading_axes(p, sk)
        R = np.stack([lat, up, fwd], axis=1)
        local = np.einsum("tij,tkj->tki", R, p - p[:, sk.root : sk.root + 1])
        total = total + local.sum(axis=0)
        count += len(p)
    return total / count


def _place(local: np.ndarray, gt: np.ndarray, skeleton, T: int) -> np.ndarray:
    """A frozen dance: ``local`` rotated to the heading of ``gt``'s first frame, at its first root."""
    from dancekit.metrics.style import _heading_axes

    lat, up, fwd = _heading_axes(gt[:1].astype(np.float64), skeleton)
    R = np.stack([lat[0], up[0], fwd[0]], axis=0)  # world -> body
    pose = local @ R + gt[0, skeleton.root]
    return np.repeat(pose[None], T, axis=0)


def make_baselines(data_root: str, out: Path, *, seed: int = 0) -> dict[str, Path]:
    from dancekit.data import PreparedData
    from dancekit.motion import Motion, write_motion

    data = PreparedData(data_root)
    sk, fps = data.skeleton, data.fps
    test, train = data.names("test"), data.names("train")
    rng = np.random.default_rng(seed)
    local = _mean_local_pose(data, train)
    feats = {n: np.asarray(data.features(n, "revolution")["features"], np.float64) for n in test + train}
    allf = np.concatenate([feats[n] for n in train])
    mu, sd = allf.mean(0), np.maximum(allf.std(0), 1e-6)
    mean_feat = {n: ((feats[n] - mu) / sd).mean(0) for n in feats}
    folders = {}
    choices = {}
    for b in BASELINES:
        with atomic_dir(out / b) as tmp:
            for n in test:
                gt = data.motion(n).to_positions()
                T = len(gt)
                if b == "ground_truth":
                    p = gt
                elif b == "mean_pose":
                    p = _place(local, gt, sk, T)
                elif b == "random_train":
                    src = train[int(rng.integers(len(train)))]
                    choices.setdefault(b, {})[n] = src
                    p = _fit_length(data.motion(src).to_positions(), T, sk)
                else:
                    src = min(train, key=lambda m: float(np.linalg.norm(mean_feat[m] - mean_feat[n])))
                    choices.setdefault(b, {})[n] = src
                    p = _fit_length(data.motion(src).to_positions(), T, sk)
                write_motion(tmp / f"{n}.npz", Motion(skeleton=sk, fps=fps, positions=np.asarray(p, np.float32)))
        folders[b] = out / b
    with atomic_path(out / "choices.json") as tmp:
        tmp.write_text(json.dumps(choices, indent=1))
    return folders


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, help="prepared dataset folder")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    from dancekit.metrics.evaluate import TABLE_ROWS, EvalSettings, _fmt, evaluate_dirs

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        folders = make_baselines(args.data, out, seed=args.seed)
        reports = {}
        for b, folder in folders.items():
            reports[b] = evaluate_dirs(folder, args.data, data=args.data, settings=EvalSettings(seed=args.seed))
            with atomic_path(out / f"{b}.json") as tmp:
                tmp.write_text(json.dumps(reports[b], indent=1))
            print(f"{b}: done")
    except DancekitError as exc:
        print(f"baselines: error: {exc}", file=sys.stderr)
        return 2
    lines = ["| metric | " + " | ".join(BASELINES) + " |", "| --- |" + " ---: |" * len(BASELINES)]
    for key, label, fmt in TABLE_ROWS:
        values = [reports[b]["metrics"].get(key) for b in BASELINES]
        if all(v is None for v in values):
            continue
        lines.append(f"| {label} | " + " | ".join(_fmt(v, fmt) for v in values) + " |")
    first = reports[BASELINES[0]]
    c = first["counts"]
    lines += ["", f"{c['songs']} test dances; FID reference: {first['settings']['fid_reference']} split "
              f"({c['fid_reference_dances']} dances); FID_k / FID_g on {first['settings']['segment_seconds']}-s "
              f"segments; BAS sigma {first['settings']['sigma']} s; hit tolerance {first['settings']['tolerance']} s."]
    table = "\n".join(lines) + "\n"
    with atomic_path(out / "table.md") as tmp:
        tmp.write_text(table)
    print(table, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
