"""Reduced-precision, fused decoding (issue 18): speed of the paper-size Dance Revolution and of the embedded
models per precision, and the accuracy budget of int8 / bf16 against fp32. Run by hand, CPU.

    python benchmarks/bench_paper_size.py speed                  # the table (paper size + embedded models)
    python benchmarks/bench_paper_size.py speed --only paper     # paper size only
    python benchmarks/bench_paper_size.py speed --only paper --paper-rows fp32 "int8 fused"
    python benchmarks/bench_paper_size.py accuracy SONG [SONG ...]   # embedded models: int8 / bf16 vs fp32
    python benchmarks/bench_paper_size.py ab --against 8b4c566  # this tree's decoder vs a git revision's

``speed``: random weights, batch 1, ``--frames`` (900: one minute at 15 fps) of random normalised music
features, ``torch.set_num_threads(--threads)`` (2), one warm-up run then the median of ``--repeats`` runs of
``model.generate`` (encoder + decoder, the whole song). Paper size (issue 18): ``RevolutionConfig(
condition_on_music=False, decoder_layers=3, decoder_hidden=1024, d_model=256, n_heads=8, d_ff=1024,
pose_dim=50)``. Rows: ``fp32`` is the model's own loop (``torch.lstm_cell``, what ``--precision fp32``
runs); ``fp32 fused`` / ``bf16 fused`` / ``int8 fused`` the decoder of :mod:`dancekit.models.precision`;
``int8 unfused`` the library's ``quantize_dynamic`` ``nn.LSTMCell`` per layer, one call per layer per frame.
Every row prints the machine's 1-minute load average when it finished and the process CPU time: on a
shared machine the wall time is not the model's alone.

``ab``: A/B of the paper-size decoder of this tree against the one of a git revision (``--against``; its
``src/dancekit/models/precision.py`` loaded from ``git show``), same random model and music, the rows
interleaved round by round in one process (on a shared machine the load changes between two runs), for the
``--precisions`` given (int8); prints the median and best wall and CPU seconds of each row and the largest
difference between the two dances.

``accuracy``: each embedded model (revolution, music2dance, dual) dances each song through its pipeline
(beat sync and clean-up off, so that the comparison is the model's) at fp32 with seeds 0 and 1, and at
bf16 / int8 with seed 0; prints the mean per-joint distance (skeleton units, cm; poses relative to the root
joint, since root paths drift apart) of each to the fp32 dance
of seed 0 over the first 2 s, the first 10 s and the whole song. The fp32 dance of seed 1 is the scale: how
far two dances of the same model and song are. The decoders are chaotic: any perturbation grows, so over a
whole song a reduced-precision dance is another dance of the model, and its budget is on the metrics
(``dancekit evaluate --precision``).
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import os
import statistics
import subprocess
import sys
import time
import warnings

import numpy as np
import torch

from dancekit.models.precision import PRECISIONS, FusedLSTMDecoder, native_bf16, to_precision
from dancekit.models.revolution import RevolutionConfig, RevolutionModel

PAPER = dict(condition_on_music=False, decoder_layers=3, decoder_hidden=1024, d_model=256, n_heads=8, d_ff=1024,
             pose_dim=50)


def _load() -> str:
    return f"{os.getloadavg()[0]:.1f}"


class _UnfusedInt8:
    """The library path: one ``quantize_dynamic`` ``nn.LSTMCell`` per layer, called per frame."""

    def __init__(self, model: RevolutionModel):
        c = model.config
        cells = []
        for layer in range(c.decoder_layers):
            cell = torch.nn.LSTMCell(c.pose_dim + (c.d_model if c.condition_on_music else 0) if layer == 0
                                     else c.decoder_hidden, c.decoder_hidden)
            for kind in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"):
                getattr(cell, kind).data = getattr(model.decoder, f"{kind}_l{layer}").data.clone()
            cells.append(cell)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.cells = torch.ao.quantization.quantize_dynamic(torch.nn.ModuleList(cells), {torch.nn.LSTMCell},
                                                                dtype=torch.qint8)
        self.model = model

    def __call__(self, z, prev, state):
        c, head = self.model.config, self.model.head
        hs, cs = list(state[0].unbind(0)), list(state[1].unbind(0))
        y, outputs = prev[:, 0], []
        for t in range(z.shape[1]):
            x = torch.cat([y, z[:, t]], -1) if c.condition_on_music else y
            for layer, cell in enumerate(self.cells):
                hs[layer], cs[layer] = cell(x, (hs[layer], cs[layer]))
                x = hs[layer]
            y = head(torch.cat([x, z[:, t]], -1))
            outputs.append(y)
        out = torch.stack(outputs, 1)
        return out, out[:, -1:], (torch.stack(hs), torch.stack(cs))


def _variants(model: RevolutionModel, *, unfused: bool) -> list[tuple[str, RevolutionModel]]:
    fused32 = copy.deepcopy(model)
    fused32.fast_decoder = FusedLSTMDecoder(fused32, "fp32")
    rows = [("fp32", model), ("fp32 fused", fused32), ("bf16 fused", to_precision(model, "bf16")),
            ("int8 fused", to_precision(model, "int8"))]
    if unfused:
        slow = to_precision(model, "int8")
        slow.fast_decoder = _UnfusedInt8(slow)
        rows.append(("int8 unfused", slow))
    return rows


def _time(fn, repeats: int) -> tuple[float, float]:
    fn()  # warm-up
    walls, cpus = [], []
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus)


def _row(name: str, wall: float, cpu: float, ref: float | None, extra: str = "") -> None:
    speedup = f"{ref / wall:5.2f}x" if ref else "   – "
    print(f"| {name:38s} | {wall:8.3f} | {cpu:8.3f} | {speedup} | {_load():>5s} | {extra}", flush=True)


def bench_speed(args: argparse.Namespace) -> None:
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    print(f"torch {torch.__version__}, CPU capability {torch.backends.cpu.get_cpu_capability()}, native bf16: "
          f"{native_bf16()}, threads {args.threads}, batch 1, {args.frames} frames, median of {args.repeats} "
          f"after a warm-up; load = 1-min load average after the row")
    print("| model, precision | wall s | CPU s | vs fp32 | load | |")
    print("| --- | ---: | ---: | ---: | ---: | --- |")
    if "paper" in args.only:
        model = RevolutionModel(RevolutionConfig(**PAPER)).eval()
        music = torch.randn(1, args.frames, model.config.music_dim)
        ref = None
        for name, m in _variants(model, unfused=not args.no_unfused):
            if args.paper_rows and name not in args.paper_rows:
                continue
            wall, cpu = _time(lambda m=m: m.generate(music, generator=torch.Generator().manual_seed(0)), args.repeats)
            ref = ref or wall
            _row(f"paper-size revolution, {name}", wall, cpu, ref, f"{model.num_parameters() / 1e6:.1f} M params")
    if "embedded" in args.only:
        from dancekit.checkpoints import load_pretrained, resolve_model

        for name in ("revolution", "music2dance", "dual"):
            model = load_pretrained(resolve_model(name))[0].eval()
            c = model.config
            music = torch.randn(1, args.frames, c.music_dim)
            if name == "revolution":
                def run(m, music=music):
                    return m.generate(music, generator=torch.Generator().manual_seed(0))
            elif name == "music2dance":
                def run(m, music=music):
                    return m.generate(music, generator=torch.Generator().manual_seed(0), noise_correlation=0.9)
            else:
                start = torch.zeros(1, c.pose_dim)

                def run(m, music=music, start=start):
                    return m.generate_dance(music, start=start)
            ref = None
            for precision in PRECISIONS:
                m = to_precision(model, precision)
                wall, cpu = _time(lambda m=m: run(m), args.repeats)
                ref = ref or wall
                _row(f"embedded {name}, {precision}", wall, cpu, ref)


def _precision_module_at(rev: str):
    """``dancekit.models.precision`` as it was at git revision ``rev`` (a separate module object)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    text = subprocess.run(["git", "show", f"{rev}:src/dancekit/models/precision.py"], cwd=root, check=True,
                          capture_output=True, text=True).stdout
    spec = importlib.util.spec_from_loader(f"precision_at_{rev}", loader=None)
    module = importlib.util.module_from_spec(spec)
    exec(compile(text, f"{rev}:precision.py", "exec"), module.__dict__)
    return module


def bench_ab(args: argparse.Namespace) -> None:
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    old = _precision_module_at(args.against)
    model = RevolutionModel(RevolutionConfig(**PAPER)).eval()
    music = torch.randn(1, args.frames, model.config.music_dim)
    rows = {}
    for p in args.precisions:
        rows[f"{p} @ {args.against}"] = old.to_precision(model, p)
        rows[f"{p} @ this tree"] = to_precision(model, p)
    dances = {name: m.generate(music, generator=torch.Generator().manual_seed(0)) for name, m in rows.items()}  # warm
    times = {name: ([], []) for name in rows}
    for _ in range(args.repeats):
        for name, m in rows.items():
            c0, t0 = time.process_time(), time.perf_counter()
            m.generate(music, generator=torch.Generator().manual_seed(0))
            times[name][0].append(time.perf_counter() - t0)
            times[name][1].append(time.process_time() - c0)
    print(f"torch {torch.__version__}, threads {args.threads}, batch 1, {args.frames} frames, paper size, {args.repeats} "
          f"interleaved rounds after a warm-up; load = 1-min load average at the end: {_load()}")
    print("| decoder | wall s (median) | wall s (best) | CPU s (median) | CPU s (best) | max abs diff to the first row |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    first = next(iter(dances.values()))
    for name, (walls, cpus) in times.items():
        diff = (dances[name] - first).abs().max().item()
        print(f"| {name} | {statistics.median(walls):.3f} | {min(walls):.3f} | {statistics.median(cpus):.3f} | "
              f"{min(cpus):.3f} | {diff:.2e} |", flush=True)


def _dance(pipe, song: str, seed: int) -> np.ndarray:
    result = pipe(song, seed=seed, beat_sync=False, cleanup=False)
    pos = np.asarray(result.motion.to_positions(), np.float64)  # (T, J, 3)
    return pos - pos[:, result.motion.skeleton.root][:, None]  # the pose: root-relative (root paths drift apart)


HORIZONS = (2.0, 10.0, None)  # seconds from the start (None: the whole song)


def bench_accuracy(args: argparse.Namespace) -> None:
    from dancekit.pipelines import load_pipeline

    torch.set_num_threads(args.threads)
    names = ["fp32 seed 1"] + [p for p in PRECISIONS[1:]]
    heads = [f"{n}, {'whole' if h is None else f'first {h:g} s'}" for n in names for h in HORIZONS]
    print("mean per-joint distance (cm, root-relative poses) to the fp32 dance of seed 0; beat sync and clean-up off")
    print("| model | song | s | " + " | ".join(heads) + " | load |")
    print("| --- | --- | ---: | " + " | ".join("---:" for _ in heads) + " | ---: |")
    for name in args.models:
        pipes = {p: load_pipeline(name, precision=p) for p in PRECISIONS}
        for song in args.songs:
            ref = _dance(pipes["fp32"], song, 0)
            dances = [_dance(pipes["fp32"], song, 1)] + [_dance(pipes[p], song, 0) for p in PRECISIONS[1:]]
            fps = pipes["fp32"].fps
            cells = []
            for d in dances:
                dist = np.linalg.norm(d - ref, axis=-1).mean(axis=-1)  # (T,) mean over joints
                cells += [f"{dist[: None if h is None else int(h * fps)].mean():.2f}" for h in HORIZONS]
            print(f"| {name} | {os.path.basename(song)} | {len(ref) / fps:.0f} | {' | '.join(cells)} | {_load()} |",
                  flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="what", required=True)
    s = sub.add_parser("speed")
    s.add_argument("--threads", type=int, default=2)
    s.add_argument("--frames", type=int, default=900)
    s.add_argument("--repeats", type=int, default=3)
    s.add_argument("--only", nargs="+", choices=("paper", "embedded"), default=["paper", "embedded"])
    s.add_argument("--no-unfused", action="store_true", help="skip the int8 unfused (library LSTMCell) row")
    s.add_argument("--paper-rows", nargs="+", default=None, metavar="ROW",
                   help='only these paper-size rows, e.g. "fp32" "int8 fused" (default: all)')
    b = sub.add_parser("ab")
    b.add_argument("--against", required=True, metavar="REV", help="git revision whose decoder is the A row")
    b.add_argument("--precisions", nargs="+", default=["int8"], choices=PRECISIONS)
    b.add_argument("--threads", type=int, default=2)
    b.add_argument("--frames", type=int, default=900)
    b.add_argument("--repeats", type=int, default=5)
    a = sub.add_parser("accuracy")
    a.add_argument("songs", nargs="+")
    a.add_argument("--models", nargs="+", default=["revolution", "music2dance", "dual"])
    a.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    {"speed": bench_speed, "ab": bench_ab, "accuracy": bench_accuracy}[args.what](args)


if __name__ == "__main__":
    sys.exit(main())
