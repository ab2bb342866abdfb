"""Training: schedules, checkpoints, the generic loop (resume), objectives, `dancekit train`, the pipeline."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
import torch
from _prepared import write_fake_prepared
from safetensors.torch import load_file

from dancekit.checkpoints import load_pretrained, save_pretrained
from dancekit.cli.main import main
from dancekit.cli.train import parse_sets
from dancekit.errors import AudioError, CheckpointError, ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel
from dancekit.training import (
    StepContext,
    TrainConfig,
    auto_condition_p,
    checkpoints,
    learning_rate,
    revolution_step,
    train,
)

D, P = 8, 6


def tiny(**kw) -> RevolutionConfig:
    base = dict(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32, window=6, decoder_hidden=24, dropout=0.1)
    return RevolutionConfig(**{**base, **kw})


class Windows(torch.utils.data.Dataset):
    """Synthetic paired windows: the dance is a smooth function of the music."""

    def __init__(self, n: int = 48, length: int = 24, seed: int = 0):
        g = torch.Generator().manual_seed(seed)
        self.music = torch.randn(n, length, D, generator=g)
        self.dance = torch.tanh(torch.cumsum(self.music[..., :P], dim=1) * 0.3)

    def __len__(self) -> int:
        return len(self.music)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"music": self.music[i], "dance": self.dance[i]}


def quick_config(**kw) -> TrainConfig:
    base = dict(steps=12, batch_size=8, lr=3e-3, warmup_steps=2, log_every=2, val_every=6, ckpt_every=6,
                threads=1, seq_len=24, curriculum_lambda=1.0, curriculum_q=3)
    return TrainConfig(**{**base, **kw})


# ---- schedules ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind,epochs,expected",
    [
        ("teacher_forcing", [0, 5, 100], [0, 0, 0]),
        ("const", [0, 5, 100], [10, 10, 10]),
        ("linear", [0, 3, 4, 10, 101], [0, 0, 1, 2, 25]),  # ⌊0.25 t⌋
        ("quadratic", [0, 1, 2, 3, 7], [0, 0, 1, 2, 12]),  # ⌊0.25 t²⌋
        ("exponential", [0, 1, 2, 3, 4], [0, 0, 1, 5, 13]),  # ⌊0.25 eᵗ⌋
    ],
)
def test_auto_condition_p_known_values(kind, epochs, expected):
    assert [auto_condition_p(t, kind=kind, lam=0.25, p_const=10) for t in epochs] == expected


def test_auto_condition_p_is_clipped_and_survives_huge_epochs():
    assert auto_condition_p(10**6, kind="exponential", lam=0.01, p_max=40) == 40
    assert auto_condition_p(10**6, kind="linear", lam=0.01, p_max=40) == 40
    assert auto_condition_p(30, kind="linear", lam=0.1) == 3  # 0.1 * 30 in floating point is 3.0000000000000004
    assert auto_condition_p(10, kind="const", p_const=12, p_max=8) == 8


@pytest.mark.parametrize("kw,match", [({"kind": "cosine"}, "cosine"), ({"lam": -1.0}, "lambda"), ({"p_max": -1}, "p_max")])
def test_auto_condition_p_bad_values(kw, match):
    with pytest.raises(ParameterError, match=match):
        auto_condition_p(3, **kw)
    with pytest.raises(ParameterError, match="epoch"):
        auto_condition_p(-1)


def test_learning_rate_warmup_cosine_constant():
    kw = dict(base_lr=1e-3, total_steps=110, warmup_steps=10, min_lr=1e-5)
    assert learning_rate(0, **kw) == pytest.approx(1e-4)
    assert learning_rate(9, **kw) == pytest.approx(1e-3)
    assert learning_rate(10, **kw) == pytest.approx(1e-3)
    assert learning_rate(60, **kw) == pytest.approx(1e-5 + 0.5 * (1e-3 - 1e-5))  # half way down the cosine
    assert learning_rate(110, **kw) == pytest.approx(1e-5)
    assert learning_rate(500, **kw) == pytest.approx(1e-5)
    assert learning_rate(60, **{**kw, "kind": "constant"}) == 1e-3
    with pytest.raises(ParameterError, match="linear"):
        learning_rate(0, base_lr=1e-3, total_steps=10, kind="linear")


# ---- checkpoints -----------------------------------------------------------------------------------


def _stats():
    return {"music_mean": np.arange(D, dtype=np.float32), "music_std": np.ones(D, np.float32),
            "dance_mean": np.zeros(P, np.float32), "dance_std": np.full(P, 2.0, np.float32)}


def test_save_load_round_trip_gives_identical_outputs(tmp_path):
    torch.manual_seed(0)
    model = RevolutionModel(tiny(encoder="conv", bop="zero"))
    folder = save_pretrained(tmp_path / "ckpt", model, model.config, stats=_stats(),
                             extra={"fps": 25.0, "representation": "positions3d"})
    assert sorted(p.name for p in folder.iterdir()) == ["config.json", "model.safetensors", "stats.npz"]
    loaded, meta, stats = load_pretrained(folder)
    assert isinstance(loaded, RevolutionModel) and not loaded.training
    assert loaded.config == model.config
    assert meta["model"] == "revolution" and meta["fps"] == 25.0
    np.testing.assert_array_equal(stats["music_mean"], _stats()["music_mean"])
    music = torch.randn(1, 20, D)
    a = model.eval().generate(music, generator=torch.Generator().manual_seed(4))
    b = loaded.generate(music, generator=torch.Generator().manual_seed(4))
    torch.testing.assert_close(a, b, rtol=0, atol=0)


def test_load_errors_name_the_folder(tmp_path):
    with pytest.raises(CheckpointError, match="nowhere"):
        load_pretrained(tmp_path / "nowhere")
    model = RevolutionModel(tiny())
    folder = save_pretrained(tmp_path / "ck", model, model.config, stats=_stats())

    broken = tmp_path / "no_weights"
    shutil.copytree(folder, broken)
    (broken / "model.safetensors").unlink()
    with pytest.raises(CheckpointError, match="no_weights"):
        load_pretrained(broken)

    corrupt = tmp_path / "corrupt"
    shutil.copytree(folder, corrupt)
    (corrupt / "model.safetensors").write_bytes(b"not a safetensors file")
    with pytest.raises(CheckpointError, match="corrupt"):
        load_pretrained(corrupt)

    bad_json = tmp_path / "bad_json"
    shutil.copytree(folder, bad_json)
    (bad_json / "config.json").write_text("{")
    with pytest.raises(CheckpointError, match="bad_json"):
        load_pretrained(bad_json)

    unknown = tmp_path / "unknown_key"
    shutil.copytree(folder, unknown)
    doc = json.loads((unknown / "config.json").read_text())
    doc["config"]["n_experts"] = 4
    (unknown / "config.json").write_text(json.dumps(doc))
    with pytest.raises(CheckpointError, match="n_experts"):
        load_pretrained(unknown)

    mismatch = tmp_path / "mismatch"
    shutil.copytree(folder, mismatch)
    doc = json.loads((mismatch / "config.json").read_text())
    doc["config"]["decoder_hidden"] = 32
    (mismatch / "config.json").write_text(json.dumps(doc))
    with pytest.raises(CheckpointError, match="do not match"):
        load_pretrained(mismatch)


# ---- the loop ---------------------------------------------------------------------------------------


def test_training_reduces_the_loss_and_writes_checkpoints(tmp_path):
    torch.manual_seed(0)
    model = RevolutionModel(tiny())
    cfg = quick_config(steps=40, log_every=5, val_every=20, ckpt_every=20)
    result = train(model, Windows(), Windows(16, seed=1), cfg, step_fn=revolution_step, out_dir=tmp_path,
                   stats=_stats(), meta={"fps": 25.0}, progress=False)
    losses = [r["loss"] for r in result.history if "loss" in r]
    assert result.step == 40 and len(losses) == 8
    assert losses[-1] < 0.8 * losses[0]
    assert result.val_loss is not None and result.best_val_loss <= result.val_loss
    assert [c.name for c in checkpoints(tmp_path)] == ["step_0000020", "step_0000040"]
    # 48 windows / batch 8 = 6 steps per epoch: step 40 ran in epoch 39 // 6 = 6, so p = ⌊1.0 · 6⌋
    assert [r["p"] for r in result.history if "loss" in r][-1] == 6
    for name in ("model", "best"):
        loaded, meta, _ = load_pretrained(tmp_path / name)
        assert meta["train"]["steps"] == 40 and meta["fps"] == 25.0
    assert len((tmp_path / "log.jsonl").read_text().splitlines()) == len(result.history)


def test_resume_continues_from_the_saved_step_exactly(tmp_path):
    cfg = quick_config()
    torch.manual_seed(0)
    straight = train(RevolutionModel(tiny()), Windows(), Windows(8, seed=1), cfg, step_fn=revolution_step,
                     out_dir=tmp_path, progress=False)
    final = load_file(str(tmp_path / "checkpoints" / "step_0000012" / "model.safetensors"))
    shutil.rmtree(tmp_path / "checkpoints" / "step_0000012")  # as if interrupted after the step-6 checkpoint

    torch.manual_seed(99)  # another fresh model: resumption must restore everything
    resumed = train(RevolutionModel(tiny()), Windows(), Windows(8, seed=1), cfg, step_fn=revolution_step,
                    out_dir=tmp_path, resume=True, progress=False)
    assert resumed.step == 12
    assert [r["step"] for r in resumed.history if "loss" in r] == [2, 4, 6, 8, 10, 12]
    again = load_file(str(tmp_path / "checkpoints" / "step_0000012" / "model.safetensors"))
    for k in final:
        torch.testing.assert_close(again[k], final[k], rtol=0, atol=0)
    assert [r["loss"] for r in resumed.history if "loss" in r] == [r["loss"] for r in straight.history if "loss" in r]


def test_resume_without_checkpoint_starts_fresh_and_mismatch_is_named(tmp_path):
    cfg = quick_config(steps=2, ckpt_every=2, val_every=100)
    r = train(RevolutionModel(tiny()), Windows(), None, cfg, step_fn=revolution_step, out_dir=tmp_path,
              resume=True, progress=False)
    assert r.step == 2 and r.val_loss is None
    with pytest.raises(CheckpointError, match="decoder_hidden"):
        train(RevolutionModel(tiny(decoder_hidden=32)), Windows(), None, quick_config(steps=4), step_fn=revolution_step,
              out_dir=tmp_path, resume=True, progress=False)


def test_epochs_length_in_steps(tmp_path):
    cfg = quick_config(epochs=2, val_every=100, ckpt_every=100)
    r = train(RevolutionModel(tiny()), Windows(n=20), None, cfg, step_fn=revolution_step, out_dir=tmp_path,
              progress=False)
    assert r.step == 2 * (20 // 8) and r.epoch == 2


@pytest.mark.parametrize("optimizer,first_step", [("adamw", 1.0), ("rmsprop", 10.0)])
def test_optimizer_setting_picks_the_update_rule(tmp_path, optimizer, first_step):
    """Known first updates from a zero state, no weight decay, no clipping: AdamW moves every weight by
    lr · g / |g| (bias-corrected m / √v); RMSprop (α = 0.99) by lr · g / √(0.01 g²) = 10 · lr · sign(g)."""
    from dancekit.training import Trainer

    lr = 1e-3
    cfg = quick_config(steps=1, optimizer=optimizer, lr=lr, warmup_steps=0, grad_clip=None, val_every=100,
                       ckpt_every=100)
    torch.manual_seed(0)
    model = RevolutionModel(tiny(dropout=0.0))
    trainer = Trainer(model, Windows(n=8), None, cfg, step_fn=revolution_step, out_dir=tmp_path, progress=False)
    trainer.build()
    assert type(trainer.optimizer).__name__ == {"adamw": "AdamW", "rmsprop": "RMSprop"}[optimizer]
    before = {k: v.detach().clone() for k, v in model.named_parameters()}
    trainer.step(next(iter(trainer.epoch_loader(0))), epoch=0)
    moved = torch.cat([(p.detach() - before[k]).abs()[p.grad.abs() > 1e-3] for k, p in model.named_parameters()
                       if p.grad is not None])  # gradients far above the optimisers' eps (1e-8)
    assert moved.numel() > 100
    torch.testing.assert_close(moved, torch.full_like(moved, first_step * lr), rtol=2e-3, atol=0)


@pytest.mark.parametrize("kw,match", [({"steps": 0}, "steps"), ({"lr": 0.0}, "lr"), ({"curriculum": "sigmoid"}, "curriculum"),
                                      ({"lr_schedule": "step"}, "lr_schedule"), ({"stride": 0}, "stride"),
                                      ({"optimizer": "sgd"}, "optimizer")])
def test_train_config_errors_name_the_field(kw, match):
    with pytest.raises(ParameterError, match=match):
        TrainConfig(**kw)


def test_nan_loss_stops_training(tmp_path):
    def bad_step(model, batch, ctx):
        _, loss = model(batch["music"], batch["dance"])
        return loss * float("nan"), {}

    with pytest.raises(FloatingPointError, match="step 0"):
        train(RevolutionModel(tiny()), Windows(), None, quick_config(), step_fn=bad_step, out_dir=tmp_path,
              progress=False)


def test_baseline_objective_uses_teacher_forcing():
    cfg = quick_config(curriculum="const", curriculum_p=5)
    ctx = StepContext(step=0, epoch=3, training=True, generator=torch.Generator(), config=cfg)
    batch = Windows(4)[0]
    batch = {k: v[None] for k, v in batch.items()}
    _, logs = revolution_step(RevolutionModel(tiny()), batch, ctx)
    assert logs["p"] == 5
    base = RevolutionModel(RevolutionConfig.lstm_baseline(music_dim=D, pose_dim=P, d_model=16, n_heads=2))
    loss, logs = revolution_step(base, batch, ctx)
    assert logs["p"] == 0 and math.isfinite(float(loss.detach()))


def test_music_dropout_zeroes_whole_windows_in_training_only():
    seen = []

    class Spy(RevolutionModel):
        def forward(self, music, dance, **kw):
            seen.append(music.clone())
            return super().forward(music, dance, **kw)

    music = torch.randn(64, 6, D, generator=torch.Generator().manual_seed(0)) + 3.0  # no window is all zeros
    batch = {"music": music, "dance": torch.randn(64, 6, P)}
    model = Spy(tiny())
    for training, share in [(True, 0.5), (True, 0.0), (False, 1.0)]:
        cfg = quick_config(music_dropout=share)
        revolution_step(model, batch, StepContext(step=0, epoch=0, training=training,
                                                  generator=torch.Generator().manual_seed(1), config=cfg))
    dropped = (seen[0] == 0).all(dim=(1, 2))
    kept = (seen[0] == music).all(dim=(1, 2))
    assert bool((dropped | kept).all()) and 16 < int(dropped.sum()) < 48  # whole windows, about half
    torch.testing.assert_close(seen[1], music)  # no dropout asked
    torch.testing.assert_close(seen[2], music)  # validation never drops
    with pytest.raises(ParameterError, match="music_dropout"):
        TrainConfig(music_dropout=1.5)


# ---- `dancekit train` ----------------------------------------------------------------------------------


def test_parse_sets_types_and_errors():
    model_sets, train_sets = parse_sets(
        ["d_model=64", "encoder=global", "condition_on_music=false", "lr=3e-4", "curriculum_p_max=none",
         "train.seq_len=120"],
        RevolutionConfig, TrainConfig,
    )
    assert model_sets == {"d_model": 64, "encoder": "global", "condition_on_music": False}
    assert train_sets == {"lr": 3e-4, "curriculum_p_max": None, "seq_len": 120}
    with pytest.raises(ParameterError, match="'n_expertz'"):
        parse_sets(["n_expertz=3"], RevolutionConfig, TrainConfig)
    with pytest.raises(ParameterError, match="steps=many"):
        parse_sets(["steps=many"], RevolutionConfig, TrainConfig)
    with pytest.raises(ParameterError, match="KEY=VALUE"):
        parse_sets(["steps"], RevolutionConfig, TrainConfig)
    with pytest.raises(ParameterError, match="model.seq_len"):
        parse_sets(["model.seq_len=3"], RevolutionConfig, TrainConfig)
    assert parse_sets(["genres=rumba, chacha"], RevolutionConfig, TrainConfig)[1] == {"genres": ["rumba", "chacha"]}
    assert parse_sets(["genres=none"], RevolutionConfig, TrainConfig)[1] == {"genres": None}
    with pytest.raises(ParameterError, match="genres"):
        TrainConfig(genres=[])


@pytest.fixture
def fake_prepared(tmp_path, rng):
    """A tiny prepared dataset (random motion, random 438-D features) in the layout of `dancekit prepare`."""
    return write_fake_prepared(tmp_path / "prepared", rng)


def test_train_cli_end_to_end_and_resume(fake_prepared, tmp_path, capsys):
    out = tmp_path / "run"
    args = ["train", "revolution", "--data", str(fake_prepared), "--out", str(out), "--quiet",
            "--set", "d_model=16", "--set", "n_heads=2", "--set", "d_ff=32", "--set", "decoder_hidden=16",
            "--set", "seq_len=40", "--set", "batch_size=2", "--set", "steps=3", "--set", "ckpt_every=3",
            "--set", "val_every=3", "--set", "threads=1"]
    assert main(args) == 0
    assert "trained revolution to step 3" in capsys.readouterr().out
    model, meta, stats = load_pretrained(out / "model")
    assert model.config.music_dim == 438 and model.config.pose_dim == 72 and model.config.d_model == 16
    assert meta["preset"] == "revolution" and meta["representation"] == "positions3d" and meta["fps"] == 25.0
    assert meta["train"]["seq_len"] == 40 and stats["dance_std"].shape == (72,)
    # the real dances' per-genre tables the stages compare with (dancekit.training.genre_stats), from the train split
    from dancekit.data import PreparedData
    from dancekit.pipelines import load_pipeline
    from dancekit.training.genre_stats import prepared_genre_stats

    tables = prepared_genre_stats(PreparedData(fake_prepared), "train")
    assert meta["genre_stats"]["jitter"] == tables["jitter"] and meta["genre_stats"]["energy"] == tables["energy"]
    assert load_pipeline(out / "model").settings.stages.genre_stats.table("jitter") == tables["jitter"]
    # resume reads the configuration back from the checkpoint; only the new length is given
    assert main(["train", "revolution", "--data", str(fake_prepared), "--out", str(out), "--quiet", "--resume",
                 "--set", "steps=5"]) == 0
    assert "to step 5" in capsys.readouterr().out
    assert main(["train", "revolution", "--data", str(fake_prepared), "--out", str(out), "--set", "dmodel=3"]) == 2
    assert "'dmodel'" in capsys.readouterr().err


# ---- the pipeline --------------------------------------------------------------------------------------


@pytest.fixture
def tiny_checkpoint(tmp_path):
    from dancekit.motion import get_skeleton

    torch.manual_seed(0)
    model = RevolutionModel(RevolutionConfig(d_model=16, n_heads=2, d_ff=32, decoder_hidden=16))
    stats = {"music_mean": np.zeros(438, np.float32), "music_std": np.ones(438, np.float32),
             "dance_mean": np.zeros(72, np.float32), "dance_std": np.full(72, 10.0, np.float32)}
    meta = {"fps": 25.0, "preset": "revolution", "representation": "positions3d", "hop_length": 512,
            "skeleton": get_skeleton("tang2018").to_dict()}
    return save_pretrained(tmp_path / "ckpt", model, model.config, stats=stats, extra=meta)


@pytest.fixture
def click_wav(tmp_path):
    import soundfile as sf

    sr = 22050
    y = np.zeros(int(3.0 * sr), np.float32)
    for t in np.arange(0.25, 3.0, 0.5):  # 120 BPM clicks
        i = int(t * sr)
        y[i : i + 200] = np.hanning(200) * 0.8
    path = tmp_path / "clicks.wav"
    sf.write(path, y, sr)
    return path


def test_pipeline_dances_a_song_deterministically(tiny_checkpoint, click_wav):
    from dancekit.pipelines import RevolutionPipeline

    pipe = RevolutionPipeline.from_pretrained(tiny_checkpoint)
    motion = pipe(click_wav, seed=0).motion
    expected_frames = 1 + int(np.ceil(3.0 * 25 * 512)) // 512  # features at sr = fps * hop_length
    assert motion.fps == 25.0 and motion.num_frames == expected_frames
    assert motion.positions.shape == (expected_frames, 23, 3) and np.isfinite(motion.positions).all()
    again = pipe(click_wav, seed=0).motion
    other = pipe(click_wav, seed=1).motion
    np.testing.assert_array_equal(motion.positions, again.positions)
    assert np.abs(motion.positions - other.positions).mean() > 1e-3
    excerpt = pipe(click_wav, seed=0, start=1.0, end=2.0).motion
    assert excerpt.num_frames == 26


def test_pipeline_errors(tiny_checkpoint, tmp_path, click_wav):
    from dancekit.pipelines import RevolutionPipeline

    pipe = RevolutionPipeline.from_pretrained(tiny_checkpoint)
    with pytest.raises(AudioError):
        pipe(tmp_path / "missing.wav")
    with pytest.raises(ParameterError, match="waltz"):
        pipe(click_wav, genre="waltz")
    with pytest.raises(CheckpointError, match="empty"):
        RevolutionPipeline.from_pretrained(tmp_path / "empty")


def test_validation_uses_the_fixed_val_p():
    cfg = quick_config(curriculum="const", curriculum_p=5, val_p=7)
    batch = {k: v[None] for k, v in Windows(4)[0].items()}
    for training, expected in ((True, 5), (False, 7)):
        ctx = StepContext(step=0, epoch=3, training=training, generator=torch.Generator(), config=cfg)
        assert revolution_step(RevolutionModel(tiny()), batch, ctx)[1]["p"] == expected
