"""The Music2Dance WaveNet's frame loop: the torch step (``generate(reference=True)``) against the NumPy loop
(:class:`dancekit.models.music2dance.NumpyWaveNet`, the default), in one process, interleaved.

    PYTHONPATH=src python benchmarks/bench_m2d_loop.py [--song ../shared/music/Kevin_MacLeod_-_Vibe_Ace.ogg]
                                                       [--repeats 3] [--batch 1]

The embedded ``music2dance`` model with its sampling settings (temperature, noise correlation, F_map window),
one torch thread (``dancekit dance``'s default). Prints per run the wall and CPU seconds of ``generate`` (the
conditions, the frame loop and the sampling; the features come from the cache), then the largest difference
between the two dances (normalised feature units; float rounding carried along the autoregression).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import torch

from dancekit.pipelines import load_pipeline

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SONG = ROOT.parent / "shared" / "music" / "Kevin_MacLeod_-_Vibe_Ace.ogg"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--song", type=Path, default=DEFAULT_SONG)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch", type=int, default=1, help="seeds generated as one batch")
    args = ap.parse_args()
    torch.set_num_threads(1)
    pipe = load_pipeline("music2dance")
    music = torch.from_numpy(pipe.features(args.song))[None].expand(args.batch, -1, -1)
    kw = {"temperature": pipe.temperature, "noise_correlation": pipe.noise_correlation,
          "fmap_window": pipe.meta.get("train", {}).get("seq_len")}
    times: dict[str, list[tuple[float, float]]] = {"torch step": [], "numpy loop": []}
    out = {}
    for _ in range(args.repeats):
        for name, reference in (("torch step", True), ("numpy loop", False)):
            gens = [torch.Generator().manual_seed(s) for s in range(args.batch)]
            c0, w0 = time.process_time(), time.perf_counter()
            out[name] = pipe.model.generate(music, torch.zeros(args.batch, dtype=torch.long), generator=gens,
                                            reference=reference, **kw)
            times[name].append((time.perf_counter() - w0, time.process_time() - c0))
            print(json.dumps({"loop": name, "frames": music.shape[1], "batch": args.batch,
                              "wall_s": round(times[name][-1][0], 3), "cpu_s": round(times[name][-1][1], 3)}),
                  flush=True)
    for name, runs in times.items():
        print(f"{name}: wall median {statistics.median(w for w, _ in runs):.2f} s, "
              f"CPU median {statistics.median(c for _, c in runs):.2f} s")
    diff = (out["torch step"] - out["numpy loop"]).abs()
    print(f"largest difference {diff.max():.3g} (first 200 frames {diff[:, :200].max():.3g}), mean {diff.mean():.3g}")


if __name__ == "__main__":
    main()
