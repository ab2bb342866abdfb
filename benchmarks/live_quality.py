"""Quality of live dances against the offline dances of the same model (issue 43), on a prepared split.

    PYTHONPATH=src nice python benchmarks/live_quality.py --model revolution --data /work/data/tang2018 \
        --split test --out /tmp/live_q/revolution
    # then score both folders with the evaluation code:
    dancekit evaluate --pred OUT/live --ref DATA --data DATA --split test -o OUT/live_report.json
    dancekit evaluate --checkpoint MODEL --data DATA --split test --seeds 1 -o OUT/offline

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="revolution")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="test")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

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
