"""The music features of a model's song prefetched in a second process (:mod:`dancekit.features.prefetch`)
with the model's own feature settings, for a cold ``dancekit dance``."""

from __future__ import annotations

import os

from dancekit.checkpoints.hub import read_meta, resolve_model
from dancekit.features.prefetch import Prefetch, prefetch_features


def prefetch_for_model(path: str | os.PathLike, model: str | os.PathLike | None, *, start: float | None = None,
                       end: float | None = None) -> Prefetch:
    """:func:`prefetch_features` with the feature settings of ``model`` (a name or folder, as
    :func:`dancekit.pipelines.load_pipeline` takes it: its ``config.json`` ``fps``, ``preset`` and
    ``hop_length``); no child when the model cannot be resolved (loading it reports that)."""
    try:
        meta = read_meta(resolve_model(model))
        preset, fps, hop = meta.get("preset"), float(meta["fps"]), int(meta.get("hop_length", 512))
    except Exception:  # noqa: BLE001 - the model's loading reports it
        return Prefetch()
    if not isinstance(preset, str):
        return Prefetch()
    return prefetch_features(path, fps=fps, preset=preset, hop_length=hop, start=start, end=end)
