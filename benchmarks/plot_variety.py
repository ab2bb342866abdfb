"""Figure of issue 15's seed variety (PIL, no plotting library): the validation trade-off and the test
seed-to-seed distance.

    PYTHONPATH=src python benchmarks/plot_variety.py --rows runs/tune*/rows.jsonl --chosen 0:0:0:1 \\
        --report "paper's decoding=runs/var_off/report.json" --report "dance latent=runs/var_on/report.json" \\
        -o docs/variety.png

Left: multimodality (style features) against FID_k of every setting tried on the validation songs
(``benchmarks/tune_variety.py`` rows, ``phrase_s:state_noise:latent_noise:dance_latent``; red: the chosen
one), with the +10 % FID_k line of the no-variety setting ``0:0:0`` (or ``--base SPEC``; dashed) and its multimodality ×3
(dotted). Right: per second, the mean per-frame distance between two seeds' dances of a song
(``seed_distance.seed_cm`` of each ``dancekit evaluate`` report, solid) and half the distance between two
songs' dances (thin), one colour per report.
"""

from __future__ import annotations

import argparse
import json

from PIL import Image, ImageDraw

COLOURS = [(40, 90, 200), (200, 50, 40), (40, 150, 60), (150, 80, 180)]
W, H, M = 620, 480, 60  # panel size and margin (pixels)


def _axes(draw, x0, title, xlabel, ylabel, xr, yr):
    draw.rectangle([x0 + M, M, x0 + W - 20, H - M], outline=(0, 0, 0))
    draw.text((x0 + M, 20), title, fill=(0, 0, 0))
    draw.text((x0 + W // 2 - 60, H - 25), xlabel, fill=(0, 0, 0))
    draw.text((x0 + 5, 35), ylabel, fill=(0, 0, 0))
    for k in range(6):
        xv, yv = xr[0] + k * (xr[1] - xr[0]) / 5, yr[0] + k * (yr[1] - yr[0]) / 5
        px = x0 + M + k * (W - 20 - M) / 5
        py = H - M - k * (H - 2 * M) / 5
        draw.text((px - 10, H - M + 5), f"{xv:.0f}", fill=(0, 0, 0))
        draw.text((x0 + 20, py - 5), f"{yv:.0f}", fill=(0, 0, 0))

    def to_px(x, y):
        return (x0 + M + (x - xr[0]) / (xr[1] - xr[0]) * (W - 20 - M), H - M - (y - yr[0]) / (yr[1] - yr[0]) * (H - 2 * M))
    return to_px


def _dashed(draw, a, b, colour, dash=6):
    (x1, y1), (x2, y2) = a, b
    n = max(int(max(abs(x2 - x1), abs(y2 - y1)) / dash), 1)
    for k in range(0, n, 2):
        t0, t1 = k / n, min((k + 1) / n, 1)
        draw.line([(x1 + (x2 - x1) * t0, y1 + (y2 - y1) * t0), (x1 + (x2 - x1) * t1, y1 + (y2 - y1) * t1)], fill=colour)


def _label(row: dict) -> str:
    """A row's point label: its spec, and for rows of another checkpoint or of the model without its genre
    models (``tune_variety.py --model / --genre-models off``) the checkpoint's last folder name / "alone"."""
    tag = [] if row.get("model", "default") == "default" else [str(row["model"]).rstrip("/").split("/")[-1]]
    if row.get("genre_models") == "off":
        tag.append("alone")
    return " ".join([row["spec"], *tag])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", nargs="+", required=True)
    ap.add_argument("--chosen", default=None)
    ap.add_argument("--base", default="0:0:0", help="the row whose FID_k +10 %% and multimodality x3 are drawn")
    ap.add_argument("--report", action="append", default=[], help="LABEL=report.json")
    ap.add_argument("--fid-max", type=float, default=130.0, help="right end of the FID_k axis (beyond: clipped)")
    ap.add_argument("--fid-min", type=float, default=30.0, help="left end of the FID_k axis")
    ap.add_argument("--right-title", default="test songs, 5 seeds: two seeds (thick) vs half of two songs (thin)")
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    rows = {}
    for path in args.rows:
        for line in open(path):
            row = json.loads(line)
            rows[_label(row)] = row
    img = Image.new("RGB", (2 * W, H), "white")
    draw = ImageDraw.Draw(img)
    mm_max = max(50.0, max(r["style_multimodality"] for r in rows.values()) * 1.1)
    to_px = _axes(draw, 0, "validation songs, 5 seeds, stages on: settings tried", "FID_k",
                  "multimodality", (args.fid_min, args.fid_max), (0.0, mm_max))
    base = rows.get(args.base)
    if base is not None:
        _dashed(draw, to_px(1.1 * base["fid_k"], 0), to_px(1.1 * base["fid_k"], mm_max), (120, 120, 120))
        _dashed(draw, to_px(args.fid_min, 3 * base["style_multimodality"]), to_px(args.fid_max, 3 * base["style_multimodality"]),
                (120, 120, 120), dash=2)
    for spec, r in rows.items():
        x, y = to_px(min(r["fid_k"], args.fid_max), r["style_multimodality"])
        c = (200, 40, 40) if spec == args.chosen else (40, 90, 200)
        draw.ellipse([x - 4, y - 4, x + 4, y + 4], fill=c)
        draw.text((x + 5, y - 12), spec + (" >" if r["fid_k"] > args.fid_max else ""), fill=c)
    reports = [(item.rsplit("=", 1)[0], json.load(open(item.rsplit("=", 1)[1]))["seed_distance"]) for item in args.report]
    t_max = max(len(sd["seed_cm"]) for _, sd in reports)
    y_max = max(max(sd["seed_cm"] + sd["song_cm"]) for _, sd in reports) * 1.05
    to_px = _axes(draw, W, args.right_title, "second of the song",
                  "cm", (0.0, float(t_max)), (0.0, y_max))
    for k, (label, sd) in enumerate(reports):
        c = COLOURS[k % len(COLOURS)]
        draw.line([to_px(t, v) for t, v in enumerate(sd["seed_cm"])], fill=c, width=3)
        draw.line([to_px(t, 0.5 * v) for t, v in enumerate(sd["song_cm"])], fill=c, width=1)
        draw.text((W + M + 10, M + 8 + 14 * k), label, fill=c)
    img.save(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
