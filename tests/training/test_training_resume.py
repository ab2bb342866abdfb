"""Exact resumption on the real training path (a prepared dataset, `WindowDataset` windows with random
offsets, an interrupted run resumed from its checkpoint ends with the uninterrupted run's weights); the
trainer's steps and data-parallel hooks; the settings' split and the checkpoints' saved settings; assembling
a run."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import torch
from _prepared import write_fake_prepared
from safetensors.torch import load_file

from dancekit.data import PreparedData, WindowDataset, compute_stats
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel
from dancekit.training import (
    DataConfig,
    OptimConfig,
    TrainConfig,
    Trainer,
    assemble_run,
    checkpoints,
    revolution_step,
    train,
)
from dancekit.training.datasets import music_dance_windows

ASSETS = Path(__file__).resolve().parents[2] / "src" / "dancekit" / "assets" / "models"

D = 8  # music features per frame of the fake dataset
STEPS = 10  # 26 training windows of 20 frames (stride 5) / batch 4 = 6 steps per epoch: two epochs


class Interrupted(Exception):
    pass


@pytest.fixture
def prepared(tmp_path, rng):
    return PreparedData(write_fake_prepared(tmp_path / "prepared", rng, dim=D))


def _run(data: PreparedData, out, cfg: TrainConfig, model_cfg: RevolutionConfig, *, model_seed: int,
         resume: bool = False, stop_after: int | None = None):
    """Train as `dancekit train` does (fresh datasets and model); raise `Interrupted` once step ``stop_after``
    is done and checkpointed (from the log record of the next step)."""
    stats = compute_stats(data, preset="revolution", representation=cfg.representation)
    train_set, val_set = music_dance_windows(data, cfg, stats, preset="revolution")
    torch.manual_seed(model_seed)
    model = RevolutionModel(model_cfg)

    def interrupt(record):
        if stop_after is not None and record.get("step") == stop_after + 1:
            raise Interrupted

    return train(model, train_set, val_set, cfg, step_fn=revolution_step, out_dir=out, resume=resume,
                 stats=stats, progress=False, callbacks=[interrupt])


@pytest.mark.parametrize("stop_after,model_kw,train_kw", [
    (4, {}, {}),  # interrupted in the first epoch
    (7, {"n_genres": 4}, {"music_dropout": 0.5, "genre_dropout": 0.5}),  # in the second; the objective draws too
], ids=["plain", "genre_music_dropout"])
def test_resumed_run_on_window_dataset_equals_uninterrupted_run(prepared, tmp_path, stop_after, model_kw, train_kw):
    cfg = TrainConfig(steps=STEPS, batch_size=4, lr=3e-3, warmup_steps=2, log_every=1, val_every=3,
                      ckpt_every=stop_after, threads=1, seq_len=20, stride=5, curriculum_lambda=1.0,
                      curriculum_q=3, **train_kw)
    assert cfg.random_offset  # the default: every item's start is jittered
    model_cfg = RevolutionConfig(music_dim=D, pose_dim=72, d_model=16, n_heads=2, d_ff=32, window=6,
                                 decoder_hidden=16, **model_kw)

    straight = _run(prepared, tmp_path / "straight", cfg, model_cfg, model_seed=0)
    assert straight.step == STEPS

    with pytest.raises(Interrupted):
        _run(prepared, tmp_path / "resumed", cfg, model_cfg, model_seed=0, stop_after=stop_after)
    assert [c.name for c in (tmp_path / "resumed" / "checkpoints").iterdir()] == [f"step_{stop_after:07d}"]
    resumed = _run(prepared, tmp_path / "resumed", cfg, model_cfg, model_seed=99, resume=True)  # another init
    assert resumed.step == STEPS

    want = load_file(str(tmp_path / "straight" / "model" / "model.safetensors"))
    got = load_file(str(tmp_path / "resumed" / "model" / "model.safetensors"))
    diff = max(float((got[k] - want[k]).abs().max()) for k in want)
    assert diff <= 1e-7, f"resumed weights differ by {diff:.3g}"
    losses = [r["loss"] for r in straight.history if "loss" in r]
    assert [r["loss"] for r in resumed.history if "loss" in r] == losses


# ---- window offsets: a pure function of (seed, epoch, item) ------------------------------------------------


def test_window_offsets_depend_on_seed_epoch_and_item_only(prepared):
    def windows(seed=0):
        return WindowDataset(prepared, "train", window=20, stride=5, random_offset=True, seed=seed)

    a, b = windows(), windows()
    n = len(a)
    first = [a[k]["music"] for k in range(n)]
    for k in reversed(range(n)):  # another order, another object: the same windows
        torch.testing.assert_close(b[k]["music"], first[k], rtol=0, atol=0)
    assert a.offset(-1 % n) == a.offset(n - 1)
    offsets = [a.offset(k) for k in range(n)]
    assert all(0 <= o < 5 for o in offsets) and len(set(offsets)) > 1
    a.set_epoch(1)
    assert [a.offset(k) for k in range(n)] != offsets
    a.set_epoch(0)
    assert [a.offset(k) for k in range(n)] == offsets
    assert [windows(seed=1).offset(k) for k in range(n)] != offsets
    assert windows().offset(3) == offsets[3]  # no state advances with reading
    plain = WindowDataset(prepared, "train", window=20, stride=5, stats=a.stats)
    assert {plain.offset(k) for k in range(n)} == {0}
    with pytest.raises(ParameterError, match="epoch"):
        a.set_epoch(-1)
    with pytest.raises(ParameterError, match="seed"):
        windows(seed=-1)


# ---- settings: the split, the checkpoints' saved dicts ----------------------------------------------------


def test_train_config_is_the_generic_and_the_per_family_settings():
    optim = {f.name for f in dataclasses.fields(OptimConfig)}
    data = {f.name for f in dataclasses.fields(DataConfig)}
    assert not optim & data and {f.name for f in dataclasses.fields(TrainConfig)} == optim | data
    assert {"lr", "steps", "seed", "ckpt_every", "device"} <= optim
    assert {"seq_len", "random_offset", "curriculum", "music_dropout"} <= data
    c = TrainConfig(lr=3e-4, seq_len=120, curriculum="const")
    assert c.optim() == OptimConfig(lr=3e-4) and c.data() == DataConfig(seq_len=120, curriculum="const")
    with pytest.raises(ParameterError, match="OptimConfig.ckpt_every"):
        OptimConfig(ckpt_every=0)
    with pytest.raises(ParameterError, match="TrainConfig.seq_len"):
        TrainConfig(seq_len=0)
    with pytest.raises(ParameterError, match="seed"):
        TrainConfig(seed=-3)


@pytest.mark.parametrize("path", sorted(ASSETS.glob("**/config.json")), ids=lambda p: str(p.relative_to(ASSETS)))
def test_the_embedded_checkpoints_training_settings_load(path):
    meta = json.loads(path.read_text())
    # a checkpoint composed of trained heads (the contact-gated foot model) records each head's training
    trains = [meta["train"]] if "train" in meta else [h["train"] for h in meta["heads"].values()]
    assert trains
    for saved in trains:
        config = TrainConfig.from_saved(saved, source=path, defaults={"balance_genres": True})
        assert {k: getattr(config, k) for k in saved} == saved
        if "balance_genres" not in saved:  # older than the field: the family default fills it
            assert config.balance_genres is True
        with pytest.raises(CheckpointError, match="n_experts"):
            TrainConfig.from_saved({**saved, "n_experts": 3}, source=path)


# ---- the trainer's steps and hooks ------------------------------------------------------------------------


class _Windows(torch.utils.data.Dataset):
    def __init__(self, n: int = 16):
        g = torch.Generator().manual_seed(0)
        self.music = torch.randn(n, 12, D, generator=g)
        self.dance = torch.tanh(self.music[..., :6])

    def __len__(self) -> int:
        return len(self.music)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"music": self.music[i], "dance": self.dance[i]}


def _tiny_model() -> RevolutionModel:
    torch.manual_seed(0)
    return RevolutionModel(RevolutionConfig(music_dim=D, pose_dim=6, d_model=16, n_heads=2, d_ff=32, window=6,
                                            decoder_hidden=16))


def test_trainer_steps_one_by_one_like_fit(tmp_path):
    cfg = TrainConfig(steps=4, batch_size=4, log_every=2, val_every=100, ckpt_every=2, threads=1, seq_len=12)
    fitted = Trainer(_tiny_model(), _Windows(), None, cfg, step_fn=revolution_step, out_dir=tmp_path / "fit",
                     progress=False).fit()

    trainer = Trainer(_tiny_model(), _Windows(), None, cfg, step_fn=revolution_step, out_dir=tmp_path / "manual",
                      progress=False)
    trainer.build()
    losses = [trainer.step(batch, epoch=0)["loss"] for batch in trainer.epoch_loader(0)]
    assert trainer.global_step == 4 == trainer.steps_per_epoch
    assert [r["loss"] for r in fitted.history] == [sum(losses[:2]) / 2, sum(losses[2:]) / 2]
    assert trainer.save_checkpoint() == tmp_path / "manual" / "checkpoints" / "step_0000004"
    want = load_file(str(tmp_path / "fit" / "model" / "model.safetensors"))
    got = load_file(str(tmp_path / "manual" / "model" / "model.safetensors"))
    assert all(torch.equal(got[k], want[k]) for k in want)

    again = Trainer(_tiny_model(), _Windows(), None, cfg, step_fn=revolution_step, out_dir=tmp_path / "manual",
                    progress=False)
    assert again.resume() == tmp_path / "manual" / "checkpoints" / "step_0000004" and again.global_step == 4


def test_data_parallel_hooks_shard_batches_and_keep_other_processes_from_writing(tmp_path):
    seen = []

    class SecondRankOfTwo(Trainer):
        is_main_process = False

        def shard_batch(self, indices):
            seen.append(indices)
            return indices[1::2]

    cfg = TrainConfig(steps=4, batch_size=4, log_every=1, val_every=2, ckpt_every=2, threads=1, seq_len=12)
    result = SecondRankOfTwo(_tiny_model(), _Windows(), _Windows(4), cfg, step_fn=revolution_step,
                             out_dir=tmp_path, progress=False).fit()
    assert result.step == 4 and len(seen) == 4 and all(len(b) == 4 for b in seen)
    assert sorted(i for b in seen for i in b) == list(range(16))  # one epoch: every item once, in global batches
    assert list(tmp_path.iterdir()) == [] and checkpoints(tmp_path) == []  # no log, no checkpoint, no best/


# ---- assembling a run (`dancekit train`) -------------------------------------------------------------------


def test_assemble_run_merges_family_defaults_checkpoint_and_sets(tmp_path, rng):
    data_dir = write_fake_prepared(tmp_path / "prepared", rng, preset="music2dance", dim=15)
    out = tmp_path / "run"
    sets = ["seq_len=40", "batch_size=2", "threads=1", "steps=2", "channels=8,8,8", "ckpt_every=2", "val_every=2"]
    run = assemble_run("music_attributes", data_dir, out, sets=sets)
    assert run.config.balance_genres is True and run.config.steps == 2  # family default, --set
    assert (run.model.config.music_dim, run.model.config.window, run.model.config.n_classes) == (15, 40, 4)
    assert run.summary_lines()[0].startswith("music_attributes: ") and run.resumed_from is None
    assert run.meta["preset"] == "music2dance" and run.meta["init"] is None
    assert run.fit(progress=False).step == 2

    more = assemble_run("music_attributes", data_dir, out, sets=["steps=3"], resume=True)
    assert more.resumed_from == out / "checkpoints" / "step_0000002"
    assert more.config.steps == 3 and more.config.seq_len == 40 and more.model.config.channels == (8, 8, 8)
    assert more.fit(progress=False).step == 3
    with pytest.raises(ParameterError, match="music_attributes"):
        assemble_run("revolution", data_dir, out, resume=True)
    with pytest.raises(ParameterError, match="window=50"):
        assemble_run("music_attributes", data_dir, tmp_path / "other", sets=["seq_len=40", "window=50"])


@pytest.mark.parametrize("family,setting", [("music2dance", "augment_tempo=0.1"), ("foot_constraint", "augment_heading=true"),
                                            ("style", "augment_mirror=0.5")])
def test_an_augmentation_a_family_would_not_apply_is_refused(tmp_path, rng, family, setting):
    """The windows of music2dance, the Foot Constraint Model and the style classifier take no augmentation:
    asking for one is an error that names it, not a run without it."""
    data_dir = write_fake_prepared(tmp_path / "prepared", rng, preset="music2dance", dim=15)
    out = tmp_path / "run"
    with pytest.raises(ParameterError, match=setting.split("=")[0]):
        assemble_run(family, data_dir, out, sets=[setting, "seq_len=40", "steps=1", "threads=1"]).fit(progress=False)
    assert not (out / "checkpoints").exists()
