"""The training data a GPU machine needs, small enough to travel with the working tree (the device tool's 64 MiB).

    python scripts/gpu_data.py slim data/tang2018 data/gpu/tang2018     # here: train + val dances, positions only,
                                                                       # the dual and music2dance features
    python scripts/gpu_data.py rebuild data/gpu/tang2018                # there: the IK rotations re-solved in place

``rebuild`` solves the rotations as ``dancekit prepare`` does (``Motion.with_rotations``); on the prepared tang2018
the re-solved rotations equal the prepared ones exactly (checked on DANCE_C_2). Then
``DATA=data/gpu/tang2018 scripts/train_gpu.sh FAMILY STEPS OUT`` trains there.
"""

from __future__ import annotations

import json
import shutil
import sys
from multiprocessing import Pool
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

PRESETS = ("dual", "music2dance")


def slim(src: Path, dst: Path) -> None:
    from dancekit.motion import Motion
    from dancekit.motion.formats import read_motion, write_motion

    shutil.rmtree(dst, ignore_errors=True)
    (dst / "dances").mkdir(parents=True)
    meta = json.loads((src / "meta.json").read_text())
    splits = json.loads((src / "splits.json").read_text())
    keep = splits["train"] + splits["val"]
    meta["dances"] = {k: v for k, v in meta["dances"].items() if k in keep}
    meta["presets"] = list(PRESETS)
    splits["test"] = []
    (dst / "meta.json").write_text(json.dumps(meta, indent=1))
    (dst / "splits.json").write_text(json.dumps(splits, indent=1))
    for name in keep:
        folder = dst / "dances" / name
        folder.mkdir()
        m = read_motion(src / "dances" / name / "motion.npz")
        write_motion(folder / "motion.npz", Motion(skeleton=m.skeleton, fps=m.fps, positions=m.positions))
        for preset in PRESETS:
            shutil.copy(src / "dances" / name / f"features_{preset}.npz", folder)
    print(f"{len(keep)} dances (train + val) -> {dst}")


def _resolve(path: Path) -> str:
    from dancekit.motion.formats import read_motion, write_motion

    motion = read_motion(path).with_rotations()
    path.unlink()
    write_motion(path, motion)
    return path.parent.name


def rebuild(root: Path) -> None:
    paths = sorted(root.glob("dances/*/motion.npz"))
    with Pool(min(14, len(paths) or 1)) as pool:
        print(f"{len(pool.map(_resolve, paths))} dances re-solved in {root}")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "slim":
        slim(Path(sys.argv[2]), Path(sys.argv[3]))
    elif len(sys.argv) == 3 and sys.argv[1] == "rebuild":
        rebuild(Path(sys.argv[2]))
    else:
        sys.exit(__doc__)
