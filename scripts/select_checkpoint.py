"""Pick a training run's checkpoint by what the dances look like on the *validation* split.

    python scripts/select_checkpoint.py --run runs/revolution_bal --data data/tang2018 [--seeds 2]
        [--steer] [--min-step 1500] [--install runs/revolution_bal/selected]

The validation loss (L1 at a fixed p) says little about whether a dance follows *its* song: on
tang2018 a model that dances every song as a waltz (19 of 26 training dances are waltzes) reaches a
good L1. This script scores every checkpoint of a run (``RUN/checkpoints/step_*`` and ``RUN/best``)
on the validation songs, never the test songs:

- ``style``: balanced per-window accuracy of the embedded style classifier on the generated dances,
  genre left to the music ("auto"), over ``--seeds`` seeds per song;
- ``stillness``: the largest share of still 1-s windows over the generated dances;
- ``steer`` (``--steer``, models that offer genres): every validation song danced as every genre
  of the model; the share of those dances that the classifier reads back as the requested genre
  (``scripts/genre_steering.py``).

Selection: among checkpoints whose stillness is at most 5 % on every validation song, the highest
``style`` (plus ``steer`` with ``--steer``), ties broken by the lower validation loss. The scores go
to ``RUN/selection.json``; ``--install DIR`` copies the chosen checkpoint's model files there.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

MODEL_FILES = ("config.json", "model.safetensors", "stats.npz")


def candidates(run: Path) -> list[Path]:
    """The run's step checkpoints, plus ``best`` unless it is a copy of one of them."""
    from dancekit._io import file_sha256

    found = [c for c in sorted((run / "checkpoints").glob("step_*")) if (c / "model.safetensors").exists()]
    best = run / "best" / "model.safetensors"
    if best.exists() and file_sha256(best) not in {file_sha256(c / "model.safetensors") for c in found}:
        found.append(best.parent)
    return found


def val_losses(run: Path) -> dict[int, float]:
    losses: dict[int, float] = {}
    log = run / "log.jsonl"
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


def score(ckpt: Path, data, style, *, split: str, seeds: int, steer: bool) -> dict:
    from dancekit.metrics.stability import stillness_share
    from dancekit.metrics.style import evaluate_classifier
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
    scores = evaluate_classifier(style, dances, fps=pipe.fps)
    result = {
        "style": scores["window_balanced_accuracy"],
        "dance_accuracy": scores["dance_accuracy"],
        "stillness_max": float(max(still)),
    }
    if steer:
        from genre_steering import steering

        result["steer"] = steering(pipe, data, style, split=split, progress=False)["read_back"]
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, help="training run folder (with checkpoints/ and log.jsonl)")
    parser.add_argument("--data", required=True, help="prepared dataset folder")
    parser.add_argument("--split", default="val", help="split to score on (default val; never select on test)")
    parser.add_argument("--seeds", type=int, default=2, help="dances per song (default 2)")
    parser.add_argument("--steer", action="store_true", help="also score genre steering")
    parser.add_argument("--max-stillness", type=float, default=0.05)
    parser.add_argument("--min-step", type=int, default=0, help="skip step checkpoints before this step")
    parser.add_argument("--install", help="copy the chosen checkpoint's model files to this folder")
    args = parser.parse_args(argv)

    from tqdm import tqdm

    from dancekit._io import atomic_dir
    from dancekit.data import PreparedData
    from dancekit.metrics.style import load_style_classifier

    run = Path(args.run)
    found = [c for c in candidates(run)
             if not c.name.startswith("step_") or int(c.name.split("_")[-1]) >= args.min_step]
    if not found:
        print(f"select_checkpoint: no checkpoints in {run}", file=sys.stderr)
        return 2
    data = PreparedData(args.data)
    style = load_style_classifier()
    losses = val_losses(run)
    rows = []
    t0 = time.perf_counter()
    for ckpt in tqdm(found, desc="checkpoints", unit="ckpt"):
        step = step_of(ckpt, losses)
        row = {"checkpoint": str(ckpt), "step": step, "val_loss": losses.get(step)}
        row.update(score(ckpt, data, style, split=args.split, seeds=args.seeds, steer=args.steer))
        rows.append(row)
        tqdm.write(json.dumps(row))

    def key(r: dict) -> tuple:
        total = r["style"] + (r.get("steer", 0.0) if args.steer else 0.0)
        return (r["stillness_max"] <= args.max_stillness, round(total, 6),
                -(r["val_loss"] if r["val_loss"] is not None else np.inf))

    chosen = max(rows, key=key)
    report = {"split": args.split, "seeds": args.seeds, "steer": args.steer,
              "rule": f"stillness_max <= {args.max_stillness:.2f}, then max style"
                      f"{' + steer' if args.steer else ''}, then min val_loss",
              "chosen": chosen, "candidates": rows, "elapsed_s": round(time.perf_counter() - t0, 1)}
    (run / "selection.json").write_text(json.dumps(report, indent=1))
    print(f"chosen: {chosen['checkpoint']} (step {chosen['step']}): " + json.dumps(
        {k: chosen[k] for k in ("style", "dance_accuracy", "stillness_max", "steer", "val_loss") if k in chosen}))
    if args.install:
        with atomic_dir(args.install) as tmp:
            for f in MODEL_FILES:
                shutil.copy2(Path(chosen["checkpoint"]) / f, Path(tmp) / f)
        print(f"installed to {args.install}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
