"""Pick a training run's checkpoint by what its dances look like on the *validation* split
(``dancekit select-checkpoint``).

The validation loss (L1 at a fixed p) says little about whether a dance follows *its* song: on tang2018 a
model that dances every song as a waltz (19 of 26 training dances are waltzes) reaches a good L1.
:func:`select_checkpoint` scores every checkpoint of a run (``RUN/checkpoints/step_*`` and ``RUN/best``)
on the validation songs, never the test songs:

- ``style``: balanced per-window accuracy of the style classifier on the generated dances, genre left to
  the music ("auto"), over ``seeds`` seeds per song;
- ``stillness``: the largest share of still 1-s windows over the generated dances;
- ``steer`` (``steer=True``, models that offer genres): every validation song danced as every genre of the
  model; the share of those dances that the classifier reads back as the requested genre
  (:func:`~dancekit.evaluation.steering`).

Selection: among checkpoints whose stillness is at most ``max_stillness`` on every validation song, the
highest ``style`` (plus ``steer``), ties broken by the lower validation loss.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import DatasetError
from dancekit.evaluation.classifiers import style_classifier_scores
from dancekit.evaluation.steering import steering
from dancekit.metrics.stability import stillness_share

__all__ = ["candidates", "score_checkpoint", "select_checkpoint", "step_of", "val_losses"]


def candidates(run: str | os.PathLike) -> list[Path]:
    """The run's step checkpoints, plus ``best`` unless it is a copy of one of them."""
    from dancekit._io import file_sha256

    run = Path(run)
    found = [c for c in sorted((run / "checkpoints").glob("step_*")) if (c / "model.safetensors").exists()]
    best = run / "best" / "model.safetensors"
    if best.exists() and file_sha256(best) not in {file_sha256(c / "model.safetensors") for c in found}:
        found.append(best.parent)
    return found


def val_losses(run: str | os.PathLike) -> dict[int, float]:
    """Step → validation loss, from the run's ``log.jsonl``."""
    losses: dict[int, float] = {}
    log = Path(run) / "log.jsonl"
    if log.exists():
        for line in log.read_text().splitlines():
            rec = json.loads(line)
            if "val_loss" in rec:
                losses[int(rec["step"])] = float(rec["val_loss"])
    return losses


def step_of(ckpt: Path, losses: dict[int, float]) -> int | None:
    """A step folder's step; for ``best``, the step of the lowest validation loss."""
    if ckpt.name.startswith("step_"):
        return int(ckpt.name.split("_")[-1])
    return min(losses, key=losses.get) if losses else None


def score_checkpoint(ckpt: str | os.PathLike, data: Any, style: Any, *, split: str, seeds: int,
                     steer: bool) -> dict[str, float]:
    """``style``, ``dance_accuracy``, ``stillness_max`` (and ``steer``) of one checkpoint on ``split``."""
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline(checkpoint=ckpt)
    dances: list[tuple[np.ndarray, int]] = []
    still: list[float] = []
    for name in data.names(split):
        ref = data.audio(name)
        for k in range(seeds):
            m = pipe(ref.path, seed=k, start=ref.start, end=ref.end).motion
            p = m.to_positions()
            dances.append((p, style.genres.index(data.genre(name))))
            still.append(stillness_share(p, fps=m.fps, skeleton=m.skeleton))
    scores = style_classifier_scores(style, dances, fps=pipe.fps)
    result = {
        "style": scores["window_balanced_accuracy"],
        "dance_accuracy": scores["dance_accuracy"],
        "stillness_max": float(max(still)),
    }
    if steer:
        result["steer"] = steering(pipe, data, style, split=split, progress=False)["read_back"]
    return result


def select_checkpoint(
    run: str | os.PathLike,
    data: Any,
    *,
    split: str = "val",
    seeds: int = 2,
    steer: bool = False,
    max_stillness: float = 0.05,
    min_step: int = 0,
    style: Any = "default",
    progress: bool = True,
) -> dict[str, Any]:
    """Score every checkpoint of ``run`` on ``split`` and choose one (see the module docstring).

    Parameters
    ----------
    run : training run folder (``checkpoints/``, ``best/``, ``log.jsonl``)
    data : a :class:`~dancekit.data.PreparedData`
    split : the songs to score on (the validation split: never select on the test split)
    seeds : dances per song
    steer : also score genre steering
    max_stillness : the largest admissible stillness share
    min_step : skip step checkpoints before this step
    style : the style classifier (see :func:`~dancekit.evaluation.load_classifier`)

    Returns
    -------
    The report (also written to ``RUN/selection.json``): ``chosen`` (a candidate row), ``candidates``
    (``checkpoint``, ``step``, ``val_loss`` and the scores of each), ``rule``, ``split``, ``seeds``.

    Raises
    ------
    DatasetError
        When the run holds no checkpoint (from ``min_step`` on).
    """
    from tqdm import tqdm

    from dancekit.evaluation.score import load_classifier

    run = Path(run)
    found = [c for c in candidates(run) if not c.name.startswith("step_") or int(c.name.split("_")[-1]) >= min_step]
    if not found:
        raise DatasetError(f"no checkpoints in {run}" + (f" from step {min_step} on" if min_step else ""))
    clf, note = load_classifier(style)
    if clf is None:
        raise DatasetError(note or "checkpoint selection needs a style classifier")
    losses = val_losses(run)
    rows = []
    t0 = time.perf_counter()
    for ckpt in tqdm(found, desc="checkpoints", unit="ckpt", disable=not progress):
        step = step_of(ckpt, losses)
        row: dict[str, Any] = {"checkpoint": str(ckpt), "step": step, "val_loss": losses.get(step)}
        row.update(score_checkpoint(ckpt, data, clf, split=split, seeds=seeds, steer=steer))
        rows.append(row)
        if progress:
            tqdm.write(json.dumps(row))

    def key(r: dict) -> tuple:
        total = r["style"] + (r.get("steer", 0.0) if steer else 0.0)
        return (r["stillness_max"] <= max_stillness, round(total, 6),
                -(r["val_loss"] if r["val_loss"] is not None else np.inf))

    chosen = max(rows, key=key)
    report = {"split": split, "seeds": seeds, "steer": steer,
              "rule": f"stillness_max <= {max_stillness:.2f}, then max style"
                      f"{' + steer' if steer else ''}, then min val_loss",
              "chosen": chosen, "candidates": rows, "elapsed_s": round(time.perf_counter() - t0, 1)}
    with atomic_path(run / "selection.json") as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    return report
