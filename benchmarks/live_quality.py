"""Quality of live dances against the offline dances of the same model (issue 43), on a prepared split.

    PYTHONPATH=src nice python benchmarks/live_quality.py --model revolution --data data/tang2018 \
        --split test --seeds 0-4 --out /tmp/live_q/revolution
    # then score the live dances and the offline ones with the evaluation code, and tabulate:
    dancekit evaluate --pred OUT/live --ref DATA --data DATA --split test --no-style -o OUT/live_report.json
    dancekit evaluate --checkpoint MODEL --data DATA --split test --seeds 0-4 --genre none --no-style \
        -o OUT/offline_none
    dancekit evaluate --checkpoint MODEL --data DATA --split test --seeds 0-4 --no-style -o OUT/offline
    python benchmarks/live_quality.py --table OUT_REVOLUTION OUT_MUSIC2DANCE --seeds 0-4 --data DATA \
        -o docs/results/live_quality.json

Each song of the split is fed to a :class:`dancekit.live.LiveSession` block by block (``block_s`` of audio per
block, every block as its own step: the computation of a real-time run that keeps up; the clock itself is not
waited for) and the frames it sends are written as ``OUT/live/NAME.npz`` (the model's skeleton and fps).

The table: per model and metric the live dances, the offline dances of the model alone (``--genre none``: live
cannot use the genre models, which need the whole song), live against those (%), the offline dances with the
genre read from the music (``dancekit dance``'s default) and the real dances; then how many songs are within
issue 15's per-song bounds (stillness ≤ 5 %, smoothed energy ≥ 0.6 × and jitter ≤ 1.2 × the song's real dance).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

METRICS = [("fid_k", "FID_k"), ("fid_g", "FID_g"), ("bas_bailando", "BAS"), ("stillness_share", "stillness share"),
           ("smoothed_energy", "smoothed energy (m/s)"), ("jitter_speed", "jitter (m/s)"),
           ("foot_skating_ratio", "foot skating"), ("beat_hit_rate", "beat hit rate")]
#: issue 15's per-song bounds: stillness share ≤, smoothed energy / real ≥, jitter / real ≤
BOUNDS = {"stillness_share": 0.05, "smoothed_energy": 0.6, "jitter_speed": 1.2}


def songs_within_bounds(report: dict, real: dict[str, dict]) -> tuple[int, int, list[str]]:
    """(songs within issue 15's per-song bounds, songs, the failures as "NAME: metric value") of a
    ``dancekit evaluate`` report, each song's worst dance against ``real[name]`` (its real dance's metrics)."""
    per: dict[str, list[dict]] = {}
    for key, row in report["per_dance"].items():
        per.setdefault(key.split("#")[0], []).append(row)
    fails = []
    for name, rows in sorted(per.items()):
        still = max(r["stillness_share"] for r in rows)
        energy = min(r["smoothed_energy"] for r in rows) / real[name]["smoothed_energy"]
        jitter = max(r["jitter_speed"] for r in rows) / real[name]["jitter_speed"]
        bad = [f"stillness {still:.3f}"] * (still > BOUNDS["stillness_share"])
        bad += [f"energy {energy:.2f}x"] * (energy < BOUNDS["smoothed_energy"])
        bad += [f"jitter {jitter:.2f}x"] * (jitter > BOUNDS["jitter_speed"])
        if bad:
            fails.append(f"{name}: {', '.join(bad)}")
    return len(per) - len(fails), len(per), fails


def table(folders: list[str], output: str, data: str, seeds: str = "0-4") -> None:
    """live vs offline per model and metric (the reports of ``dancekit evaluate``, each of the seeds ``seeds``)
    → the results JSON."""
    import platform

    from dancekit.data import PreparedData
    from dancekit.evaluation.score import EvalSettings, dance_metrics

    prepared = PreparedData(data)
    real_cache: dict[str, dict] = {}

    def real(names):
        for name in names:
            if name not in real_cache:
                gt = prepared.motion(name)
                real_cache[name] = dance_metrics(gt.to_positions(), fps=gt.fps, skeleton=gt.skeleton,
                                                 music_beats=None, settings=EvalSettings())
        return real_cache

    rows, failures = [], []
    for folder in folders:
        live = json.loads((Path(folder) / "live_report.json").read_text())
        alone = json.loads((Path(folder) / "offline_none" / "report.json").read_text())
        auto = json.loads((Path(folder) / "offline" / "report.json").read_text())
        model = Path(folder).name
        for key, label in METRICS:
            a, b, c, r = (live["metrics"].get(key), alone["metrics"].get(key), auto["metrics"].get(key),
                          alone["real"].get(key))
            rel = None if a is None or not b else round(100.0 * (a - b) / abs(b), 1)
            rows.append([model, label] + [None if v is None else round(v, 4) for v in (a, b)] + [rel]
                        + [None if v is None else round(v, 4) for v in (c, r)])
        counts = []
        for name, rep in (("live", live), ("offline alone", alone), ("offline genre auto", auto)):
            names = {k.split("#")[0] for k in rep["per_dance"]}
            ok, n, bad = songs_within_bounds(rep, real(names))
            counts.append(f"{ok}/{n}")
            failures += [f"{model} {name}: {b}" for b in bad]
        rows.append([model, "songs within issue 15's per-song bounds", counts[0], counts[1], None, counts[2], None])
    out = {"title": "dancekit live: live dances of the test songs against the offline dances of the same model",
           "command": f"PYTHONPATH=src python benchmarks/live_quality.py --model MODEL --data DATA --split test "
                      f"--seeds {seeds} --out OUT/MODEL; dancekit evaluate --pred OUT/MODEL/live --ref DATA --data DATA "
                      f"--no-style -o OUT/MODEL/live_report.json; dancekit evaluate --checkpoint MODEL --data DATA "
                      f"--split test --seeds {seeds} --genre none --no-style -o OUT/MODEL/offline_none; dancekit "
                      f"evaluate --checkpoint MODEL --data DATA --split test --seeds {seeds} --no-style -o "
                      f"OUT/MODEL/offline; python benchmarks/live_quality.py --table OUT/revolution OUT/music2dance "
                      f"--seeds {seeds} --data DATA -o docs/results/live_quality.json",
           "machine": f"{platform.machine()}, 2 cores", "date": time.strftime("%Y-%m-%d"),
           "columns": ["model", "metric", "live", f"offline, the model alone (seeds {seeds}, genre none, every stage)",
                       "live vs offline alone %", f"offline (seeds {seeds}, genre auto, every stage)", "real dances"],
           "rows": rows,
           "note": f"6 test songs of tang2018, a dance per seed {seeds} of each. Live: fed block by block (0.04 s, as a "
                   "real-time run that keeps up), the model alone (no genre model), the online stages (the beat "
                   "nudge within the model's offline warp bound; calm, smoothing, floor, the online foot lock); "
                   "music2dance's samples smoothed by the offline Gaussian, each frame held back 0.08 s (LiveConfig."
                   "smoothing_hold_s). Offline: the pipeline with every stage. Per-song bounds (issue 15): "
                   "stillness ≤ 5 %, smoothed energy ≥ 0.6 x and jitter ≤ 1.2 x the song's real dance, each "
                   "song's worst dance; outside them: " + ("; ".join(failures) if failures else "none") + ". FID reference: the training "
                   "dances (dancekit evaluate's default)."}
    Path(output).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(rows, indent=0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="revolution")
    ap.add_argument("--data")
    ap.add_argument("--split", default="test")
    ap.add_argument("--block-s", type=float, default=None,
                    help="audio per block (s; default: LiveConfig's block_s)")
    ap.add_argument("--seeds", default="0", help="seeds of each song's live dances: K or A-B (NAME__k.npz when several)")
    ap.add_argument("--live-set", action="append", default=[], metavar="KEY=VALUE",
                    help="a LiveConfig setting (repeatable; VALUE as JSON, else a string)")
    ap.add_argument("--out")
    ap.add_argument("--table", nargs="+", metavar="OUT", help="tabulate finished runs instead (needs --data)")
    ap.add_argument("-o", "--output", default="docs/results/live_quality.json")
    args = ap.parse_args()
    if args.table:
        if not args.data:
            ap.error("--table needs --data (the real dances of the per-song bounds)")
        table(args.table, args.output, args.data, seeds=args.seeds)
        return
    if not args.data or not args.out:
        ap.error("--data and --out are needed to dance")

    import torch
    from threadpoolctl import threadpool_limits

    from dancekit.audio import load
    from dancekit.data import PreparedData
    from dancekit.live import LiveConfig
    from dancekit.live.session import Block, LiveSession
    from dancekit.motion import Motion
    from dancekit.motion.formats.npz import write_npz

    torch.set_num_threads(1)
    data = PreparedData(args.data)
    out = Path(args.out) / "live"
    out.mkdir(parents=True, exist_ok=True)
    log = {}
    spec = {}
    for item in args.live_set:
        key, _, value = item.partition("=")
        try:
            spec[key] = json.loads(value)
        except json.JSONDecodeError:
            spec[key] = value
    if args.block_s is not None:
        spec["block_s"] = args.block_s
    a_, _, b_ = args.seeds.partition("-")
    seeds = list(range(int(a_), int(b_ or a_) + 1))
    with threadpool_limits(1):
        for name, seed in [(n, k) for n in data.names(args.split) for k in seeds]:
            ref = data.audio(name)
            s = LiveSession(args.model, config=LiveConfig.from_dict({**spec, "seed": seed}))
            y, _ = load(ref.path, sr=s.sr, start=ref.start, end=ref.end)
            n = int(round(s.config.block_s * s.sr))
            frames = []
            t0, c0 = time.monotonic(), time.process_time()
            for a in range(0, len(y), n):
                frames.extend(s.feed([Block(y[a : a + n], time.monotonic())]))
            frames.extend(s.finish())
            p = np.stack([f.joints for f in frames]).astype(np.float32)
            key = name if len(seeds) == 1 else f"{name}__{seed}"
            write_npz(out / f"{key}.npz", Motion(skeleton=s.skeleton, fps=s.fps, positions=p))
            log[key] = {"seconds": len(y) / s.sr, "frames": len(frames), "cpu_s": time.process_time() - c0,
                         "wall_s": time.monotonic() - t0}
            print(key, log[key], flush=True)
    (Path(args.out) / "live_log.json").write_text(json.dumps(log, indent=1))


if __name__ == "__main__":
    main()
