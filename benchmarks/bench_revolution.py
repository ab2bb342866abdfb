"""Dance Revolution speed and memory figures (run by hand, CPU).

    python benchmarks/bench_revolution.py memory                 # peak RSS of the encoder, local vs global
    python benchmarks/bench_revolution.py train [--quick]        # s/iteration of candidate sizes
    python benchmarks/bench_revolution.py generate               # model time for a 60 s dance (1,500 frames)

``memory`` runs every measurement in a fresh subprocess and reports the growth of the peak resident
set size (``ru_maxrss``) during one encoder forward pass (no gradients), batch 1, for n = 1,000 and
n = 10,000 frames. ``train`` times full optimisation steps (forward with the curriculum at the given
p, backward, AdamW) with ``torch.set_num_threads(threads)`` and the median of several steps.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

import torch

from dancekit.models.revolution import RevolutionConfig, RevolutionModel

MUSIC_DIM, POSE_DIM = 438, 72


def _memory_child(encoder: str, n: int, pos_encoding: str) -> None:
    import resource

    torch.set_num_threads(1)
    cfg = RevolutionConfig(encoder=encoder, pos_encoding=pos_encoding)
    model = RevolutionModel(cfg).eval()
    music = torch.randn(1, n, MUSIC_DIM)
    with torch.no_grad():
        model.encoder(music[:, :8])  # warm-up allocations
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    with torch.no_grad():
        z = model.encoder(music)
    dt = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"encoder": encoder, "pos_encoding": pos_encoding, "n": n, "peak_delta_mib": (after - before) / 1024,
                      "seconds": dt, "shape": list(z.shape)}))


def bench_memory(args: argparse.Namespace) -> None:
    cfg = RevolutionConfig()
    print(f"encoder: d_model={cfg.d_model} heads={cfg.n_heads} layers={cfg.n_layers} window k={cfg.window}; batch 1")
    for pos in args.pos_encodings:
        for n in (1000, 10000):
            for encoder in ("local", "global"):
                out = subprocess.run(
                    [sys.executable, __file__, "_memory_child", encoder, str(n), pos],
                    capture_output=True, text=True,
                )
                if out.returncode != 0:
                    print(f"{encoder:6s} n={n:6d} {pos}: failed ({out.stderr.strip().splitlines()[-1:]})")
                    continue
                r = json.loads(out.stdout.strip().splitlines()[-1])
                print(f"{encoder:6s} {pos:10s} n={n:6d}: peak RSS +{r['peak_delta_mib']:8.1f} MiB, {r['seconds']:.3f} s")


CANDIDATES = [
    # (batch, seq_len, d_model, d_ff, decoder_hidden, decoder_layers); the first is the default
    (16, 240, 128, 512, 256, 2),
    (32, 120, 128, 512, 256, 2),
    (16, 240, 192, 768, 256, 2),
    (16, 240, 128, 512, 384, 2),
    (16, 240, 128, 512, 512, 2),
    (16, 240, 256, 1024, 512, 2),
    (16, 240, 256, 1024, 512, 3),  # near an earlier probe (4.4 M parameters, ~1.5 s/iteration at p = 20)
]


def _time_steps(cfg: RevolutionConfig, *, batch: int, seq_len: int, p: int, q: int, steps: int) -> float:
    model = RevolutionModel(cfg).train()
    opt = torch.optim.AdamW(model.parameters(), lr=1e-4)
    music, dance = torch.randn(batch, seq_len, cfg.music_dim), torch.randn(batch, seq_len, cfg.pose_dim)
    gen = torch.Generator().manual_seed(0)
    times = []
    for i in range(steps + 1):
        t0 = time.perf_counter()
        _, loss = model(music, dance, schedule_p=p, schedule_q=q, generator=gen)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        if i:  # the first step warms up allocators
            times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_train(args: argparse.Namespace) -> None:
    torch.set_num_threads(args.threads)
    cands = CANDIDATES[:2] if args.quick else CANDIDATES
    print(f"threads={args.threads}, q={args.q}; median of {args.steps} steps after one warm-up step (forward + backward + AdamW)")
    for batch, seq_len, d_model, d_ff, hidden, layers in cands:
        cfg = RevolutionConfig(d_model=d_model, d_ff=d_ff, n_heads=max(4, d_model // 64), decoder_hidden=hidden,
                               decoder_layers=layers)
        n_params = RevolutionModel(cfg).num_parameters()
        row = []
        for p in args.p:
            row.append(_time_steps(cfg, batch=batch, seq_len=seq_len, p=p, q=args.q, steps=args.steps))
        cells = "  ".join(f"p={p:2d}: {t:.3f} s" for p, t in zip(args.p, row))
        print(f"B={batch:2d} L={seq_len} d={d_model} ff={d_ff} lstm={layers}x{hidden} ({n_params / 1e6:.2f} M): {cells}")


def bench_generate(args: argparse.Namespace) -> None:
    torch.set_num_threads(args.threads)
    cfg = RevolutionConfig()
    model = RevolutionModel(cfg).eval()
    music = torch.randn(1, args.frames, cfg.music_dim)
    model.generate(music[:, :50], generator=torch.Generator().manual_seed(0))
    times = []
    for seed in range(args.repeats):
        t0 = time.perf_counter()
        out = model.generate(music, generator=torch.Generator().manual_seed(seed))
        times.append(time.perf_counter() - t0)
    print(f"generate {args.frames} frames ({model.num_parameters() / 1e6:.2f} M parameters, threads={args.threads}): "
          f"median {statistics.median(times):.3f} s, min {min(times):.3f} s, output {tuple(out.shape)}")


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "_memory_child":
        _memory_child(sys.argv[2], int(sys.argv[3]), sys.argv[4])
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="what", required=True)
    m = sub.add_parser("memory")
    m.add_argument("--pos-encodings", nargs="+", default=["relative"], choices=["relative", "sinusoidal"])
    t = sub.add_parser("train")
    t.add_argument("--threads", type=int, default=2)
    t.add_argument("--steps", type=int, default=3)
    t.add_argument("--p", type=int, nargs="+", default=[0, 10, 30])
    t.add_argument("--q", type=int, default=10)
    t.add_argument("--quick", action="store_true")
    g = sub.add_parser("generate")
    g.add_argument("--threads", type=int, default=2)
    g.add_argument("--frames", type=int, default=1500)
    g.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    {"memory": bench_memory, "train": bench_train, "generate": bench_generate}[args.what](args)


if __name__ == "__main__":
    main()
