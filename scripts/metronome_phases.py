"""The real-tempo metronome of ``dancekit evaluate --compose`` over many random phases (issue 41).

    python scripts/metronome_phases.py --data data/tang2018 --split test --draws 100 [--json OUT.json]

For each draw k (seeds ``[k, index of the dance]``), every dance of the split gets clicks at its real music's
tempo (60 / median interval of the beats tracked on the real music, as the evaluation measures it) with a
random phase (:func:`dancekit.metrics.music_beats.metronome`); the draw's score is the mean over dances of
beat F1 against the real music's beats (±0.1 s), as in the evaluation's table. Prints the median, min and
max over the draws (draw 0 is the table's own metronome column, whose settings seed is 0).
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np


def main() -> int:
    from dancekit.data import PreparedData
    from dancekit.evaluation.music import MusicSettings, _load_audio, audio_piece
    from dancekit.metrics import music_beats as mb

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--split", default="test")
    p.add_argument("--draws", type=int, default=100)
    p.add_argument("--json", default=None, help="write {draws: [...], median, min, max} here")
    args = p.parse_args()
    settings = MusicSettings()
    data = PreparedData(args.data)
    refs = []
    for n in data.names(args.split):
        m, a = data.motion(n), data.audio(n)
        d = m.num_frames / m.fps
        piece = audio_piece(_load_audio(a.path, settings.sr, start=a.start, end=a.end), sr=settings.sr,
                            with_notes=False)
        rb = piece.beats[piece.beats < d]
        refs.append((n, d, rb, mb.tempo_from_beats(rb)))
    scores = []
    for k in range(args.draws):
        f1 = []
        for i, (_n, d, rb, bpm) in enumerate(refs):
            if not math.isfinite(bpm):
                continue
            rng = np.random.default_rng([k, i])
            clicks = mb.clicks_on(mb.metronome(bpm=bpm, duration=d, seed=rng), duration=d)
            f1.append(mb.beat_f1(clicks[clicks < d], rb, tolerance=settings.beat_tolerance))
        scores.append(float(np.mean(f1)))
    out = {"draws": scores, "median": float(np.median(scores)), "min": float(np.min(scores)),
           "max": float(np.max(scores)), "dances": [r[0] for r in refs]}
    print(f"metronome (real tempo, random phase), beat F1 vs real music over {args.draws} draws: median "
          f"{out['median']:.3f}, min {out['min']:.3f}, max {out['max']:.3f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
