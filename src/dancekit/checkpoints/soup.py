"""Weight averaging of checkpoints fine-tuned from one base ("model soup", Wortsman et al., ICML 2022).

Runs of one fine-tuning recipe that start from the same pretrained weights and differ only in their seed
tend to stay in one basin of the loss; the element-wise mean of their weights then keeps what the runs
share and averages out each run's own drift. :func:`average_checkpoints` writes that mean as a new
checkpoint folder (:mod:`dancekit.checkpoints.folder`), which loads like any other.

Only checkpoints that can be averaged are accepted: the same model family and configuration, the same
tensor names, shapes and dtypes, identical integer tensors and identical normalisation statistics (the
same training data). Anything else is a :class:`~dancekit.errors.CheckpointError` naming the folder.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._io import atomic_dir
from dancekit.errors import CheckpointError, ParameterError

__all__ = ["average_checkpoints"]


def _load(folder: Path) -> tuple[dict[str, Any], dict[str, Any], dict[str, np.ndarray]]:
    from dancekit.checkpoints.folder import read_config, read_stats, read_weights

    return read_config(folder), read_weights(folder), read_stats(folder)


def average_checkpoints(
    folders: Sequence[str | os.PathLike],
    out: str | os.PathLike,
    *,
    weights: Sequence[float] | None = None,
    keep: Sequence[str] = (),
) -> Path:
    """Write the (weighted) element-wise mean of several checkpoints' weights as a new checkpoint.

    Parameters
    ----------
    folders : two or more checkpoint folders of one family and configuration, trained on the same data
        (identical ``stats.npz``)
    out : the folder to write (replaced atomically if it exists)
    weights : one non-negative weight per folder (normalised to sum 1); default: equal weights
    keep : names of tensors that are state, not weights, copied from the first folder instead of averaged (e.g.
        the dual model's pool of training start poses, ``("pose_pool", "pool_count")``)

    Returns
    -------
    ``out``. Its ``config.json`` is the first folder's, with ``"soup": {"folders": [...], "weights": [...],
    "kept": [...]}`` added; floating-point tensors are averaged in float64 and stored in their own dtype, integer
    tensors (which must be equal) and the ``keep`` tensors are copied from the first folder, and so are the
    first folder's sub-folders (the components its ``config.json`` declares, e.g. ``music_attributes/``).

    Raises
    ------
    ParameterError
        Fewer than two folders, or bad weights.
    CheckpointError
        A folder that is not a checkpoint, or checkpoints that cannot be averaged.
    """
    import torch
    from safetensors.torch import save_file

    from dancekit.checkpoints.folder import CONFIG_FILE, STATS_FILE, WEIGHTS_FILE

    paths = [Path(f) for f in folders]
    if len(paths) < 2:
        raise ParameterError(f"averaging needs at least two checkpoints, got {len(paths)}")
    if weights is None:
        w = np.full(len(paths), 1.0 / len(paths))
    else:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (len(paths),) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ParameterError(f"weights must be {len(paths)} non-negative numbers with a positive sum, got "
                                 f"{list(weights)}")
        w = w / w.sum()
    first_meta, first_state, first_stats = _load(paths[0])
    missing = sorted(set(keep) - set(first_state))
    if missing:
        raise ParameterError(f"keep names tensors that {paths[0]} does not have: {missing}")
    kept = set(keep)

    def averaged(k: str, v: torch.Tensor) -> bool:
        return v.is_floating_point() and k not in kept

    acc = {k: v.to(torch.float64) * w[0] if averaged(k, v) else v.clone() for k, v in first_state.items()}
    for path, wi in zip(paths[1:], w[1:], strict=True):
        meta, state, stats = _load(path)
        if meta["model"] != first_meta["model"] or meta["config"] != first_meta["config"]:
            raise CheckpointError(f"cannot average {path}: its model family or configuration differs from "
                                  f"{paths[0]}'s")
        if set(state) != set(first_state):
            diff = sorted(set(state) ^ set(first_state))[:3]
            raise CheckpointError(f"cannot average {path}: its tensors differ from {paths[0]}'s (e.g. {diff})")
        for k, v in state.items():
            ref = first_state[k]
            if v.shape != ref.shape or v.dtype != ref.dtype:
                raise CheckpointError(f"cannot average {path}: tensor {k!r} is {tuple(v.shape)} {v.dtype}, "
                                      f"{tuple(ref.shape)} {ref.dtype} in {paths[0]}")
            if averaged(k, v):
                acc[k] += v.to(torch.float64) * wi
            elif k not in kept and not torch.equal(v, ref):
                raise CheckpointError(f"cannot average {path}: integer tensor {k!r} differs from {paths[0]}'s")
        if set(stats) != set(first_stats) or any(not np.array_equal(stats[k], first_stats[k]) for k in stats):
            raise CheckpointError(f"cannot average {path}: its {STATS_FILE} differs from {paths[0]}'s "
                                  "(trained on other data?)")
    state = {k: (v.to(first_state[k].dtype) if averaged(k, first_state[k]) else v).contiguous()
             for k, v in acc.items()}
    doc = dict(first_meta)
    doc["soup"] = {"folders": [os.fspath(p.resolve()) for p in paths], "weights": [float(x) for x in w],
                   "kept": sorted(kept)}
    with atomic_dir(out) as tmp:
        for sub in sorted(p for p in paths[0].iterdir() if p.is_dir()):
            shutil.copytree(sub, tmp / sub.name)
        (tmp / CONFIG_FILE).write_text(json.dumps(doc, indent=1))
        save_file(state, str(tmp / WEIGHTS_FILE))
        np.savez(tmp / STATS_FILE, **first_stats)
    return Path(out)
