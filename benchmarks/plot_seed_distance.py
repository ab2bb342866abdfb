"""Figure of issue 15's seed-distance bound (PIL): per second of the song, two seeds' dances against half the
distance between two songs' dances, one panel per model.

    PYTHONPATH=src python benchmarks/plot_seed_distance.py \\
        "default before (s1.2)=runs/m/sd31_test_default.json" \\
        "default now (M29)=runs/m/test_r31_embedded/report.json" -o docs/seed_distance_r31.png

Each argument is ``LABEL=FILE``, FILE a ``dancekit evaluate`` report (its ``seed_distance`` entry) or that entry
alone. Thick: ``seed_cm`` (every pair of seeds of every song); thin: half of ``song_cm`` (two songs compared
seed by seed, every seed); dashed grey: half of ``song_seed0_cm`` (the first seed's dances alone, one pair per
song pair: the curve reports gave before the fifteenth session) where the entry has it; seconds where the
thick line is under the thin one are shaded. A song drops out of both curves past its end (from second 57 of
the test songs only C_6 and R_2 are left).
"""

from __future__ import annotations

import argparse
import json

from PIL import Image, ImageDraw
from plot_variety import COLOURS, H, M, W, _axes, _dashed


def _entry(path: str) -> dict:
    data = json.load(open(path))
    return data.get("seed_distance", data)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", nargs="+", help="LABEL=report.json (or a seed_distance JSON)")
    ap.add_argument("--title", default="test songs, 5 seeds")
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args(argv)
    panels = [(item.rsplit("=", 1)[0], _entry(item.rsplit("=", 1)[1])) for item in args.report]
    t_max = max(len(sd["seed_cm"]) for _, sd in panels)
    y_max = max(max(sd["seed_cm"]) for _, sd in panels) * 1.15
    img = Image.new("RGB", (W * len(panels), H), "white")
    draw = ImageDraw.Draw(img)
    for k, (label, sd) in enumerate(panels):
        to_px = _axes(draw, W * k, f"{args.title}: {label}", "second of the song", "cm", (0.0, float(t_max)),
                      (0.0, y_max))
        c = COLOURS[0]  # one colour: red only marks a break
        seed, song = sd["seed_cm"], sd["song_cm"]
        n = min(len(seed), len(song))
        below = [t for t in range(n) if seed[t] < 0.5 * song[t]]
        for t in below:  # a second where the bound breaks: shaded
            (x0, y0), (x1, y1) = to_px(t, y_max), to_px(t + 1, 0)
            draw.rectangle([x0, y0, x1, y1], fill=(255, 210, 210))
        if sd.get("song_seed0_cm"):
            first = sd["song_seed0_cm"]
            for t in range(len(first) - 1):
                _dashed(draw, to_px(t + 0.5, 0.5 * first[t]), to_px(t + 1.5, 0.5 * first[t + 1]), (140, 140, 140),
                        dash=3)
        draw.line([to_px(t + 0.5, v) for t, v in enumerate(seed)], fill=c, width=3)
        draw.line([to_px(t + 0.5, 0.5 * v) for t, v in enumerate(song)], fill=c, width=1)
        worst = min(range(n), key=lambda t: seed[t] / max(0.5 * song[t], 1e-9))
        draw.text((W * k + M + 10, M + 8), "thick: two seeds   thin: half of two songs (every seed)", fill=c)
        draw.text((W * k + M + 10, M + 22), "dashed: half of two songs (first seed only)", fill=(110, 110, 110))
        draw.text((W * k + M + 10, M + 36), f"worst second {worst}: {seed[worst]:.1f} vs {0.5 * song[worst]:.1f} cm; "
                  f"below in {len(below)} s", fill=(200, 40, 40) if below else c)
    img.save(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
