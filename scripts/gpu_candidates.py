"""Candidate folders from a training run's checkpoints, each danced with an embedded model's settings.

    python scripts/gpu_candidates.py runs/gpu/dual_a/run --model dual -o runs/gpu/cand
    # -> runs/gpu/cand/dual_a-best, dual_a-step_0000462, ...: each the embedded `dual` folder (its "stages",
    #    "sampling", "genre_stats" and components: the genre reader, the Foot Constraint Model) with the
    #    checkpoint's weights, statistics and model configuration

so that a retrained model is scored with exactly the pipeline settings of the model it would replace (only the
network differs): ``dancekit evaluate --checkpoint runs/gpu/cand/NAME --data data/tang2018 --split val``.
``fmap_checkpoint`` (a training-time initialisation path) is cleared: the F_map weights are in the checkpoint.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "src" / "dancekit" / "assets" / "models"
FROM_RUN = ("config", "step", "train", "val_loss", "data", "init")  # the network's own entries


def candidate(checkpoint: Path, model: str, dst: Path) -> Path:
    shipped = MODELS / model
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(shipped, dst, ignore=shutil.ignore_patterns("card.json"))
    cfg = json.loads((shipped / "config.json").read_text())
    run = json.loads((checkpoint / "config.json").read_text())
    if run.get("model") != cfg.get("model"):
        sys.exit(f"error: {checkpoint} is a {run.get('model')!r} checkpoint, not {cfg.get('model')!r}")
    for key in FROM_RUN:
        if key in run:
            cfg[key] = run[key]
        else:
            cfg.pop(key, None)
    if "fmap_checkpoint" in cfg["config"]:
        cfg["config"]["fmap_checkpoint"] = ""
    for name in ("model.safetensors", "stats.npz"):
        shutil.copy(checkpoint / name, dst / name)
    (dst / "config.json").write_text(json.dumps(cfg, indent=1))
    return dst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a `dancekit train` run folder (best/, checkpoints/step_*)")
    ap.add_argument("--model", required=True, help="the embedded model whose settings the candidates take")
    ap.add_argument("-o", "--output", type=Path, required=True, help="folder of the candidate folders")
    ap.add_argument("--steps", default="", help="comma-separated steps to keep (default: best and every step)")
    args = ap.parse_args(argv)
    name = args.run.parent.name if args.run.name == "run" else args.run.name
    sources = [("best", args.run / "best")] + [(p.name, p) for p in sorted((args.run / "checkpoints").glob("step_*"))]
    if args.steps:
        keep = {int(s) for s in args.steps.split(",")}
        sources = [(n, p) for n, p in sources if n == "best" or int(n.split("_")[1]) in keep]
    for label, src in sources:
        out = candidate(src, args.model, args.output / f"{name}-{label}")
        print(out, "step", json.loads((out / "config.json").read_text()).get("step"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
