"""A GPU round's validation curve: each run's screened S = max(FID_k / 31.7, FID_g / 12.35) and multimodality
against the training step (issue 41; docs/research/gpu-round.md, round 3: ``docs/gpu_round3.png``).

    PYTHONPATH=src python scripts/gpu_round_figure.py --screen runs/gpu3/screen --runs runs/gpu3 \
        --embedded runs/gpu3/screen_embedded -o docs/gpu_round3.png

``--screen`` holds one ``dancekit evaluate`` report folder per candidate, named ``RUN-step_NNNNNNN`` or
``RUN-best`` (the candidate folders of ``scripts/gpu_candidates.py``); ``RUN-best`` is placed at the step of
the run's lowest validation loss (``--runs``/RUN/run/log.jsonl).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from PIL import Image, ImageDraw

COLOURS = [(200, 60, 40), (40, 90, 200), (40, 150, 60), (150, 60, 170), (220, 140, 20), (20, 160, 170)]


def screen_point(report: Path) -> tuple[float, float]:
    m = json.loads((report / "report.json").read_text())["metrics"]
    return max(m["fid_k"] / 31.7, m["fid_g"] / 12.35), float(m["style_multimodality"])


def best_step(log: Path) -> int:
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    return min((r for r in rows if "val_loss" in r), key=lambda r: r["val_loss"])["step"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--screen", required=True)
    ap.add_argument("--runs", required=True)
    ap.add_argument("--embedded", help="the embedded model's report at the same seeds (a dashed line)")
    ap.add_argument("--embedded-label", default="the embedded model (GPU round 2, m2d_e step 708)",
                    help="what the dashed line is, for the caption")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    curves: dict[str, list[tuple[int, float, float]]] = {}
    for rep in sorted(Path(a.screen).iterdir()):
        if not (rep / "report.json").exists():
            continue
        run, _, tag = rep.name.rpartition("-")
        step = best_step(Path(a.runs) / run / "run" / "log.jsonl") if tag == "best" else int(tag.split("_")[1])
        curves.setdefault(run, []).append((step, *screen_point(rep)))
    embedded = screen_point(Path(a.embedded)) if a.embedded else None
    W, H, pad = 1200, 520, 70
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    xmax = max(s for pts in curves.values() for s, *_ in pts) * 1.05
    panels = [("S = max(FID_k / 31.7, FID_g / 12.35), validation, seeds 0-1 (lower is better)", 1, 5.0, 1.0),
              ("multimodality, validation, seeds 0-1 (issue 41: >= 27)", 2, 60.0, 27.0)]
    pw = (W - 3 * pad) // 2
    for k, (title, idx, ymax, ref) in enumerate(panels):
        x0, y0, y1 = pad + k * (pw + pad), pad, H - pad

        def X(s, x0=x0):
            return x0 + s / xmax * pw

        def Y(v, ymax=ymax, y0=y0, y1=y1):
            return y1 - min(v, ymax) / ymax * (y1 - y0)
        d.rectangle([x0, y0, x0 + pw, y1], outline="black")
        d.text((x0, y0 - 40), title, fill="black")
        for t in range(0, int(xmax) + 1, 1000 if xmax > 3000 else 200):
            d.text((X(t) - 10, y1 + 6), str(t), fill="black")
        for v in (ymax * i / 5 for i in range(6)):
            d.text((x0 - 40, Y(v) - 6), f"{v:g}", fill="black")
        d.line([x0, Y(ref), x0 + pw, Y(ref)], fill=(120, 120, 120), width=1)
        if embedded is not None:
            ye = Y(embedded[idx - 1])
            for xs in range(x0, x0 + pw, 16):
                d.line([xs, ye, xs + 8, ye], fill="black", width=2)
        for c, (run, pts) in enumerate(sorted(curves.items())):
            colour = COLOURS[c % len(COLOURS)]
            pts.sort()
            xy = [(X(p[0]), Y(p[idx])) for p in pts]
            d.line(xy, fill=colour, width=3)
            for x, y in xy:
                d.ellipse([x - 4, y - 4, x + 4, y + 4], fill=colour)
            d.text((x0 + pw - 150, y0 + 10 + 16 * c), run, fill=colour)
        d.text((x0 + pw // 2 - 40, y1 + 24), "training step", fill="black")
    if embedded is not None:
        d.text((pad, H - 24), f"dashed: {a.embedded_label} on the same screen; "
               "grey: the bound (S 1 = the median random training dance)", fill="black")
    img.save(a.output)


if __name__ == "__main__":
    main()
