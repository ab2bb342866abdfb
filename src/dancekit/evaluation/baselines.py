"""Calibrating baselines for ``dancekit evaluate``: what do trivial "models" score? (``dancekit baselines``)

For every dance of the test split, one ``NAME.npz`` per baseline is written into ``OUT/<baseline>/``:

``ground_truth``     the real test dance itself
``mean_pose``        a frozen dance: the mean training pose (joints relative to the pelvis, averaged
                     in the body's heading frame), placed where and as the test dance starts
``random_train``     a random training dance (seeded): real motion, wrong music, cropped (or
                     looped) to the test dance's length; drawn ``draws`` times (default 10) into
                     ``OUT/random_train_draws/KK/``, each draw scored on its own (``KK.json`` beside it)
``nearest_music``    retrieval: the training dance whose mean ``revolution`` music features
                     (z-scored with the training statistics) are closest to the test song's,
                     cropped (or looped) to the test length

Each folder is then scored by :func:`~dancekit.evaluation.evaluate_dirs` exactly as ``dancekit evaluate
--pred OUT/<baseline> --ref DATA --data DATA`` would (``OUT/<baseline>.json``); the combined markdown
table goes to ``OUT/table.md`` and the source dances of the two copying baselines to ``OUT/choices.json``
(``random_train``: one ``{test dance: training dance}`` mapping per draw).

One random draw is not a baseline: over 10 draws the random dance's FID_k spans 21-51 on tang2018 (issue 41).
``OUT/random_train.json`` therefore summarises the draws: its ``metrics`` are the **median over the draws of
each metric** (each metric's own median, not one draw's metrics), ``min`` / ``max`` the extremes of each
metric over the draws and ``draws`` every draw's metrics; the table shows the median column (the one the
cards and docs/BENCHMARKS.md quote) with the min and max columns beside it. Draw 0 is the dance set of the
earlier single-draw baseline (the same seeded generator, drawn first).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._io import atomic_dir, atomic_path
from dancekit.errors import DatasetError, ParameterError
from dancekit.evaluation.report import metrics_table
from dancekit.evaluation.score import EvalSettings, evaluate_dirs
from dancekit.motion.analysis import heading_rotation

__all__ = ["BASELINES", "DEFAULT_DRAWS", "make_baselines", "run_baselines", "summarize_draws"]

BASELINES = ("ground_truth", "mean_pose", "random_train", "nearest_music")
DEFAULT_DRAWS = 10  # random training dances drawn for random_train (its min / median / max)
DRAWS_FOLDER = "random_train_draws"


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


def make_baselines(data_root: str | os.PathLike, out: str | os.PathLike, *, seed: int = 0,
                   draws: int = DEFAULT_DRAWS) -> dict[str, Path | list[Path]]:
    """Write the baseline dances (see the module docstring) into ``out/<baseline>/``; returns the folders
    (``"random_train"``: the list of the ``draws`` folders ``out/random_train_draws/KK``)."""
    from dancekit.data import PreparedData
    from dancekit.motion import Motion, write_motion

    if not isinstance(draws, int) or isinstance(draws, bool) or draws < 1:
        raise ParameterError(f"the number of random draws must be a whole number >= 1, got {draws!r}")
    out = Path(out)
    data = PreparedData(data_root)
    sk, fps = data.skeleton, data.fps
    test, train = data.names("test"), data.names("train")
    if not test or not train:
        raise DatasetError(f"{data_root}: baselines need a test and a train split "
                           f"({len(test)} test, {len(train)} train dances)")
    rng = np.random.default_rng(seed)
    local = _mean_local_pose(data, train)
    feats = {n: np.asarray(data.features(n, "revolution")["features"], np.float64) for n in test + train}
    allf = np.concatenate([feats[n] for n in train])
    mu, sd = allf.mean(0), np.maximum(allf.std(0), 1e-6)
    mean_feat = {n: ((feats[n] - mu) / sd).mean(0) for n in feats}
    folders: dict[str, Path | list[Path]] = {}
    choices: dict[str, Any] = {}

    def write(folder: Path, pick) -> None:
        with atomic_dir(folder) as tmp:
            for n in test:
                gt = data.motion(n).to_positions()
                p = pick(n, gt)
                write_motion(tmp / f"{n}.npz", Motion(skeleton=sk, fps=fps, positions=np.asarray(p, np.float32)))

    def copy_of(src: str, gt: np.ndarray) -> np.ndarray:
        return _fit_length(data.motion(src).to_positions(), len(gt), sk)

    write(out / "ground_truth", lambda n, gt: gt)
    write(out / "mean_pose", lambda n, gt: _place(local, gt, sk, len(gt)))
    draw_folders, drawn = [], []
    for k in range(draws):  # one generator drawn in turn: draw 0 is the earlier single draw
        srcs = {n: train[int(rng.integers(len(train)))] for n in test}
        drawn.append(srcs)
        draw_folders.append(out / DRAWS_FOLDER / f"{k:02d}")
        write(draw_folders[-1], lambda n, gt, srcs=srcs: copy_of(srcs[n], gt))
    choices["random_train"] = drawn
    nearest = {n: min(train, key=lambda m: float(np.linalg.norm(mean_feat[m] - mean_feat[n]))) for n in test}
    choices["nearest_music"] = nearest
    write(out / "nearest_music", lambda n, gt: copy_of(nearest[n], gt))
    folders.update(ground_truth=out / "ground_truth", mean_pose=out / "mean_pose", random_train=draw_folders,
                   nearest_music=out / "nearest_music")
    with atomic_path(out / "choices.json") as tmp:
        tmp.write_text(json.dumps(choices, indent=1))
    return folders


def summarize_draws(reports: list[dict[str, Any]]) -> dict[str, Any]:
    """One report for several scored draws of a baseline: ``metrics`` the median over the draws of each
    numeric metric (NaN / missing values left out; None where no draw has one), ``min`` / ``max`` the
    extremes, ``draws`` the draws' metrics in order; ``real``, ``counts``, ``settings`` of the first draw."""
    if not reports:
        raise ParameterError("no draws to summarise")
    keys = [k for k in reports[0]["metrics"] if all(isinstance(r["metrics"].get(k), (int, float, type(None)))
                                                    and not isinstance(r["metrics"].get(k), bool)
                                                    for r in reports)]
    med, lo, hi = {}, {}, {}
    for k in keys:
        v = np.asarray([r["metrics"][k] for r in reports if r["metrics"].get(k) is not None], np.float64)
        v = v[np.isfinite(v)]
        med[k], lo[k], hi[k] = ((float(np.median(v)), float(v.min()), float(v.max())) if v.size
                                else (None, None, None))
    first = reports[0]
    return {"metrics": med, "min": lo, "max": hi, "draws": [r["metrics"] for r in reports],
            "real": first.get("real"), "counts": first.get("counts"), "settings": first.get("settings"),
            "notes": [f"median, min and max of each metric over {len(reports)} random draws "
                      "(each metric's own median: not the metrics of one draw)"]}


def run_baselines(data_root: str | os.PathLike, out: str | os.PathLike, *, seed: int = 0,
                  draws: int = DEFAULT_DRAWS, progress: bool = True) -> tuple[dict[str, dict], str]:
    """Write and score every baseline (:func:`make_baselines`); returns ``(reports, table)``.

    Writes ``out/<baseline>.json`` (each report; ``random_train.json`` the summary of the draws,
    :func:`summarize_draws`, each draw's report in ``out/random_train_draws/KK.json``) and ``out/table.md``
    (the table of all of them: the random draws' median, min and max in three columns).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    folders = make_baselines(data_root, out, seed=seed, draws=draws)
    reports = {}

    def score(folder: Path, path: Path, label: str) -> dict:
        report = evaluate_dirs(folder, data_root, data=data_root, settings=EvalSettings(seed=seed))
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(report, indent=1))
        if progress:
            print(f"{label}: done")
        return report

    for b in BASELINES:
        if b == "random_train":
            runs = [score(f, f.parent / f"{f.name}.json", f"{b} draw {k}") for k, f in enumerate(folders[b])]
            reports[b] = summarize_draws(runs)
            with atomic_path(out / f"{b}.json") as tmp:
                tmp.write_text(json.dumps(reports[b], indent=1))
        else:
            reports[b] = score(folders[b], out / f"{b}.json", b)
    first = reports[BASELINES[0]]
    c, st = first["counts"], first["settings"]
    rt = reports["random_train"]
    columns = [("ground_truth", reports["ground_truth"]["metrics"]), ("mean_pose", reports["mean_pose"]["metrics"]),
               (f"random_train (median of {draws})", rt["metrics"]), ("random_train min", rt["min"]),
               ("random_train max", rt["max"]), ("nearest_music", reports["nearest_music"]["metrics"])]
    table = metrics_table(columns) + "\n\n" + (
        f"{c['songs']} test dances; FID reference: {st['fid_reference']} split ({c['fid_reference_dances']} dances); "
        f"FID_k / FID_g on {st['segment_seconds']}-s segments; BAS sigma {st['sigma']} s; "
        f"hit tolerance {st['tolerance']} s; random_train: {draws} draws (seed {seed}), each metric's median, "
        "min and max over the draws.\n")
    with atomic_path(out / "table.md") as tmp:
        tmp.write_text(table)
    return reports, table
