"""The per-genre tables of the embedded checkpoints ("genre_stats") recomputed from the tang2018 dances of their
training split as `dancekit prepare` makes them: what `dancekit train` writes (prepared_genre_stats of the prepared
data), and the same from the raw dances (tang2018_genre_stats)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancekit.data.prepared import level_tang2018
from dancekit.training.genre_stats import genre_stats, prepared_genre_stats, tang2018_genre_stats

ASSETS = Path(__file__).resolve().parents[2] / "src" / "dancekit" / "assets" / "models"

#: the tables each embedded model carries: the ones its stages read (revolution: the genre draw's and the jitter
#: cap's jitter, the energy lift's floor, the foot lock's planted share, the smoothing targets; music2dance: the
#: jitter cap, the foot lock's planted share and the smoothing; dual: the jitter cap and the energy lift)
TABLES = {"revolution": ("jitter", "energy", "planted_share", "smoothing"),
          "music2dance": ("jitter", "planted_share", "smoothing"),
          "dual": ("jitter", "energy")}


def _stored(model: str) -> dict:
    return json.loads((ASSETS / model / "config.json").read_text())["genre_stats"]


@pytest.fixture(scope="module")
def recomputed(prepared_tang2018):
    """The tables of the training split of tang2018 prepared here (conftest's session fixture; the same split as the
    embedded models': whole dances by genre, seed 0)."""
    names = json.loads((ASSETS / "revolution" / "config.json").read_text())["data"]["train"]
    for name in ("music2dance", "dual"):  # one training split for the three embedded models
        assert json.loads((ASSETS / name / "config.json").read_text())["data"]["train"] == names
    assert prepared_tang2018.names("train") == names
    return prepared_genre_stats(prepared_tang2018, "train")


@pytest.mark.parametrize("model", sorted(TABLES))
def test_each_model_carries_the_tables_its_stages_read(model):
    assert set(_stored(model)) == set(TABLES[model])


@pytest.mark.slow
@pytest.mark.parametrize("model,table", [(m, t) for m, tables in TABLES.items() for t in tables])
def test_the_embedded_tables_are_the_training_dances_statistics(recomputed, model, table):
    assert _stored(model)[table] == recomputed[table]  # to the 3 decimals stored


@pytest.mark.slow
def test_the_raw_dances_give_the_prepared_dances_tables(prepared_tang2018, tang2018_dir):
    """tang2018_genre_stats levels the raw dances' floor as `dancekit prepare` does, so a dance's tables are the
    prepared dance's (the planted share moves with an unlevelled floor: 0.2595 unlevelled, 0.2582 levelled for
    DANCE_C_2)."""
    names = ["DANCE_C_2", "DANCE_W_10"]
    raw = tang2018_genre_stats(tang2018_dir, names)
    assert raw == genre_stats((prepared_tang2018.genre(n), prepared_tang2018.motion(n)) for n in names)
    motion = level_tang2018(Path(tang2018_dir) / names[0])[0]
    np.testing.assert_array_equal(motion.positions, prepared_tang2018.motion(names[0]).positions)
