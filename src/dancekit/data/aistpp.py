"""The AIST++ release on disk: ``dancekit prepare aistpp SRC -o DIR`` (:func:`prepare_aistpp`).

The release layout (https://google.github.io/aistplusplus_dataset/)::

    SRC/motions/gBR_sBM_cAll_d04_mBR0_ch01.pkl   # smpl_poses (T, 72), smpl_trans (T, 3), smpl_scaling (1,), 60 fps
    SRC/wavs/mBR0.wav                            # the music, named by the music id inside the sequence name
    SRC/splits/crossmodal_train.txt              # one sequence name a line (also _val, _test)
    SRC/ignore_list.txt                          # sequences with bad motion, left out

(``wavs/`` may also be called ``music/``; songs in any format :func:`dancekit.audio.load` reads.) Each
sequence is paired with the song of its music id (the ``m…`` part of the name: ``mBR0``); motion frame 0
plays at second 0 of the song. The genre is the name's first part without its ``g`` (``gBR`` → ``BR``,
break). The official crossmodal splits are used as given; a sequence in none of them, in the ignore
list, without its song, or unreadable is skipped and listed in ``DIR/report.json``. Preparation is
:func:`dancekit.data.pairs.prepare_dataset`'s: one pair at a time per worker process (memory bounded by the
longest dance), motions resampled to ``fps``, positions by SMPL forward kinematics.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from dancekit.data.pairs import AUDIO_SUFFIXES, check_prepare_args, prepare_dataset
from dancekit.errors import DatasetError

__all__ = ["AISTPP_GENRES", "music_id", "prepare_aistpp"]

#: AIST++ genre codes → names.
AISTPP_GENRES = {"BR": "break", "PO": "pop", "LO": "lock", "MH": "middle hip-hop", "LH": "LA hip-hop",
                 "HO": "house", "WA": "waack", "KR": "krump", "JS": "street jazz", "JB": "ballet jazz"}

_NAME = re.compile(r"^g(?P<genre>[A-Z]{2})_.*_(?P<music>m[A-Z]{2}\d+)(_|$)")
SPLITS = ("train", "val", "test")


def music_id(sequence: str) -> tuple[str, str] | None:
    """(genre code, music id) of an AIST++ sequence name, e.g. ``("BR", "mBR0")`` for
    ``gBR_sBM_cAll_d04_mBR0_ch01``; None when the name does not follow the AIST++ pattern."""
    m = _NAME.match(sequence)
    return None if m is None else (m["genre"], m["music"])


def _lines(path: Path) -> list[str]:
    return [ln.strip() for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]


def prepare_aistpp(
    src: str | os.PathLike,
    out: str | os.PathLike,
    *,
    fps: float = 25.0,
    presets: tuple[str, ...] = ("revolution",),
    hop_length: int = 512,
    workers: int = 1,
    progress: bool = True,
) -> tuple[Path, dict[str, Any]]:
    """Prepare an AIST++ release folder ``src`` into ``out`` (see the module docstring).

    Returns
    -------
    (``out``, the report): ``{"prepared": [names], "skipped": [{"file", "reason"}], ...}``, also written to
    ``out/report.json``.

    Raises
    ------
    DatasetError
        When ``src`` lacks ``motions/`` or a music folder, or no sequence could be prepared.
    ParameterError
        For an unknown preset, a bad ``fps`` or ``workers``.
    """
    src = Path(src)
    fps = check_prepare_args(presets=presets, fps=fps, workers=workers)
    motions_dir = src / "motions"
    music_dir = next((src / d for d in ("wavs", "music") if (src / d).is_dir()), None)
    if not motions_dir.is_dir() or music_dir is None:
        raise DatasetError(f"{src} is not an AIST++ release folder: it needs motions/ and wavs/ (or music/)")
    songs = {p.stem: p for p in sorted(music_dir.iterdir()) if p.suffix.lower() in AUDIO_SUFFIXES}
    ignored = set(_lines(src / "ignore_list.txt")) if (src / "ignore_list.txt").is_file() else set()
    splits: dict[str, list[str]] | None = None
    if (src / "splits").is_dir():
        splits = {k: _lines(src / "splits" / f"crossmodal_{k}.txt") for k in SPLITS
                  if (src / "splits" / f"crossmodal_{k}.txt").is_file()}
    in_split = set() if splits is None else {n for names in splits.values() for n in names}

    pairs: dict[str, tuple[Path, Path]] = {}
    labels: dict[str, dict[str, Any]] = {}
    skipped: list[dict[str, str]] = []
    for p in sorted(motions_dir.iterdir()):
        if p.suffix.lower() != ".pkl":
            if not p.name.startswith("."):
                skipped.append({"file": f"motions/{p.name}", "reason": "not an AIST++ motion .pkl"})
            continue
        name = p.stem
        ids = music_id(name)
        reason = None
        if name in ignored:
            reason = "in ignore_list.txt"
        elif ids is None:
            reason = "its name has no AIST++ genre and music id (gXX_..._mXXN_...)"
        elif ids[1] not in songs:
            reason = f"no song {ids[1]} in {music_dir.name}/"
        elif splits is not None and name not in in_split:
            reason = "in none of the crossmodal splits"
        if reason is not None:
            skipped.append({"file": f"motions/{p.name}", "reason": reason})
            continue
        pairs[name] = (songs[ids[1]], p)
        labels[name] = {"genre": ids[0]}
    if not pairs:
        raise DatasetError(f"no AIST++ sequence of {src} has its song (skipped: {len(skipped)} files)")
    return prepare_dataset(src, out, pairs, skipped, labels=labels, source="aistpp", fps=fps, presets=presets,
                           hop_length=hop_length, workers=workers, progress=progress, splits=splits)
