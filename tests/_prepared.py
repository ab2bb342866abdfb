"""A tiny prepared dataset (random motion and features) in the layout of `dancekit prepare`, for tests."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

DANCES = [("DANCE_W_1", "train", 90), ("DANCE_R_1", "train", 70), ("DANCE_W_2", "val", 60)]


def write_fake_prepared(root: Path, rng: np.random.Generator, *, preset: str = "revolution", dim: int = 438) -> Path:
    """Two waltzes and a rumba (``DANCES``) with random positions and random ``preset`` features of ``dim``
    columns, written to ``root``; returns ``root``."""
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.formats import write_motion

    skel = get_skeleton("tang2018")
    dances, splits = {}, {"train": [], "val": [], "test": [], "seed": 0}
    for name, split, T in DANCES:
        folder = root / "dances" / name
        folder.mkdir(parents=True)
        pos = rng.normal(0, 10, (T, skel.num_joints, 3)).astype(np.float32)
        write_motion(folder / "motion.npz", Motion(skeleton=skel, fps=25.0, positions=pos))
        np.savez(folder / f"features_{preset}.npz", features=rng.normal(size=(T, dim)).astype(np.float32),
                 names=np.asarray([f"x:{dim}"]), beat_times=np.zeros(0), fps=np.float64(25), preset=np.asarray(preset))
        dances[name] = {"genre": "waltz" if "_W_" in name else "rumba", "frames": T, "audio": ["none.wav", 0.0, T / 25]}
        splits[split].append(name)
    meta = {"source": "test", "fps": 25.0, "hop_length": 512, "skeleton": skel.to_dict(), "presets": [preset],
            "genres": ["waltz", "rumba", "chacha", "tango"], "dances": dances}
    (root / "meta.json").write_text(json.dumps(meta))
    (root / "splits.json").write_text(json.dumps(splits))
    return root
