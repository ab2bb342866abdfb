"""How much five seeds move FID: FID_k / FID_g of disjoint seed sets of a many-seed ``dancekit evaluate`` folder.

Each FOLDER is an evaluate output made with ``--seeds N`` (N a multiple of ``--set-size``; files
``pred/NAME__k.npz``); every set of ``--set-size`` consecutive seeds is scored on its own with
``dancekit evaluate --pred`` against the same split, and the folder's own report gives the pooled value.
With ``--png`` the sets are drawn as bars next to the pooled value (docs/seed_sets.png).

    dancekit evaluate --checkpoint revolution --data data/tang2018 --split val --seeds 30 -o runs/s30
    PYTHONPATH=src python benchmarks/seed_sets.py runs/s30 runs/s30_spread --labels default spread \
        --split val --png docs/seed_sets.png
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from dancekit.evaluation.score import SAMPLE_SEP

COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40)]


def seed_sets(folder: Path, *, split: str, data: str, size: int) -> tuple[list[tuple[float, float]], dict]:
    """Per set of ``size`` consecutive seeds: (FID_k, FID_g); and the folder's pooled metrics."""
    seed_of = {f: int(f.stem.rsplit(SAMPLE_SEP, 1)[1]) for f in (folder / "pred").glob(f"*{SAMPLE_SEP}*.npz")}
    seeds = sorted(set(seed_of.values()))
    if not seeds or len(seeds) % size:
        sys.exit(f"{folder}: {len(seeds)} seeds in pred/, not a multiple of --set-size {size}")
    out = []
    for first in range(0, len(seeds), size):
        with tempfile.TemporaryDirectory() as tmp:
            for f, seed in seed_of.items():
                if first <= seed < first + size:
                    os.symlink(f.resolve(), Path(tmp) / f.name)
            report = Path(tmp) / "report.json"
            subprocess.run([sys.executable, "-m", "dancekit.cli.main", "evaluate", "--pred", tmp, "--ref", data,
                            "--split", split, "--data", data, "-o", str(report), "--quiet", "--no-baselines"],
                           check=True, stdout=subprocess.DEVNULL)
            m = json.loads(report.read_text())["metrics"]
            out.append((float(m["fid_k"]), float(m["fid_g"])))
    return out, json.loads((folder / "report.json").read_text())["metrics"]


def draw(rows: list[tuple[str, list[float], float]], size: int, path: Path) -> None:
    """Grouped bars: one group per seed set, one bar per folder, its pooled value dashed."""
    W, H, left, bottom, top = 900, 460, 70, 40 + 16 * len(rows), 40
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    n_sets = len(rows[0][1])
    ymax = max(max(v) for _, v, _ in rows) * 1.15
    plot_w, plot_h = W - left - 20, H - bottom - top

    def y(v: float) -> float:
        return top + plot_h * (1 - v / ymax)

    d.line([(left, top), (left, H - bottom), (W - 20, H - bottom)], fill="black")
    for tick in np.arange(0, ymax, 10):
        d.line([(left - 4, y(tick)), (left, y(tick))], fill="black")
        d.text((left - 30, y(tick) - 6), f"{tick:.0f}", fill="black")
    d.text((8, top - 25), "FID_k (5 songs, each set of seeds alone; dashed: all seeds pooled)", fill="black")
    group = plot_w / n_sets
    bar = group * 0.8 / len(rows)
    for r, (label, values, pooled) in enumerate(rows):
        colour = COLOURS[r % len(COLOURS)]
        for s, v in enumerate(values):
            x0 = left + s * group + group * 0.1 + r * bar
            d.rectangle([x0, y(v), x0 + bar - 2, H - bottom], fill=colour)
        for x in range(left, W - 20, 12):
            d.line([(x, y(pooled)), (x + 6, y(pooled))], fill=colour, width=2)
        ly = H - bottom + 26 + 16 * r  # the legend, under the seed-set labels
        d.rectangle([left + 10, ly, left + 20, ly + 10], fill=colour)
        d.text((left + 26, ly - 1),
               f"{label}: sets {min(values):.1f}-{max(values):.1f} (sd {np.std(values):.2f}), pooled {pooled:.2f}",
               fill="black")
    for s in range(n_sets):
        d.text((left + s * group + group * 0.3, H - bottom + 4), f"seeds {s * size}-{s * size + size - 1}",
               fill="black")
    img.save(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--labels", nargs="+")
    ap.add_argument("--split", default="val")
    ap.add_argument("--data", default="data/tang2018")
    ap.add_argument("--set-size", type=int, default=5)
    ap.add_argument("--png", type=Path)
    args = ap.parse_args()
    labels = args.labels or [f.name for f in args.folders]
    if len(labels) != len(args.folders):
        sys.exit("give one --labels entry per folder")
    rows = []
    for label, folder in zip(labels, args.folders):
        sets, pooled = seed_sets(folder, split=args.split, data=args.data, size=args.set_size)
        ks = [k for k, _ in sets]
        print(f"{label}: pooled FID_k {pooled['fid_k']:.2f} FID_g {pooled['fid_g']:.2f} | sets FID_k "
              + " ".join(f"{k:.2f}" for k in ks) + f" (sd {np.std(ks):.2f}) | FID_g "
              + " ".join(f"{g:.2f}" for _, g in sets), flush=True)
        rows.append((label, ks, float(pooled["fid_k"])))
    if args.png:
        draw(rows, args.set_size, args.png)
        print(f"figure: {args.png}")


if __name__ == "__main__":
    main()
