"""Calibrating baselines for ``dancekit evaluate``: what do trivial "models" score? (``dancekit baselines``)

For every dance of the test split, one ``NAME.npz`` per baseline is written into ``OUT/<baseline>/``:

``ground_truth``     the real test dance itself
``mean_pose``        a frozen dance: the mean training pose (joints relative to the pelvis, averaged
                     in the body's heading frame), placed where and as the test dance starts
``random_train``     a random training dance (seeded): real motion, wrong music, cropped (or
                     looped) to the test dance's length
``nearest_music``    retrieval: the training dance whose mean ``revolution`` music features
                     (z-scored with the training statistics) are closest to the test song's,
                     cropped (or looped) to the test length

Each folder is then scored by :func:`~dancekit.evaluation.evaluate_dirs` exactly as ``dancekit evaluate
--pred OUT/<baseline> --ref DATA --data DATA`` would (``OUT/<baseline>.json``); the combined markdown
table goes to ``OUT/table.md`` and the source dances of the two copying baselines to ``OUT/choices.json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._io import atomic_dir, atomic_path
from dancekit.evaluation.report import metrics_table
from dancekit.evaluation.score import EvalSettings, evaluate_dirs
from dancekit.motion.analysis import heading_rotation

__all__ = ["BASELINES", "make_baselines", "run_baselines"]

BASELINES = ("ground_truth", "mean_pose", "random_train", "nearest_music")


def _fit_length(positions: np.ndarray, T: int, skeleton: Any) -> np.ndarray:
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


def _mean_local_pose(data: Any, names: list[str]) -> np.ndarray:
    """Mean pose in the heading frame (J, 3), skeleton units."""
    sk = data.skeleton
    total, count = 0.0, 0
    for n in names:
        p = data.motion(n).to_positions().astype(np.float64)
        R = heading_rotation(p, sk)  # (T, 3, 3) world -> body
        local = np.einsum("tij,tkj->tki", R, p - p[:, sk.root : sk.root + 1])
        total = total + local.sum(axis=0)
        count += len(p)
    return total / count


def _place(local: np.ndarray, gt: np.ndarray, skeleton: Any, T: int) -> np.ndarray:
    """A frozen dance: ``local`` rotated to the heading of ``gt``'s first frame, at its first root."""
    R = heading_rotation(gt[:1].astype(np.float64), skeleton)[0]  # (3, 3) world -> body
    pose = local @ R + gt[0, skeleton.root]
    return np.repeat(pose[None], T, axis=0)


def make_baselines(data_root: str | os.PathLike, out: str | os.PathLike, *, seed: int = 0) -> dict[str, Path]:
    """Write the baseline dances (see the module docstring) into ``out/<baseline>/``; returns the folders."""
    from dancekit.data import PreparedData
    from dancekit.motion import Motion, write_motion

    out = Path(out)
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
    choices: dict[str, dict[str, str]] = {}
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


def run_baselines(data_root: str | os.PathLike, out: str | os.PathLike, *, seed: int = 0,
                  progress: bool = True) -> tuple[dict[str, dict], str]:
    """Write and score every baseline (:func:`make_baselines`); returns ``(reports, table)``.

    Writes ``out/<baseline>.json`` (each report) and ``out/table.md`` (the table of all of them).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    folders = make_baselines(data_root, out, seed=seed)
    reports = {}
    for b, folder in folders.items():
        reports[b] = evaluate_dirs(folder, data_root, data=data_root, settings=EvalSettings(seed=seed))
        with atomic_path(out / f"{b}.json") as tmp:
            tmp.write_text(json.dumps(reports[b], indent=1))
        if progress:
            print(f"{b}: done")
    first = reports[BASELINES[0]]
    c, st = first["counts"], first["settings"]
    table = metrics_table([(b, reports[b]["metrics"]) for b in BASELINES]) + "\n\n" + (
        f"{c['songs']} test dances; FID reference: {st['fid_reference']} split ({c['fid_reference_dances']} dances); "
        f"FID_k / FID_g on {st['segment_seconds']}-s segments; BAS sigma {st['sigma']} s; "
        f"hit tolerance {st['tolerance']} s.\n")
    with atomic_path(out / "table.md") as tmp:
        tmp.write_text(table)
    return reports, table
