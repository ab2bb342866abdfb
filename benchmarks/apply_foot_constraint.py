"""Post-process a folder of generated dances with a Foot Constraint Model (before/after foot skating).

    PYTHONPATH=src python benchmarks/apply_foot_constraint.py runs/eval_rev/pred runs/eval_rev_fc/pred [MODEL]
    PYTHONPATH=src python benchmarks/apply_foot_constraint.py --real data/tang2018 val runs/fc_real_val [MODEL]

Every ``*.npz`` dance of the first folder (``dancekit evaluate --checkpoint ... -o OUT`` writes ``OUT/pred``) is
corrected by the foot model (default: the one embedded with music2dance; or a foot_constraint checkpoint folder)
and written with the same name into the second folder, so that ``dancekit evaluate --pred`` scores both folders
alike (FID_k, foot skating, ...). Prints the mean foot-skating ratio (``dancekit.metrics.physics.foot_skating``)
before and after, and the seconds the model took. ``--real DATA SPLIT OUT``: the real dances of the split,
round-tripped through ``rotations_rootdelta`` (clean input: the foot model should leave them as they are),
written to ``OUT/clean`` and corrected into ``OUT/fixed``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch

from dancekit.metrics.physics import foot_skating
from dancekit.motion import read_motion, write_motion
from dancekit.pipelines.foot_constraint import load_foot_constraint


def main(src: str, dst: str, model: str | None = None) -> None:
    torch.set_num_threads(1)
    fix = load_foot_constraint(model)
    out = Path(dst)
    out.mkdir(parents=True, exist_ok=True)
    before, after, seconds, elapsed = [], [], 0.0, 0.0
    for path in sorted(Path(src).glob("*.npz")):
        motion = read_motion(path)
        t0 = time.perf_counter()
        fixed = fix(motion)
        elapsed += time.perf_counter() - t0
        seconds += motion.duration
        write_motion(out / path.name, fixed)
        for m, acc in ((motion, before), (fixed, after)):
            acc.append(foot_skating(m.to_positions(), fps=m.fps, skeleton=m.skeleton)["ratio"])
    print(f"{src} → {dst} ({fix.folder}): {len(before)} dances, foot skating {np.nanmean(before):.3f} → "
          f"{np.nanmean(after):.3f}; {elapsed:.1f} s for {seconds:.0f} s of dance")


def real(data: str, split: str, out: str, model: str | None = None) -> None:
    from dancekit.data import PreparedData
    from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta

    prepared = PreparedData(data)
    clean = Path(out) / "clean"
    clean.mkdir(parents=True, exist_ok=True)
    for name in prepared.names(split):
        m = prepared.motion(name)
        write_motion(clean / f"{name}.npz", decode_rootdelta(encode_rootdelta(m), m.skeleton, m.fps))
    main(str(clean), str(Path(out) / "fixed"), model)


if __name__ == "__main__":
    if sys.argv[1] == "--real":
        real(*sys.argv[2:6])
    else:
        main(*sys.argv[1:4])
