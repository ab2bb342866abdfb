"""The per-genre tables of the embedded checkpoints ("genre_stats") recomputed from the raw tang2018 dances of
their training split as `dancekit prepare` makes them (dancekit.training.genre_stats.tang2018_genre_stats), which
is what `dancekit train` writes from the prepared dataset."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest

from dancekit.training.genre_stats import tang2018_genre_stats

ASSETS = Path(__file__).resolve().parents[2] / "src" / "dancekit" / "assets" / "models"

#: the tables each embedded model carries: the ones its stages read (revolution: the genre draw's and the jitter
#: cap's jitter, the energy lift's floor, the foot lock's planted share, the smoothing targets; music2dance: the
#: jitter cap and the smoothing; dual: the jitter cap and the energy lift)
TABLES = {"revolution": ("jitter", "energy", "planted_share", "smoothing"),
          "music2dance": ("jitter", "smoothing"),
          "dual": ("jitter", "energy")}


def _stored(model: str) -> dict:
    return json.loads((ASSETS / model / "config.json").read_text())["genre_stats"]


@functools.lru_cache(maxsize=1)
def _recompute(root: Path) -> dict:
    meta = json.loads((ASSETS / "revolution" / "config.json").read_text())
    names = meta["data"]["train"]
    for name in ("music2dance", "dual"):  # one training split for the three embedded models
        assert json.loads((ASSETS / name / "config.json").read_text())["data"]["train"] == names
    return tang2018_genre_stats(root, names)


@pytest.fixture
def recomputed(tang2018_dir):
    return _recompute(Path(tang2018_dir))


@pytest.mark.parametrize("model", sorted(TABLES))
def test_each_model_carries_the_tables_its_stages_read(model):
    assert set(_stored(model)) == set(TABLES[model])


@pytest.mark.slow
@pytest.mark.parametrize("model,table", [(m, t) for m, tables in TABLES.items() for t in tables])
def test_the_embedded_tables_are_the_training_dances_statistics(recomputed, model, table):
    assert _stored(model)[table] == recomputed[table]  # to the 3 decimals stored
