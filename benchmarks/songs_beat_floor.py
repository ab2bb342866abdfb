"""The three songs of ``../shared/music`` danced with beat sync on and off (seeds 0-2, every other stage):
per song the mean BAS / beat hit rate / jerk against the song's tracked beats and the floor, feet, jitter
and energy measures of ``bench_feet.metrics`` (issue 15: the beat and floor points outside the dataset).

    PYTHONPATH=src python benchmarks/songs_beat_floor.py revolution --data data/tang2018 \\
        --music ../shared/music -o runs/songs_beat.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages
import numpy as np

from dancekit.data import PreparedData
from dancekit.pipelines import load_pipeline, stages

KEYS = ("bas", "hit_rate", "jerk", "floor_median_cm", "floor_within_2cm", "planted_foot_share", "foot_skating",
        "jitter_ratio", "energy_ratio", "stillness")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model", help="embedded name or checkpoint folder")
    ap.add_argument("--data", required=True, help="prepared tang2018 (the real test dances' means)")
    ap.add_argument("--music", default="../shared/music")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    data = PreparedData(args.data)
    real_mean = bench_feet.mean_rows([bench_feet.metrics(data.motion(n), None, None) for n in data.names("test")])
    pipe = load_pipeline(args.model)
    report = {}
    for song in bench_stages.SONGS:
        path = str(Path(args.music) / song)
        beats = stages.song_beats_for(path)
        for sync in (True, False):
            rows = [bench_feet.metrics(r.motion, beats.times, real_mean)
                    for r in pipe.dances(path, seeds=list(range(args.seeds)), beat_sync=sync)]
            report[f"{song}|{'on' if sync else 'off'}"] = rows
            mean = {k: float(np.mean([r[k] for r in rows])) for k in KEYS}
            print(song[:24], "on " if sync else "off", " ".join(f"{k} {v:.3f}" for k, v in mean.items()),
                  f"| max jitter {max(r['jitter_ratio'] for r in rows):.2f}", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, default=float))


if __name__ == "__main__":
    main()
