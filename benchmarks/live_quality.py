"""Quality of live dances against the offline dances of the same model (issue 43), on a prepared split.

    PYTHONPATH=src nice python benchmarks/live_quality.py --model revolution --data /work/data/tang2018 \
        --split test --out /tmp/live_q/revolution
    # then score both folders with the evaluation code, and tabulate (docs/results/live_quality.json):
    dancekit evaluate --pred OUT/live --ref DATA --data DATA --split test -o OUT/live_report.json
    dancekit evaluate --checkpoint MODEL --data DATA --split test --seeds 1 -o OUT/offline
    python benchmarks/live_quality.py --table OUT_REVOLUTION OUT_MUSIC2DANCE -o docs/results/live_quality.json

Each song of the split is fed to a :class:`dancekit.live.LiveSession` block by block (``block_s`` of audio per
block, every block as its own step: the computation of a real-time run that keeps up; the clock itself is not
waited for) and the frames it sends are written as ``OUT/live/NAME.npz`` (the model's skeleton and fps).
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


def table(folders: list[str], output: str) -> None:
    """live vs offline per model and metric (the reports of ``dancekit evaluate``) → the results JSON."""
    import platform

    rows = []
    for folder in folders:
        live = json.loads((Path(folder) / "live_report.json").read_text())
        off = json.loads((Path(folder) / "offline" / "report.json").read_text())
        model = Path(folder).name
        for key, label in METRICS:
            a, b, r = live["metrics"].get(key), off["metrics"].get(key), off["real"].get(key)
            rel = None if a is None or not b else round(100.0 * (a - b) / abs(b), 1)
            rows.append([model, label, None if a is None else round(a, 4), None if b is None else round(b, 4),
                         rel, None if r is None else round(r, 4)])
    out = {"title": "dancekit live: live dances of the test songs against the offline dances of the same model",
           "command": "PYTHONPATH=src python benchmarks/live_quality.py --model MODEL --data /work/data/tang2018 "
                      "--split test --out OUT/MODEL; dancekit evaluate --pred OUT/MODEL/live --ref DATA --data DATA "
                      "-o OUT/MODEL/live_report.json; dancekit evaluate --checkpoint MODEL --data DATA --split test "
                      "--seeds 1 -o OUT/MODEL/offline; python benchmarks/live_quality.py --table OUT/revolution "
                      "OUT/music2dance -o docs/results/live_quality.json",
           "machine": f"{platform.machine()}, 2 cores", "date": time.strftime("%Y-%m-%d"),
           "columns": ["model", "metric", "live", "offline (seed 0, genre auto, every stage)", "live vs offline %",
                       "real dances"],
           "rows": rows,
           "note": "6 test songs of tang2018, one dance each. Live: fed block by block (0.04 s), the model alone "
                   "(no genre model), the online stages (calm, smoothing, floor): no beat warp and no foot lock "
                   "online yet, so BAS is the model's own; offline: the pipeline with every stage. FID reference: "
                   "the training dances (dancekit evaluate's default)."}
    Path(output).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(rows, indent=0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="revolution")
    ap.add_argument("--data")
    ap.add_argument("--split", default="test")
    ap.add_argument("--out")
    ap.add_argument("--table", nargs="+", metavar="OUT", help="tabulate finished runs instead")
    ap.add_argument("-o", "--output", default="docs/results/live_quality.json")
    args = ap.parse_args()
    if args.table:
        table(args.table, args.output)
        return
    if not args.data or not args.out:
        ap.error("--data and --out are needed to dance")

    import torch
    from threadpoolctl import threadpool_limits

    from dancekit.audio import load
    from dancekit.data import PreparedData
    from dancekit.live.session import Block, LiveSession
    from dancekit.motion import Motion
    from dancekit.motion.formats.npz import write_npz

    torch.set_num_threads(1)
    data = PreparedData(args.data)
    out = Path(args.out) / "live"
    out.mkdir(parents=True, exist_ok=True)
    log = {}
    with threadpool_limits(1):
        for name in data.names(args.split):
            ref = data.audio(name)
            s = LiveSession(args.model)
            y, _ = load(ref.path, sr=s.sr, start=ref.start, end=ref.end)
            n = int(round(s.config.block_s * s.sr))
            frames = []
            t0, c0 = time.monotonic(), time.process_time()
            for a in range(0, len(y), n):
                frames.extend(s.feed([Block(y[a : a + n], time.monotonic())]))
            frames.extend(s.finish())
            p = np.stack([f.joints for f in frames]).astype(np.float32)
            write_npz(out / f"{name}.npz", Motion(skeleton=s.skeleton, fps=s.fps, positions=p))
            log[name] = {"seconds": len(y) / s.sr, "frames": len(frames), "cpu_s": time.process_time() - c0,
                         "wall_s": time.monotonic() - t0}
            print(name, log[name], flush=True)
    (Path(args.out) / "live_log.json").write_text(json.dumps(log, indent=1))


if __name__ == "__main__":
    main()
