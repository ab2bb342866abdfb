"""Validation-loss curves of Music2Dance ablation runs (issue 13): a table and a Pillow line chart.

    PYTHONPATH=src python benchmarks/m2d_ablations.py runs/ab_on:"clustering on, F_map fine-tuned" \
        runs/ab_off:"clustering off" runs/ab_frozen:"F_map frozen" runs/ab_raw:"raw music features" \
        --plot docs/m2d_ablations.png

Each RUN is a ``dancekit train music2dance --out RUN`` folder; its ``log.jsonl`` holds the validation
losses (``val_loss``, ``(L_gmm + 0.1 BCE) / D`` on the validation windows, unweighted) and the training
log (``elapsed_s``). Prints a markdown table (validation loss at every validation step, the wall time and
seconds per step of the run) and draws the curves, one colour per run. ``--reports`` prints the dance
metrics of evaluation reports (``benchmarks/m2d_eval_prepared.py``'s ``report.json``) side by side.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (255, 127, 14), (23, 190, 207),
           (140, 86, 75)]


def read_run(folder: Path) -> dict:
    """``{"val": [(step, loss)], "train": [(step, loss)], "elapsed_s": s, "steps": n}`` of a run's log."""
    val, train, elapsed, step = [], [], 0.0, 0
    for line in (folder / "log.jsonl").read_text().splitlines():
        rec = json.loads(line)
        if "val_loss" in rec:
            if not val or val[-1][0] != rec["step"]:
                val.append((int(rec["step"]), float(rec["val_loss"])))
        elif "loss" in rec:
            train.append((int(rec["step"]), float(rec["loss"])))
            elapsed, step = float(rec.get("elapsed_s", elapsed)), max(step, int(rec["step"]))
    return {"val": val, "train": train, "elapsed_s": elapsed, "steps": step}


def plot(path: Path, runs: list[tuple[str, dict]], title: str) -> None:
    """Validation loss against the step, one line per run (Pillow)."""
    from PIL import Image, ImageDraw

    W, H, left, right, top, bottom = 900, 520, 70, 250, 40, 50
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    pts = [p for _, r in runs for p in r["val"]]
    x_max = max(s for s, _ in pts)
    y_lo, y_hi = min(v for _, v in pts), max(v for _, v in pts)
    pad = 0.05 * (y_hi - y_lo or 1.0)
    y_lo, y_hi = y_lo - pad, y_hi + pad

    def xy(step: float, v: float) -> tuple[float, float]:
        return (left + (W - left - right) * step / x_max, top + (H - top - bottom) * (y_hi - v) / (y_hi - y_lo))

    d.rectangle([left, top, W - right, H - bottom], outline="black")
    for k in range(6):
        v = y_lo + (y_hi - y_lo) * k / 5
        _, y = xy(0, v)
        d.line([left - 4, y, left, y], fill="black")
        d.text((8, y - 6), f"{v:.3f}", fill="black")
    for k in range(6):
        s = x_max * k / 5
        x, _ = xy(s, y_lo)
        d.line([x, H - bottom, x, H - bottom + 4], fill="black")
        d.text((x - 10, H - bottom + 8), f"{s:.0f}", fill="black")
    d.text((left + (W - left - right) // 2 - 20, H - 20), "step", fill="black")
    d.text((left, 12), title, fill="black")
    for i, (label, r) in enumerate(runs):
        c = COLOURS[i % len(COLOURS)]
        line = [xy(s, v) for s, v in r["val"]]
        width = max(3, 9 - 2 * i)  # earlier runs drawn wider: a curve hidden under a later one still shows
        if len(line) > 1:
            d.line(line, fill=c, width=width)
        for x, y in line:
            r_ = width // 2 + 2
            d.ellipse([x - r_, y - r_, x + r_, y + r_], fill=c)
        ly = top + 10 + 22 * i
        d.line([W - right + 15, ly + 6, W - right + 40, ly + 6], fill=c, width=3)
        d.text((W - right + 46, ly), label, fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)


METRICS = ("fid_k", "fid_g", "div_k", "div_g", "bas_bailando", "style_acc", "style_multimodality", "stillness_share",
           "smoothed_energy_ratio", "jitter_speed_ratio", "foot_skating_ratio")


def metric_table(reports: list[tuple[str, Path]]) -> None:
    """A markdown table of ``dancekit evaluate`` reports (``report.json``), one column per report."""
    rows = [(label, json.loads(path.read_text())["metrics"]) for label, path in reports]
    print("| metric | " + " | ".join(label for label, _ in rows) + " |")
    print("| --- |" + " ---: |" * len(rows))
    for key in METRICS:
        cells = [f"{m[key]:.4g}" if isinstance(m.get(key), (int, float)) else "–" for _, m in rows]
        print(f"| {key} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="*", help="RUN_FOLDER[:label]")
    ap.add_argument("--reports", nargs="*", default=[], metavar="REPORT_JSON[:label]",
                    help="also print the dance metrics of these evaluation reports side by side")
    ap.add_argument("--plot", default=None, help="write the chart here (png)")
    ap.add_argument("--title", default="Music2Dance: validation loss (L_gmm + 0.1 BCE) / D, equal budgets")
    args = ap.parse_args()
    runs = []
    for item in args.runs:
        folder, _, label = item.partition(":")
        runs.append((label or Path(folder).name, read_run(Path(folder))))
    if not runs and not args.reports:
        ap.error("give run folders or --reports")
    steps = sorted({s for _, r in runs for s, _ in r["val"]})
    if runs:
        print("| run | " + " | ".join(f"val @{s}" for s in steps) + " | best | wall (s) | s/step |")
        print("| --- |" + " --- |" * (len(steps) + 3))
    for label, r in runs:
        v = dict(r["val"])
        cells = [f"{v[s]:.3f}" if s in v else "–" for s in steps]
        best = min(v.values()) if v else float("nan")
        rate = r["elapsed_s"] / r["steps"] if r["steps"] else float("nan")
        print(f"| {label} | " + " | ".join(cells) + f" | {best:.3f} | {r['elapsed_s']:.0f} | {rate:.2f} |")
    if args.plot and runs:
        plot(Path(args.plot), runs, args.title)
        print(f"wrote {args.plot}")
    if args.reports:
        metric_table([(item.partition(":")[2] or item, Path(item.partition(":")[0])) for item in args.reports])


if __name__ == "__main__":
    main()
