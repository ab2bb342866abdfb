"""The contract every model family of ``dancekit.registry`` keeps.

For every registered family, with a tiny configuration, on a small fake prepared dataset:
``dancekit train FAMILY`` runs (dataset builder, data fields, objective, checkpoint), the model runs forward
and its loss has gradients, save → load gives identical outputs, and the family's pipeline loads the
checkpoint by folder and runs on a short synthetic song (or a motion, for families whose input is motion).
A new family needs its tiny settings in ``TINY`` below — the first test fails until it has them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from _prepared import write_fake_prepared

from dancekit import registry
from dancekit.cli.main import main

# per family: --set values that make the model small enough to train two steps in a second
TINY: dict[str, list[str]] = {
    "revolution": ["d_model=16", "n_heads=2", "d_ff=32", "decoder_hidden=16", "window=6"],
    "music_attributes": ["channels=4,4,4", "lstm_hidden=4"],
    "style": ["channels=8", "feature_dim=8"],
    "dual": ["m2d_d_model=8", "m2d_heads=2", "m2d_ff=8", "m2d_layers=1", "d2m_d_model=8", "d2m_heads=2", "d2m_ff=8",
             "d2m_layers=1", "gw_sinkhorn_iters=3", "gw_projection_iters=2"],
    "music2dance": ["n_layers=3", "channels=4", "skip_channels=4", "genre_dim=4", "fmap_channels=4,4,4",
                    "fmap_lstm_hidden=4"],
    "foot_constraint": ["channels=4", "lstm_hidden=4"],
}
TRAIN = ["steps=2", "batch_size=2", "seq_len=32", "stride=16", "val_every=2", "ckpt_every=2", "log_every=1",
         "warmup_steps=0", "threads=1"]


def test_every_family_is_declared_completely():
    assert set(TINY) == set(registry.families()), "give every registered family its tiny settings in TINY"
    for name in registry.families():
        fam = registry.get(name)
        assert dataclasses.is_dataclass(fam.config_class), name
        assert issubclass(fam.module_class, torch.nn.Module), name
        assert callable(fam.load("objective")) and callable(fam.load("dataset")), name
        assert hasattr(fam.load("pipeline"), "from_pretrained"), name
        assert fam.kind in ("dance", "classifier", "postprocess") and fam.input in ("audio", "motion"), name
        assert set(fam.data_fields) <= {f.name for f in dataclasses.fields(fam.config_class)}, name


def test_unknown_family_is_a_named_error():
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError, match="unknown model family 'nope'.*revolution"):
        registry.get("nope")
    with pytest.raises(ParameterError, match="registered already"):
        registry.register(registry.get("revolution"))


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    from dancekit.audio import save_wav, synth

    path = tmp_path_factory.mktemp("song") / "tune.wav"
    save_wav(path, synth.ode_to_joy(sr=22050)[: 3 * 22050], sr=22050)
    return path


@pytest.fixture(scope="module", params=sorted(TINY))
def trained(request, tmp_path_factory):
    """(family, prepared data folder, run folder) after `dancekit train FAMILY` for two steps."""
    from dancekit.features import PRESET_DIMS

    name = request.param
    fam = registry.get(name)
    preset = fam.preset or "revolution"
    root = tmp_path_factory.mktemp(name)
    data = write_fake_prepared(root / "data", np.random.default_rng(0), preset=preset, dim=PRESET_DIMS[preset])
    run = root / "run"
    args = ["train", name, "--data", str(data), "--out", str(run), "--quiet"]
    for item in TINY[name] + TRAIN:
        args += ["--set", item]
    assert main(args) == 0
    return name, data, run


def _batch_and_ctx(name, data, model, *, training):
    from dancekit.checkpoints import NormStats, load_pretrained
    from dancekit.data import PreparedData
    from dancekit.training import StepContext, TrainConfig

    fam = registry.get(name)
    _, meta, arrays = load_pretrained(data.parent / "run" / "model")
    tc = TrainConfig(**meta["train"])
    stats = NormStats(**arrays) if set(arrays) == {"music_mean", "music_std", "dance_mean", "dance_std"} else arrays
    train_set, _ = fam.load("dataset")(PreparedData(data), tc, stats, preset=fam.preset)
    batch = torch.utils.data.default_collate([train_set[i] for i in range(2)])
    ctx = StepContext(step=0, epoch=0, training=training, generator=torch.Generator().manual_seed(0), config=tc)
    return batch, ctx


def test_forward_and_loss_have_gradients(trained):
    from dancekit.checkpoints import load_pretrained

    name, data, run = trained
    model, _, _ = load_pretrained(run / "model")
    model.train()
    batch, ctx = _batch_and_ctx(name, data, model, training=True)
    loss, logs = registry.get(name).load("objective")(model, batch, ctx)
    assert loss.ndim == 0 and torch.isfinite(loss)
    loss.backward()
    grads = [p.grad for p in model.parameters() if p.grad is not None]
    assert grads and any(float(g.abs().sum()) > 0 for g in grads)


def test_save_then_load_gives_identical_outputs(trained, tmp_path):
    from dancekit.checkpoints import load_pretrained, read_config, save_pretrained

    name, data, run = trained
    model, meta, arrays = load_pretrained(run / "model")
    extra = {k: v for k, v in read_config(run / "model").items() if k not in ("model", "config")}
    save_pretrained(tmp_path / "copy", model, model.config, stats=arrays, extra=extra)
    again, meta2, arrays2 = load_pretrained(tmp_path / "copy")
    assert meta2["model"] == name and meta2["config"] == meta["config"]
    for key in arrays:
        np.testing.assert_array_equal(arrays[key], arrays2[key])
    objective = registry.get(name).load("objective")
    batch, ctx = _batch_and_ctx(name, data, model, training=False)
    a, _ = objective(model, batch, ctx)
    _, ctx2 = _batch_and_ctx(name, data, again, training=False)
    b, _ = objective(again, batch, ctx2)
    assert float(a.detach()) == float(b.detach())


def test_pipeline_runs_on_a_short_synthetic_input(trained, song):
    from dancekit.motion import Motion, get_skeleton
    from dancekit.pipelines import DanceResult, load_pipeline

    name, _, run = trained
    fam = registry.get(name)
    pipe = fam.load("pipeline").from_pretrained(run / "model")
    assert type(load_pipeline(run / "model")) is type(pipe)  # the registry picks the same class
    if fam.input == "audio":
        out = pipe(str(song), seed=1) if fam.kind == "dance" else pipe(str(song))
    else:
        t = np.linspace(0, 2 * np.pi, 120)[:, None, None]
        skel = get_skeleton("tang2018")
        positions = (skel.rest_positions()[None] if hasattr(skel, "rest_positions") else
                     np.zeros((1, skel.num_joints, 3))) + 5 * np.sin(t) * np.ones((1, skel.num_joints, 3))
        out = pipe(Motion(skeleton=skel, fps=25.0, positions=positions.astype(np.float32)))
    if fam.kind == "postprocess":  # motion → motion (the Foot Constraint Model)
        assert isinstance(out, Motion) and out.num_frames == 120 and np.isfinite(out.to_positions()).all()
    elif fam.kind == "dance":
        assert isinstance(out, DanceResult) and out.seed == 1
        assert out.motion.num_frames == 1 + (3 * 22050 * 25 * 512 // 22050) // 512
        assert np.isfinite(out.motion.to_positions()).all()
    else:  # a classifier: the probabilities of its classes (a dict, or a result holding them)
        probs = getattr(out, "genre_probs", out)
        assert isinstance(probs, dict) and len(probs) >= 2 and sum(probs.values()) == pytest.approx(1.0, abs=1e-5)
