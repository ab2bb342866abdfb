"""Speed of a live dance against the music's beats, the target nudge above and the pulse below (issue 43;
docs/research/live.md, round 15: ``docs/live_pulse.png``).

    PYTHONPATH=src python scripts/live_pulse_figure.py --data data/tang2018 --song DANCE_W_11 --seed 16 \
        --target runs/r14/revolution_target/live --pulse runs/r14/revolution_pulse/live --start 30 -o docs/live_pulse.png
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from dancekit.data import PreparedData
from dancekit.metrics.beat import kinematic_beats
from dancekit.motion.analysis import mean_joint_speed
from dancekit.motion.formats.npz import read_npz


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--song", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--target", required=True)
    ap.add_argument("--pulse", required=True)
    ap.add_argument("--model", default="revolution", help="the model that danced (the caption)")
    ap.add_argument("--start", type=float, default=30.0)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    beats = np.asarray(PreparedData(a.data).features(a.song, "revolution")["beat_times"], np.float64)
    W, H, pad = 1200, 560, 60
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    t0, t1 = a.start, a.start + a.seconds

    def X(t):
        return pad + (t - t0) / (t1 - t0) * (W - 2 * pad)

    for row, (label, folder) in enumerate((("target nudge (today)", a.target), ("pulse", a.pulse))):
        m = read_npz(Path(folder) / f"{a.song}__{a.seed}.npz")
        p = m.to_positions() * m.skeleton.unit_scale
        v = mean_joint_speed(p, fps=m.fps)
        t = np.arange(len(v)) / m.fps
        keep = (t >= t0) & (t <= t1)
        top, h = 40 + row * (H - 40) // 2, (H - 40) // 2 - 50
        vmax = float(v[keep].max()) * 1.1

        def Y(y, top=top, h=h, vmax=vmax):
            return top + h - y / vmax * h

        for b in beats[(beats >= t0) & (beats <= t1)]:
            d.line([(X(b), top), (X(b), top + h)], fill=(200, 200, 255), width=3)
        pts = [(X(tt), Y(vv)) for tt, vv in zip(t[keep], v[keep])]
        d.line(pts, fill=(30, 30, 30), width=2)
        for k in kinematic_beats(p, fps=m.fps):
            if t0 <= k <= t1:
                d.ellipse([X(k) - 5, Y(float(np.interp(k, t, v))) - 5, X(k) + 5, Y(float(np.interp(k, t, v))) + 5],
                          outline=(220, 40, 40), width=2)
        d.text((pad, top - 18), f"{label}: mean joint speed (m/s, 0 to {vmax:.2f}); blue: music beats; red: kinematic beats",
               fill=(0, 0, 0))
    d.text((pad, H - 20), f"{a.song}, seed {a.seed}, live {a.model}, {t0:g}-{t1:g} s", fill=(0, 0, 0))
    img.save(a.output)


if __name__ == "__main__":
    main()
