"""Training on the CPU: seconds a step of every dance model family, and what its schedule costs.

    python benchmarks/bench_train.py --data data/tang2018 [--families revolution,music2dance,dual,music_attributes]
                                     [--threads 1,2] [--steps 12] [--json docs/results/train_speed.json]

Each (family, recipe, threads) trains ``--steps`` steps in a fresh process (``dancekit train FAMILY --data DATA
--set steps=N --set threads=T``, the family's defaults otherwise; no validation or checkpoint among the timed
steps). The seconds a step are the training log's elapsed time from its first logged step (a quarter of
``--steps``) to the last, over the steps between: start-up, data loading and the first steps are left out. The
schedule's time is the recipe's steps at that rate (validation and checkpoints not counted). Recipes: each
family's defaults, and the recipes of the embedded ``music2dance`` (batch 256, music dropout, genre-balanced
windows) and ``dual`` (a 16-d latent, batch 64), which the long runs of docs/research use. The peak resident
memory is the training process's. Run it on a quiet machine (the 1-minute load average is printed).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: (family, recipe name, extra settings, steps of the schedule it is run for; None: the family's default)
RECIPES = (
    ("revolution", "default", (), None),
    ("music2dance", "default", (), None),
    ("music2dance", "embedded (GPU round 2), batch 256", (
        "fmap_checkpoint=src/dancekit/assets/models/revolution/music_attributes", "music_dropout=0.3",
        "balance_genres=true", "batch_size=256"), 4800),
    ("dual", "default", (), None),
    ("dual", "embedded (latent 16), batch 64", ("latent_dim=16", "kl_free_bits=0.5", "dropout=0.2",
                                                 "batch_size=64"), 6000),
    ("music_attributes", "default", (), None),
)

# the child: `dancekit train ...`, then its own peak resident memory on stderr
CHILD = """import resource, sys
from dancekit.cli.main import main
try:
    rc = main(sys.argv[1:])
except SystemExit as e:
    rc = e.code
print("PEAK_RSS_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)
sys.exit(rc or 0)
"""


def defaults(family: str) -> tuple[int, int, int]:
    """``(steps, batch_size, seq_len)`` of the family's default training recipe."""
    from dancekit import registry
    from dancekit.training.config import TrainConfig

    c = TrainConfig.from_saved({}, defaults=registry.get(family).train_defaults)  # as `dancekit train` builds it
    return c.steps, c.batch_size, c.seq_len


def one(family: str, sets: tuple[str, ...], *, data: str, threads: int, steps: int) -> dict:
    """Seconds a step and peak memory of ``steps`` steps of ``family`` with ``sets``, in a fresh process."""
    every = max(1, steps // 4)
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-c", CHILD, "train", family, "--data", data, "--out", f"{tmp}/run", "--quiet",
               "--set", f"steps={steps}", "--set", f"threads={threads}", "--set", f"log_every={every}",
               "--set", "val_every=1000000", "--set", "ckpt_every=1000000"]
        for s in sets:
            cmd += ["--set", s]
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        if p.returncode:
            raise SystemExit(f"{family} {sets}: dancekit train failed:\n{p.stderr[-2000:]}")
        rows = [json.loads(line) for line in open(f"{tmp}/run/log.jsonl") if '"elapsed_s"' in line]
    rows = [r for r in rows if "step" in r]
    a, b = rows[0], rows[-1]
    rss = [int(line.split()[1]) for line in p.stderr.splitlines() if line.startswith("PEAK_RSS_KB")]
    return {"s_per_step": (b["elapsed_s"] - a["elapsed_s"]) / (b["step"] - a["step"]),
            "peak_rss_mb": rss[-1] / 1024 if rss else float("nan")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="data/tang2018", help="prepared dataset (dancekit prepare)")
    ap.add_argument("--families", default=None, help="comma-separated families (default: all of RECIPES)")
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    ap.add_argument("--steps", type=int, default=12, help="steps a run (>= 8)")
    ap.add_argument("--json", default=None, help="write the figures in the docs/results shape")
    args = ap.parse_args()
    if args.steps < 8:
        raise SystemExit("--steps must be at least 8")
    families = None if args.families is None else set(args.families.split(","))
    threads = [int(t) for t in args.threads.split(",")]
    data = str(Path(args.data).resolve())
    rows = []
    for family, recipe, sets, schedule in RECIPES:
        if families is not None and family not in families:
            continue
        steps, batch, seq = defaults(family)
        for s in sets:
            if s.startswith("batch_size="):
                batch = int(s.split("=")[1])
        schedule = schedule or steps
        for t in threads:
            r = one(family, sets, data=data, threads=t, steps=args.steps)
            minutes = schedule * r["s_per_step"] / 60
            row = [family, recipe, f"{batch} x {seq}", t, round(r["s_per_step"], 3), schedule, round(minutes, 1),
                   round(r["peak_rss_mb"]), round(os.getloadavg()[0], 1)]
            print(" | ".join(str(v) for v in row), flush=True)
            rows.append(row)
    if args.json:
        from dancekit._io import atomic_path

        cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")),
                   platform.machine())
        out = {"title": "Training on the CPU: seconds a step of each model family, and its schedule's time",
               "command": "python " + " ".join([Path(__file__).relative_to(ROOT).as_posix()] + sys.argv[1:]),
               "machine": f"{cpu}, {os.cpu_count()} cores, torch {__import__('torch').__version__}",
               "date": datetime.date.today().isoformat(),
               "columns": ["family", "recipe", "batch (windows x frames)", "threads", "s a step",
                           "schedule (steps)", "schedule (min)", "peak RSS (MB)", "1-min load average"],
               "rows": rows,
               "note": "dancekit train FAMILY --data data/tang2018 with the family's defaults (or the embedded "
                       "model's recipe), fp32, a fresh process each; seconds a step over the steps after the "
                       "first quarter (start-up, data loading and validation excluded); the schedule's time is its "
                       "steps at that rate. The long CPU runs of docs/research (dual 6,000 steps, music2dance "
                       "4,800) use the embedded recipes on one thread."}
        with atomic_path(args.json) as tmp:
            Path(tmp).write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
