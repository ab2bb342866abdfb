"""A candidate checkpoint folder: a model folder with some ``config.json`` entries changed, every other file
linked (nothing copied but the config), for `dancekit evaluate --checkpoint FOLDER` on a grid of settings.

    PYTHONPATH=src python benchmarks/candidate_folder.py revolution /tmp/cand1 \
        '{"sampling": {"genre_temperature": 2, "genre_alone": 0.25, "jitter_cap": 1.0}}'

The JSON's top-level objects are merged into the folder's entries of the same name (``null`` deletes a key).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from dancekit.checkpoints.hub import resolve_model


def candidate_folder(model: str, dst: str | Path, change: dict, *, merge: bool = True) -> Path:
    """``dst``: the folder of ``model`` (a name or a folder) with ``change`` applied to its ``config.json`` (each
    top-level object merged into the entry of that name, ``null`` inside it deleting a key; ``merge=False``:
    each entry replaced whole; a top-level ``null`` deletes the entry) and every other file linked."""
    src, dst = Path(resolve_model(model)), Path(dst)
    dst.mkdir(parents=True, exist_ok=False)
    for item in src.iterdir():
        if item.name != "config.json":
            (dst / item.name).symlink_to(item.resolve())
    config = json.loads((src / "config.json").read_text())
    for key, value in change.items():
        if merge and isinstance(value, dict) and isinstance(config.get(key), dict):
            merged = {**config[key], **value}
            config[key] = {k: v for k, v in merged.items() if v is not None}
        elif value is None:
            config.pop(key, None)
        else:
            config[key] = value
    (dst / "config.json").write_text(json.dumps(config, indent=2))
    return dst


def main() -> None:
    dst = candidate_folder(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]))
    print(dst, json.dumps(json.loads((dst / "config.json").read_text()).get("sampling")))


if __name__ == "__main__":
    main()
