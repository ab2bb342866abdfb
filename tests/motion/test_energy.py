"""The energy stage (issues 14 and 15): a dance under its floor lifted towards it, nothing else changed.

Known answers: one joint swinging about a fixed axis by ``A sin(2π f t)`` moves its children at a speed
proportional to ``A`` (rotation about a fixed axis: speed = distance × angular speed), and its 2-s moving mean
over two whole periods of a 1-Hz swing is the rest pose, so the whole swing is the deviation and it lies in
the low band: the gain that brings the smoothed energy to ``floor`` is ``floor / energy`` and the swing's
amplitude becomes ``A × floor / energy``. The energies are measured with :func:`dancekit.metrics.smoothed_energy`
(not the stage's own copy).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from dancekit.metrics import smoothed_energy
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.energy import rotation_exp, rotation_log

FPS = 25.0


def _swing(amplitude: float, *, seconds: float = 30.0, hz: float = 1.0) -> Motion:
    """The tang2018 rest pose with the left shoulder swinging about the forward axis by ``amplitude`` rad."""
    from dancekit.motion.kinematics import rig_forward_kinematics

    sk = get_skeleton("tang2018")
    T = int(seconds * FPS)
    t = np.arange(T) / FPS
    rot = np.tile(np.eye(3), (T, sk.num_joints, 1, 1))
    angle = amplitude * np.sin(2 * np.pi * hz * t)
    rot[:, sk.index("left_shoulder")] = rotation_exp(angle[:, None] * np.array([0.0, 0.0, 1.0]))
    tr = np.tile([0.0, 100.0, 0.0], (T, 1))
    import torch

    pos = rig_forward_kinematics(torch.from_numpy(rot), torch.from_numpy(tr), sk).numpy()
    return Motion(skeleton=sk, fps=FPS, positions=pos.astype(np.float32), rotations=rot.astype(np.float32),
                  root_translation=tr.astype(np.float32))


def _result(motion: Motion, model: str = "synthetic"):
    from dancekit.pipelines import DanceResult

    return DanceResult(motion=motion, model=model, seed=0)


def _energy(motion: Motion) -> float:
    return smoothed_energy(np.asarray(motion.to_positions(), np.float64), fps=motion.fps, skeleton=motion.skeleton)


def test_rotation_log_inverts_exp_at_every_angle():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(2000, 3))
    w *= (rng.uniform(0, np.pi * 0.999, size=2000) / np.linalg.norm(w, axis=1))[:, None]
    w[:4] *= 1e-9
    r = rotation_exp(w)
    np.testing.assert_allclose(r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    np.testing.assert_allclose(rotation_log(r), w, atol=1e-9)


def test_a_calm_swing_gets_the_gain_that_brings_it_to_the_floor():
    from dancekit.pipelines import stages

    A = 0.2
    motion = _swing(A)
    e0 = _energy(motion)
    floor = 1.5 * e0
    out = stages.lift_energy(_result(motion), floor=floor, mean_s=2.0, band_hz=2.5, max_gain=3.0)
    assert out.notes[-1].startswith("energy lifted (gain 1.50")
    assert _energy(out.motion) == pytest.approx(floor, rel=0.01)
    sk = motion.skeleton
    angle = rotation_log(out.motion.rotations[:, sk.index("left_shoulder")].astype(np.float64))  # (T, 3)
    inner = slice(int(3 * FPS), -int(3 * FPS))  # away from the ends' padding
    assert np.abs(angle[inner, 2]).max() == pytest.approx(1.5 * A, rel=0.01)
    assert np.abs(angle[:, :2]).max() < 1e-5  # still about the same axis
    others = np.delete(out.motion.rotations, sk.index("left_shoulder"), axis=1)
    np.testing.assert_allclose(others, np.broadcast_to(np.eye(3), others.shape), atol=1e-6)
    # positions by forward kinematics: bone lengths exact, root where it was (lowest joint on the floor)
    p, q = np.asarray(out.motion.positions, np.float64), np.asarray(motion.positions, np.float64)
    for j, parent in enumerate(sk.parents):
        if parent >= 0:
            np.testing.assert_allclose(np.linalg.norm(p[:, j] - p[:, parent], axis=-1),
                                       np.linalg.norm(q[:, j] - q[:, parent], axis=-1), atol=1e-3)
    np.testing.assert_allclose(p[:, sk.root, [0, 2]], q[:, sk.root, [0, 2]], atol=1e-4)


def test_the_gain_stops_at_max_gain():
    from dancekit.pipelines import stages

    motion = _swing(0.1)
    out = stages.lift_energy(_result(motion), floor=4 * _energy(motion), mean_s=2.0, max_gain=2.0)
    assert out.notes[-1].startswith("energy lifted (gain 2.00")
    assert _energy(out.motion) == pytest.approx(2 * _energy(motion), rel=0.02)


def test_a_dance_at_or_above_the_floor_is_left_alone():
    from dancekit.pipelines import stages

    motion = _swing(0.3)
    res = _result(motion)
    assert stages.lift_energy(res, floor=0.9 * _energy(motion)) is res
    assert stages.lift_energy(res) is res  # no floor (no entry): no change


def test_positions_only_dance_keeps_bone_lengths_and_root():
    from dancekit.pipelines import stages

    rng = np.random.default_rng(1)
    swing = _swing(0.15)
    p = np.asarray(swing.positions, np.float64)
    p = p + rng.normal(scale=0.3, size=p.shape)  # per-frame bone lengths that vary, as a positions model's do
    motion = Motion(skeleton=swing.skeleton, fps=FPS, positions=p.astype(np.float32))
    out = stages.lift_energy(_result(motion), floor=1.4 * _energy(motion), max_gain=3.0)
    assert "energy lifted" in out.notes[-1]
    assert out.motion.rotations is None
    assert _energy(out.motion) == pytest.approx(1.4 * _energy(motion), rel=0.01)
    q = np.asarray(out.motion.positions, np.float64)
    sk = motion.skeleton
    for j, parent in enumerate(sk.parents):
        if parent >= 0:
            np.testing.assert_allclose(np.linalg.norm(q[:, j] - q[:, parent], axis=-1),
                                       np.linalg.norm(p[:, j] - p[:, parent], axis=-1), atol=1e-3)
    np.testing.assert_allclose(q[:, sk.root, [0, 2]], p[:, sk.root, [0, 2]], atol=1e-4)


def test_the_floor_follows_the_genres_read_from_the_music():
    from dancekit.pipelines import stages

    res = dataclasses.replace(_result(_swing(0.1)), genre_probs={"waltz": 0.5, "chacha": 0.25, "salsa": 0.25})
    table = {"waltz": 0.4, "chacha": 0.8}
    # salsa is not in the table: waltz and chacha renormalised to 2/3, 1/3
    assert stages.energy_floor(res, fraction=0.6, genre_energy=table) == pytest.approx(0.6 * (0.4 * 2 + 0.8) / 3)
    named = dataclasses.replace(res, genre_probs={}, genre="chacha")
    assert stages.energy_floor(named, fraction=0.5, genre_energy=table, floor=0.1) == pytest.approx(0.4)
    plain = dataclasses.replace(res, genre_probs={})
    assert stages.energy_floor(plain, fraction=0.5, genre_energy=table, floor=0.1) == 0.1
    assert stages.energy_floor(plain, fraction=0.5, genre_energy=table) is None


def _checkpoint(tmp_path, entry, name="m"):
    folder = tmp_path / name
    folder.mkdir(exist_ok=True)
    (folder / "config.json").write_text(json.dumps({"model": "dual", **({"energy": entry} if entry else {})}))
    return str(folder)


def test_finish_without_an_entry_is_bit_identical_and_with_one_lifts(tmp_path):
    from dancekit.pipelines import stages
    from dancekit.pipelines.config import read_stage_config

    motion = _swing(0.1, seconds=12.0)
    plain = _checkpoint(tmp_path, None, "plain")
    config = read_stage_config(plain)
    a = stages.finish(_result(motion, plain), "unused.wav", config.switched(beat_sync=False))
    b = stages.finish(_result(motion, plain), "unused.wav", config.switched(beat_sync=False, energy=False))
    for x, y in ((a.motion.positions, b.motion.positions), (a.motion.rotations, b.motion.rotations)):
        np.testing.assert_array_equal(x, y)
    assert not any("energy" in n for n in a.notes)
    lift = _checkpoint(tmp_path, {"floor": 2 * _energy(motion), "max_gain": 1.5}, "lift")
    lifted = stages.finish(_result(motion, lift), "unused.wav", read_stage_config(lift).switched(beat_sync=False))
    assert any(n.startswith("energy lifted (gain 1.50") for n in lifted.notes)
    assert _energy(lifted.motion) > 1.3 * _energy(a.motion)


def test_the_embedded_models_entries():
    from pathlib import Path

    from dancekit.pipelines import stages
    from dancekit.pipelines.config import read_stage_config

    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    for name in ("revolution", "music2dance", "dual"):  # the dance models (style is a classifier)
        config = read_stage_config(folder / name)
        spec = config.lift_energy
        assert spec is None or (spec.fraction is not None and config.genre_stats.energy) or spec.floor is not None
    assert read_stage_config(folder / "music2dance").lift_energy is None
    assert read_stage_config(folder / "dual").lift_energy.fraction == 0.8


@pytest.mark.parametrize("entry", [{"max_gain": 2.0}, {"floor": 0.0}, {"floor": -0.3}, {"floor": "high"},
                                   {"floor": 0.4, "max_gain": 0.5}, {"floor": 0.4, "band_hz": 0},
                                   {"floor": 0.4, "mean_s": -1}, {"floor": 0.4, "damp": 2},
                                   {"fraction": 0.6}, {"fraction": 0.6, "genre_energy": {"waltz": -1}},
                                   {"fraction": 0.6, "genre_energy": [0.4]}, {"floor": 0.4, "gain": 2}, [0.4],
                                   {"floor": True}])
def test_a_bad_energy_entry_is_a_checkpoint_error(tmp_path, entry):
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.config import read_stage_config

    with pytest.raises(CheckpointError, match=f"{tmp_path / 'm'}: config.json.*energy"):
        read_stage_config(_checkpoint(tmp_path, entry))


def test_a_band_above_nyquist_is_a_checkpoint_error(tmp_path):
    from pathlib import Path

    from dancekit.errors import CheckpointError
    from dancekit.pipelines import stages
    from dancekit.pipelines.config import read_stage_config

    folder = _checkpoint(tmp_path, {"floor": 10.0, "band_hz": 13.0})
    spec = read_stage_config(folder).lift_energy
    with pytest.raises(CheckpointError, match="config.json.*band_hz"):
        stages.lift_energy(_result(_swing(0.1), folder), floor=spec.floor, band_hz=spec.band_hz)
    meta = json.loads((Path(folder) / "config.json").read_text())
    (Path(folder) / "config.json").write_text(json.dumps({**meta, "fps": 25.0}))  # known when the checkpoint loads
    with pytest.raises(CheckpointError, match=r"config.json: stages.lift_energy.band_hz must be below 12.5 Hz"):
        read_stage_config(folder)


def _leg_swing(seconds: float = 20.0) -> Motion:
    """The swing of :func:`_swing` plus a knee bending in time with it: the legs move too."""
    m = _swing(0.15, seconds=seconds)
    sk = m.skeleton
    t = np.arange(m.num_frames) / FPS
    rot = np.array(m.rotations, np.float64)
    rot[:, sk.index("left_knee")] = rotation_exp((0.3 * np.sin(2 * np.pi * t))[:, None] * np.array([1.0, 0, 0]))
    return Motion(skeleton=sk, fps=FPS, rotations=rot.astype(np.float32), root_translation=m.root_translation)


def test_legs_off_keeps_the_legs_rotations_and_positions():
    from dancekit.motion.energy import leg_joints, leg_rotations
    from dancekit.pipelines import stages

    motion = _leg_swing()
    sk = motion.skeleton
    legs = leg_rotations(sk, motion.rotations.shape[1])
    assert {sk.index("left_knee"), sk.index("right_hip")} <= set(legs)
    assert sk.index("left_shoulder") not in legs and sk.root not in legs
    both = stages.lift_energy(_result(motion), floor=1.3 * _energy(motion), mean_s=2.0, max_gain=3.0)
    kept = stages.lift_energy(_result(motion), floor=1.3 * _energy(motion), mean_s=2.0, max_gain=3.0, legs=0)
    assert "energy lifted" in both.notes[-1] and "energy lifted" in kept.notes[-1]
    np.testing.assert_array_equal(kept.motion.rotations[:, legs], motion.rotations[:, legs])
    assert np.abs(both.motion.rotations[:, sk.index("left_knee")] - motion.rotations[:, sk.index("left_knee")]).max() > 0.01
    # positions only: the legs' joints stay where they were relative to the root
    pos = Motion(skeleton=sk, fps=FPS, positions=motion.to_positions())
    out = stages.lift_energy(_result(pos), floor=1.3 * _energy(pos), mean_s=2.0, max_gain=3.0, legs=0)
    p, q = np.asarray(pos.positions, np.float64), np.asarray(out.motion.positions, np.float64)
    lj = leg_joints(sk)
    np.testing.assert_allclose(q[:, lj] - q[:, [sk.root]], p[:, lj] - p[:, [sk.root]], atol=1e-4)
    arm = sk.index("left_wrist")
    assert np.abs((q[:, arm] - q[:, sk.root]) - (p[:, arm] - p[:, sk.root])).max() > 1.0  # cm: the arm lifted


def test_a_calmed_dance_of_an_input_that_is_not_music_stays_calm():
    from dancekit.pipelines import stages

    motion = _swing(0.1)
    res = dataclasses.replace(_result(motion), looks_like_music=False)
    assert stages.lift_energy(res, floor=3 * _energy(motion)) is res


def test_a_dual_checkpoint_with_a_genre_reader_reads_the_genre_for_the_energy_floor(tmp_path):
    """A dual checkpoint that declares a ``"genre_reader"`` component and a genre-table energy entry gets the
    music's genre probabilities on its results (the model itself has no genre input); without the entry the
    reader is not run; an unknown component is a CheckpointError."""
    import shutil
    from pathlib import Path

    import torch

    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy
    from dancekit.checkpoints import save_pretrained
    from dancekit.errors import CheckpointError
    from dancekit.models.dual import DualConfig, DualModel
    from dancekit.pipelines import stages
    from dancekit.pipelines.dual import DualPipeline

    sk = get_skeleton("tang2018")
    cfg = DualConfig(music_dim=53, music_raw_from=40, pose_dim=171, window=10, m2d_d_model=16, m2d_layers=1,
                     m2d_heads=2, m2d_ff=16, d2m_d_model=16, d2m_layers=1, d2m_heads=2, d2m_ff=16)
    torch.manual_seed(0)
    stats = {"music_mean": np.zeros(53, np.float32), "music_std": np.ones(53, np.float32),
             "dance_mean": np.zeros(171, np.float32), "dance_std": np.ones(171, np.float32)}
    folder = tmp_path / "dual"
    save_pretrained(folder, DualModel(cfg), cfg, stats=stats, extra={
        "representation": "rot6d", "preset": "dual", "fps": 25.0, "hop_length": 512, "skeleton": sk.to_dict()})
    models = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    shutil.copytree(models / "music2dance" / "music_attributes", folder / "music_attributes")
    meta = json.loads((folder / "config.json").read_text())
    song = tmp_path / "ode.wav"
    save_wav(song, ode_to_joy(sr=22050, bpm=120)[: 4 * 22050], sr=22050)

    (folder / "config.json").write_text(json.dumps({**meta, "components": {"genre_reader": "music_attributes"}}))
    pipe = DualPipeline.from_pretrained(folder)
    assert pipe.genre_reader is not None
    assert pipe(song, seed=0, beat_sync=False).genre_probs == {}  # no energy entry: the reader is not run
    entry = {"fraction": 0.6, "genre_energy": {"waltz": 0.44, "rumba": 0.59, "chacha": 0.79, "tango": 0.91}}
    (folder / "config.json").write_text(json.dumps({**meta, "components": {"genre_reader": "music_attributes"},
                                                    "energy": entry}))
    result = DualPipeline.from_pretrained(folder)(song, seed=0, beat_sync=False)
    assert set(result.genre_probs) == {"waltz", "rumba", "chacha", "tango"}
    assert sum(result.genre_probs.values()) == pytest.approx(1.0, abs=1e-5) and result.genre is None
    (folder / "config.json").write_text(json.dumps({**meta, "components": {"style": "music_attributes"}}))
    with pytest.raises(CheckpointError, match="unknown components"):
        DualPipeline.from_pretrained(folder)


def _jitter_ratio(motion: Motion) -> float:
    from dancekit.metrics import jitter

    p = np.asarray(motion.to_positions(), np.float64)
    return jitter(p, fps=motion.fps, skeleton=motion.skeleton)["speed_residual"] / smoothed_energy(
        p, fps=motion.fps, skeleton=motion.skeleton)


def test_a_per_dance_settle_filters_only_a_jittery_dance_down_to_its_target():
    from dancekit.pipelines import stages

    calm = _swing(0.3)
    calm = Motion(skeleton=calm.skeleton, fps=FPS, positions=calm.positions)
    res = _result(calm)
    r0 = _jitter_ratio(calm)
    assert r0 < 0.1
    assert stages.settle(res, ratio_target=1.05 * r0) is res  # already under the target: left alone
    # frame-to-frame noise on every joint's rotation (bone lengths stay fixed, as a model's dance's do)
    swing = _swing(0.3)
    noise = rotation_exp(np.random.default_rng(2).normal(scale=0.03, size=swing.rotations.shape[:2] + (3,)))
    noisy = Motion(skeleton=swing.skeleton, fps=FPS, rotations=(swing.rotations @ noise).astype(np.float32),
                   root_translation=swing.root_translation)
    noisy = Motion(skeleton=swing.skeleton, fps=FPS, positions=noisy.to_positions())
    assert _jitter_ratio(noisy) > 1.0
    light = _jitter_ratio(stages.settle(_result(noisy), ratio_target=0.3).motion)
    strong = _jitter_ratio(stages.settle(_result(noisy), ratio_target=0.2).motion)
    # the metrics' own ratio: at the target (the bones restored after), and a lower target filters harder
    assert 0.2 < light <= 0.3 * 1.05 and strong <= 0.2 * 1.05 and strong < 0.8 * light


@pytest.mark.parametrize("entry", [{"ratio_target": 0.0}, {"ratio_target": -0.1}, {"cutoff_hz": -1.0},
                                   {"cutoff_hz": 3.0, "ratio_target": 0.07}, {"ratio_target": "low"}])
def test_a_bad_settle_entry_is_a_checkpoint_error(tmp_path, entry):
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.config import read_stage_config

    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"model": "music2dance", "stages": {"settle": entry}}))
    with pytest.raises(CheckpointError, match="config.json.*stages.settle"):
        read_stage_config(folder)
    (folder / "config.json").write_text(json.dumps({"model": "music2dance", "stages": {"settle": {"ratio_target": 0.07}}}))
    assert read_stage_config(folder).settle.settle_options() == {"ratio_target": 0.07}



def test_a_long_dance_is_lifted_piece_by_piece_with_the_numbers_of_one_pass(monkeypatch):
    """Over :data:`dancekit.motion.filters.CHUNK` frames the positions path works piece by piece (margins over
    the filters' reach): the same dance as one pass, and the same energy as the metrics'."""
    from dancekit.motion import energy as en
    from dancekit.motion import filters

    swing = _swing(0.2, seconds=400.0)  # 10,000 frames: three pieces
    p = np.asarray(swing.positions)
    sk = swing.skeleton
    assert en.smoothed_energy(p, skeleton=sk, fps=FPS) == pytest.approx(
        smoothed_energy(p.astype(np.float64), fps=FPS, skeleton=sk), rel=1e-9)
    floor = 1.4 * smoothed_energy(p.astype(np.float64), fps=FPS, skeleton=sk)
    pieces, gain = en.lift_positions(p, skeleton=sk, fps=FPS, floor=floor, max_gain=3.0)
    monkeypatch.setattr(filters, "CHUNK", 100_000)
    whole, gain1 = en.lift_positions(p, skeleton=sk, fps=FPS, floor=floor, max_gain=3.0)
    assert gain == pytest.approx(gain1, rel=1e-6) and gain > 1.3
    np.testing.assert_allclose(pieces, whole, atol=1e-3)  # cm
    assert smoothed_energy(pieces.astype(np.float64), fps=FPS, skeleton=sk) == pytest.approx(floor, rel=0.01)
