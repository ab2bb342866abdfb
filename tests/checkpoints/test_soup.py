"""dancekit.checkpoints.soup: the weighted mean of checkpoints' weights, written as a folder that loads."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from dancekit.errors import CheckpointError, ParameterError


def _tiny(tmp_path, name: str, seed: int, *, d_model: int = 16, stats_shift: float = 0.0):
    from dancekit.checkpoints import save_pretrained
    from dancekit.models.revolution import RevolutionConfig, RevolutionModel

    torch.manual_seed(seed)
    model = RevolutionModel(RevolutionConfig(music_dim=8, pose_dim=72, d_model=d_model, n_heads=2, d_ff=32,
                                             decoder_hidden=16))
    stats = {"music_mean": np.zeros(8) + stats_shift, "music_std": np.ones(8), "dance_mean": np.zeros(72),
             "dance_std": np.ones(72)}
    save_pretrained(tmp_path / name, model, model.config, stats=stats, extra={"fps": 25.0})
    return tmp_path / name, model


def test_the_average_of_two_checkpoints_is_their_elementwise_mean(tmp_path):
    from dancekit.checkpoints import load_pretrained
    from dancekit.checkpoints.soup import average_checkpoints

    a, ma = _tiny(tmp_path, "a", 0)
    b, mb = _tiny(tmp_path, "b", 1)
    out = average_checkpoints([a, b], tmp_path / "ab", weights=[3, 1])
    model, meta, stats = load_pretrained(out)
    sa, sb = ma.state_dict(), mb.state_dict()
    for k, v in model.state_dict().items():
        if v.is_floating_point():
            torch.testing.assert_close(v, 0.75 * sa[k] + 0.25 * sb[k], rtol=0, atol=1e-6)
    assert meta["soup"]["weights"] == [0.75, 0.25] and meta["fps"] == 25.0
    np.testing.assert_array_equal(stats["music_mean"], np.zeros(8))


def test_checkpoints_that_cannot_be_averaged_are_refused(tmp_path):
    from dancekit.checkpoints.soup import average_checkpoints

    a, _ = _tiny(tmp_path, "a", 0)
    wide, _ = _tiny(tmp_path, "wide", 1, d_model=32)
    other_data, _ = _tiny(tmp_path, "other", 2, stats_shift=1.0)
    with pytest.raises(CheckpointError, match="wide"):
        average_checkpoints([a, wide], tmp_path / "x")
    with pytest.raises(CheckpointError, match="stats.npz"):
        average_checkpoints([a, other_data], tmp_path / "x")
    with pytest.raises(CheckpointError, match="not found"):
        average_checkpoints([a, tmp_path / "missing"], tmp_path / "x")
    with pytest.raises(ParameterError, match="at least two"):
        average_checkpoints([a], tmp_path / "x")
    with pytest.raises(ParameterError, match="weights"):
        average_checkpoints([a, a], tmp_path / "x", weights=[1, -1])
    assert not (tmp_path / "x").exists()  # nothing half-written


def test_kept_tensors_and_component_folders_come_from_the_first_checkpoint(tmp_path):
    """``keep`` copies state that is not a weight (e.g. a pool of start poses) from the first folder, where the
    mean would blend unrelated entries; the first folder's sub-folders (its components) are copied."""
    from dancekit.checkpoints import load_pretrained
    from dancekit.checkpoints.soup import average_checkpoints

    a, ma = _tiny(tmp_path, "a", 0)
    b, mb = _tiny(tmp_path, "b", 1)
    (a / "music_attributes").mkdir()
    (a / "music_attributes" / "marker.txt").write_text("component")
    name = next(k for k, v in ma.state_dict().items() if v.is_floating_point())
    out = average_checkpoints([a, b], tmp_path / "ab", keep=[name])
    model, meta, _ = load_pretrained(out)
    state, sa, sb = model.state_dict(), ma.state_dict(), mb.state_dict()
    torch.testing.assert_close(state[name], sa[name], rtol=0, atol=0)
    other = next(k for k, v in sa.items() if v.is_floating_point() and k != name)
    torch.testing.assert_close(state[other], 0.5 * sa[other] + 0.5 * sb[other], rtol=0, atol=1e-6)
    assert meta["soup"]["kept"] == [name]
    assert (out / "music_attributes" / "marker.txt").read_text() == "component"
    with pytest.raises(ParameterError, match="no_such_tensor"):
        average_checkpoints([a, b], tmp_path / "x", keep=["no_such_tensor"])


def test_an_averaged_checkpoint_passes_the_pipelines_config_check(tmp_path):
    """Anything dancekit writes it reads back: the ``"soup"`` entry is a known key of a checkpoint's config."""
    from dancekit.checkpoints.soup import average_checkpoints
    from dancekit.pipelines.config import checkpoint_settings

    a, _ = _tiny(tmp_path, "a", 0)
    b, _ = _tiny(tmp_path, "b", 1)
    out = average_checkpoints([a, b], tmp_path / "ab")
    meta = json.loads((out / "config.json").read_text())
    checkpoint_settings(meta, folder=out)  # raises on an unknown key
    with pytest.raises(CheckpointError, match="soupe"):
        checkpoint_settings({**meta, "soupe": 1}, folder=out)
