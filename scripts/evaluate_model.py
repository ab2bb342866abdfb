"""Generate a dance for every test song (or ``--split``) with a checkpoint, and score it with ``dancekit evaluate``.

    python scripts/evaluate_model.py --checkpoint runs/revolution/model --data data/tang2018 \
        --out runs/revolution/eval [--seeds 5]

For every dance of the test split, the model dances to the same slice of the same song
(``PreparedData.audio``) with ``--seeds`` seeds (``NAME__k.npz``; multimodality needs several);
the folder is then scored exactly as ``dancekit evaluate --pred OUT/pred --ref DATA --data DATA``
would, into ``OUT/report.json``, and the markdown table is printed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", required=True, help="checkpoint folder, or an embedded model name")
    parser.add_argument("--data", required=True, help="prepared dataset folder")
    parser.add_argument("--out", required=True, help="output folder (pred/ and report.json)")
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=5, help="dances per song (default 5)")
    parser.add_argument("--genre", default="auto",
                        help="auto (the genre read from the music when the model has a music attribute "
                             "classifier, else the model alone), none (the model alone), true (each song's own "
                             "genre), or a genre name for every song")
    args = parser.parse_args(argv)

    from tqdm import tqdm

    from dancekit.cli.main import main as dancekit
    from dancekit.data import PreparedData
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines import load_pipeline

    data = PreparedData(args.data)
    ckpt = Path(args.checkpoint)
    pipe = load_pipeline(checkpoint=ckpt) if ckpt.is_dir() else load_pipeline(args.checkpoint)
    pred = Path(args.out) / "pred"
    pred.mkdir(parents=True, exist_ok=True)
    for old in pred.glob("*.npz"):
        old.unlink()
    t0 = time.perf_counter()
    seconds = 0.0
    for name in tqdm(data.names(args.split), desc="generate", unit="song"):
        ref = data.audio(name)
        for k in range(args.seeds):
            genre = {"auto": None, "true": data.genre(name)}.get(args.genre, args.genre)
            motion = pipe(ref.path, seed=k, start=ref.start, end=ref.end, genre=genre).motion
            stem = name if args.seeds == 1 else f"{name}__{k}"
            write_motion(pred / f"{stem}.npz", motion)
            seconds += motion.duration
    elapsed = time.perf_counter() - t0
    print(f"generated {seconds:.0f} s of dance in {elapsed:.1f} s ({elapsed / seconds * 60:.2f} s per minute)")
    return dancekit(["evaluate", "--pred", str(pred), "--ref", args.data, "--split", args.split, "--data", args.data,
                     "-o", str(Path(args.out) / "report.json")])


if __name__ == "__main__":
    sys.exit(main())
