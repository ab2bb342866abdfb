"""The three songs of ``../shared/music`` danced as a user would (``dancekit dance SONG --seeds 0-2``: every
default stage, genre read from the music, the seed's genre draw where the checkpoint has one), per seed and per
song: the genre danced, jitter and smoothed energy against the real test dances' mean, stillness, the floor
(median height of the lowest joint over the local floor, share within 2 cm), the planted-foot share and foot
skating (``bench_feet.metrics``, the measures of the earlier sections). Issue 15, seed variety.

    PYTHONPATH=src python benchmarks/variety_songs.py --data data/tang2018 --music ../shared/music \\
        --model revolution --model /tmp/rev_today --seeds 3 -o runs/variety_songs.json

``--beat-sync both`` dances each song with the beat sync off as well (the report's keys ``SONG|off``) and
prints the mean BAS / beat hit rate / jerk of each (issue 15's beat point outside the dataset).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import bench_feet  # benchmarks/ is on the path when run as a script
import bench_stages

from dancekit.data import PreparedData
from dancekit.pipelines import load_pipeline, stages


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--music", default="../shared/music")
    ap.add_argument("--model", action="append", required=True, help="embedded name or checkpoint folder (repeat)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--beat-sync", choices=("on", "both"), default="on", help="both: also with the beat sync off")
    ap.add_argument("-o", "--out", required=True)
    args = ap.parse_args()
    data = PreparedData(args.data)
    real = [bench_feet.metrics(data.motion(n), None, None) for n in data.names("test")]
    real_mean = bench_feet.mean_rows(real)
    report = {"real_test_mean": real_mean, "models": {}}
    seeds = list(range(args.seeds))
    for model in args.model:
        pipe = load_pipeline(model)
        report["models"][model] = {}
        for song in bench_stages.SONGS:
            path = str(Path(args.music) / song)
            t0 = time.perf_counter()
            beats = stages.song_beats_for(path)
            for sync in (True, False) if args.beat_sync == "both" else (True,):
                rows = []
                for res in pipe.dances(path, seeds=seeds, beat_sync=sync):
                    row = bench_feet.metrics(res.motion, None if beats is None else beats.times, real_mean)
                    row["genre"] = res.genre or "alone"
                    rows.append(row)
                report["models"][model][song if sync else f"{song}|off"] = rows
                if args.beat_sync == "both" and beats is not None:
                    mean = {k: sum(r[k] for r in rows) / len(rows) for k in ("bas", "hit_rate", "jerk")}
                    print(f"{model} {song[:28]:28s} beat sync {'on ' if sync else 'off'}: BAS {mean['bas']:.3f} "
                          f"hit {mean['hit_rate']:.3f} jerk {mean['jerk']:.2f}", flush=True)
            rows = report["models"][model][song]
            print(f"{model} {song[:28]:28s} ({time.perf_counter() - t0:.0f} s): "
                  + "; ".join(f"seed {k} {r['genre']}: jitter {r['jitter_ratio']:.2f} energy {r['energy_ratio']:.2f} "
                              f"still {r['stillness']:.3f} floor {r['floor_median_cm']:.2f}/{r['floor_within_2cm']:.2f} "
                              f"planted {r['planted_foot_share']:.3f} skate {r['foot_skating']:.3f}"
                              for k, r in enumerate(rows)), flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()
