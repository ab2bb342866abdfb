"""A fourth dance family defined here, in the test file: what docs/ARCHITECTURE.md ("Adding a dance family") says
a new family touches is all it takes for `load_pipeline` and `dancekit dance --model FOLDER` to dance with it.

The places this file touches, as the list in docs/ARCHITECTURE.md: (1) a ``@dataclass`` config and an
``nn.Module(config)`` (:class:`TinyConfig`, :class:`TinyModel`), (2) a :class:`~dancekit.pipelines.dance.DancePipeline`
subclass that writes its generation step (:class:`TinyPipeline`), (3) one :func:`dancekit.registry.register`
entry. Nothing in src/ is edited."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from dancekit import registry
from dancekit.cli.main import main
from dancekit.motion import Motion
from dancekit.pipelines.dance import DancePipeline

MODULE = __name__  # the registry's entries are "module:name" strings of this test module


@dataclass
class TinyConfig:
    """(1) The family's config: the music features in, the pose vector out (positions3d on tang2018: 72)."""

    music_dim: int = 0
    pose_dim: int = 72


class TinyModel(nn.Module):
    """(1) A few-parameter model: each pose vector is a linear map of the frame's music features."""

    family = "tiny"

    def __init__(self, config: TinyConfig):
        super().__init__()
        self.config = config
        self.proj = nn.Linear(config.music_dim, config.pose_dim)


class TinyPipeline(DancePipeline):
    """(2) The family's pipeline: its generation step only (features → linear map + a seed's offset → poses)."""

    family = "tiny"

    def generate_batch(self, audio_path, *, seeds, choices, start=None, end=None, progress=False, spread=0.3):
        from dancekit.motion.representations import decode_motion
        from dancekit.pipelines.base import clean_motion

        x = torch.from_numpy(self.features(audio_path, start=start, end=end))  # (T, music_dim)
        out = []
        for seed in seeds:
            g = torch.Generator().manual_seed(int(seed))
            y = self.model.proj(x) + spread * torch.randn(self.model.config.pose_dim, generator=g)  # (T, pose_dim)
            poses = self.stats.denormalize_dance(y.detach().numpy())
            out.append(clean_motion(decode_motion(poses, self.skeleton, self.fps, "positions3d")))
        return out


@pytest.fixture
def tiny_family():
    """(3) The registry entry (removed again after the test)."""
    fam = registry.register(registry.Family(
        name="tiny", config=f"{MODULE}:TinyConfig", module=f"{MODULE}:TinyModel",
        objective=f"{MODULE}:untrainable", dataset=f"{MODULE}:untrainable", pipeline=f"{MODULE}:TinyPipeline",
        preset="revolution", description="a test family: one linear map"))
    yield fam
    registry.unregister("tiny")


@pytest.fixture
def tiny_checkpoint(tiny_family, tmp_path):
    """A checkpoint folder of the tiny family on the tang2018 skeleton, with the statistics of the real data's
    scale (so the dance is a person-sized figure) and a stage configuration of its own."""
    from dancekit.checkpoints import save_pretrained
    from dancekit.features import PRESET_DIMS
    from dancekit.motion import get_skeleton

    sk = get_skeleton("tang2018")
    config = TinyConfig(music_dim=PRESET_DIMS["revolution"])
    torch.manual_seed(0)
    model = TinyModel(config)
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    dance_mean = np.concatenate([(rest - rest[sk.root]).reshape(-1), [0.0, 0.0, 90.0]]).astype(np.float32)
    stats = {"music_mean": np.zeros(config.music_dim, np.float32), "music_std": np.ones(config.music_dim, np.float32),
             "dance_mean": dance_mean, "dance_std": np.full(72, 2.0, np.float32)}
    folder = tmp_path / "tiny"
    save_pretrained(folder, model, config, stats=stats,
                    extra={"representation": "positions3d", "preset": "revolution", "fps": 25.0, "hop_length": 512,
                           "skeleton": sk.to_dict(), "genres": [],
                           "stages": {"settle": {"cutoff_hz": 3.0}, "beat_sync": {"max_rate_change": 0.2}}})
    return folder


@pytest.fixture
def song(tmp_path):
    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy

    path = tmp_path / "ode.wav"
    save_wav(path, ode_to_joy(sr=22050, bpm=120)[: 4 * 22050], sr=22050)
    return path


def test_a_fourth_family_dances_through_load_pipeline_and_the_cli(tiny_checkpoint, song, tmp_path):
    from dancekit.motion import read_motion
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline(tiny_checkpoint)
    assert isinstance(pipe, TinyPipeline) and pipe.settings.stages.settle.cutoff_hz == 3.0
    results = pipe.dances(song, seeds=[0, 1])
    m = results[0].motion
    assert isinstance(m, Motion) and m.num_frames == 1 + (4 * 25 * 512) // 512 and m.fps == 25.0
    assert np.abs(results[0].motion.positions - results[1].motion.positions).max() > 1.0  # seeds differ
    np.testing.assert_array_equal(pipe(song, seed=1).motion.positions, results[1].motion.positions)
    assert results[0].model == str(tiny_checkpoint) and "beat-synced" in results[0].summary()
    raw = pipe.dances(song, seeds=[0], beat_sync=False, cleanup=False)[0]
    assert not np.array_equal(raw.motion.positions, m.positions)  # the stages ran on it
    # the family's own option reaches its generation step through dances() and __call__; another is refused
    still = pipe(song, seed=0, spread=0.0, beat_sync=False, cleanup=False).motion.positions
    assert not np.array_equal(still, raw.motion.positions)
    np.testing.assert_array_equal(still, pipe(song, seed=1, spread=0.0, beat_sync=False, cleanup=False).motion.positions)
    with pytest.raises(TypeError, match="temperature"):
        pipe(song, seed=0, temperature=1.0)
    assert load_pipeline(tiny_checkpoint, precision="fp32").precision == "fp32"
    out = tmp_path / "out"
    assert main(["dance", str(song), "-o", str(out), "--model", str(tiny_checkpoint), "--quiet", "--format", "npz",
                 "--seeds", "0-1"]) == 0
    for k in (0, 1):
        np.testing.assert_array_equal(read_motion(out / f"ode_seed{k}.npz").positions, results[k].motion.positions)


def test_the_fourth_familys_settings_are_checked_like_the_others(tiny_checkpoint, song, tmp_path, capsys):
    import json

    meta = json.loads((tiny_checkpoint / "config.json").read_text())
    meta["stages"]["settle"]["cutoff_hz"] = "3"
    (tiny_checkpoint / "config.json").write_text(json.dumps(meta))
    out = tmp_path / "bad"
    assert main(["dance", str(song), "-o", str(out), "--model", str(tiny_checkpoint), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "stages.settle.cutoff_hz" in err and str(tiny_checkpoint) in err
    assert not out.exists() or list(out.iterdir()) == []


def test_the_architecture_doc_lists_what_this_file_touches():
    """docs/ARCHITECTURE.md's list of the places a new dance family touches is the three this file needed."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "ARCHITECTURE.md").read_text()
    section = doc.split("### Adding a dance family", 1)[1].split("\n#", 1)[0]
    items = [" ".join(i.split()) for i in re.findall(r"^\d+\. (.+?)(?=^\d+\. |\Z)", section, flags=re.M | re.S)]
    assert len(items) == 3, items
    assert "config" in items[0] and "nn.Module" in items[0]
    assert "DancePipeline" in items[1] and "generate_batch" in items[1]
    assert "registry" in items[2] and "register" in items[2]
