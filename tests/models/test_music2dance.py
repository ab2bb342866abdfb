"""Music2Dance (paper §4.4): the rotations_rootdelta representation, the WaveNet generator, its GMM head,
incremental generation, the training objective and the pipeline. Tiny configurations, CPU, float64 maths."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.representations import decode_motion, encode_motion, pose_dim
from dancekit.motion.root_delta import RootDeltaDecoder, decode_rootdelta, encode_rootdelta, rootdelta_layout
from dancekit.motion.rotations import axis_angle_to_matrix, euler_angles_to_matrix

SK = get_skeleton("tang2018")


@pytest.fixture(autouse=True)
def _one_thread():
    """Tiny models: one torch thread is faster than several on a shared machine."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _random_motion(rng: np.random.Generator, T: int = 120) -> Motion:
    """Random rig rotations (up to ~70° per joint), a wandering root that turns through ±π, tilts up to ~30°."""
    Jr = SK.rig().num_joints
    R = axis_angle_to_matrix(torch.from_numpy(rng.normal(0, 0.7, (T, Jr, 3)))).numpy()
    heading = np.cumsum(rng.normal(0.15, 0.3, T)) + 3.0  # crosses ±π several times
    tilt = rng.normal(0, 0.25, (T, 2))
    R[:, SK.root] = euler_angles_to_matrix(torch.from_numpy(np.stack([heading, tilt[:, 0], tilt[:, 1]], -1)),
                                           "YXZ").numpy()
    tr = np.cumsum(rng.normal(0, 3.0, (T, 3)), axis=0)
    tr[:, 1] = 90 + rng.normal(0, 2, T)
    return Motion(skeleton=SK, fps=25.0, rotations=R, root_translation=tr)


def test_rootdelta_layout_of_tang2018():
    lay = rootdelta_layout(SK)
    assert lay.dim == pose_dim(SK, "rotations_rootdelta") == 6 + 6 * 22 + 3 * 5 + 2 == 155
    assert lay.contact_cols == (153, 154)
    assert [SK.joint_names[j] for j in lay.end_effectors] == ["head_left", "left_toe", "right_toe", "left_aux",
                                                              "right_aux"]
    assert SK.root not in lay.rot_joints and all(SK.rig().children(j) for j in lay.rot_joints)


def test_rootdelta_round_trip_is_exact(rng):
    """Deltas integrate back to the trajectory and rotations give the positions, to 1e-4 cm (float64)."""
    m = _random_motion(rng)
    x = encode_rootdelta(m)
    heading0 = float(np.arctan2(m.rotations[0, SK.root, 0, 2], m.rotations[0, SK.root, 2, 2]))  # YXZ: atan2(R02, R22)
    back = decode_rootdelta(x, SK, 25.0, origin=(m.root_translation[0, 0], m.root_translation[0, 2], heading0))
    np.testing.assert_allclose(back.root_translation, m.root_translation, atol=1e-4)
    np.testing.assert_allclose(back.to_positions(), m.to_positions(), atol=1e-4)
    lay = rootdelta_layout(SK)
    np.testing.assert_allclose(back.rotations[:, list(lay.rot_joints)], m.rotations[:, list(lay.rot_joints)],
                               atol=1e-9)
    # heading deltas are wrapped: no 2π jumps although the heading crosses ±π
    assert np.abs(x[:, 3]).max() < 2.0


def test_the_numpy_decoder_gives_the_positions_of_the_torch_one(rng):
    """RootDeltaDecoder (NumPy, the live stepper's) against the motion itself and decode_rootdelta (torch's rotations
    and per-joint FK): the whole dance, one and two rows from a carried origin, and degenerate 6D blocks."""
    m = _random_motion(rng, T=40)
    x = encode_rootdelta(m)
    heading0 = float(np.arctan2(m.rotations[0, SK.root, 0, 2], m.rotations[0, SK.root, 2, 2]))
    origin = (m.root_translation[0, 0], m.root_translation[0, 2], heading0)
    dec = RootDeltaDecoder(SK)
    pos, tr = dec(x, origin=origin)
    np.testing.assert_allclose(pos, m.to_positions(), atol=1e-4)
    np.testing.assert_allclose(tr, m.root_translation, atol=1e-4)
    x[5, 6:12] = 0.0  # a zero block
    x[6, 9:12] = x[6, 6:9]  # parallel columns
    for rows, o in ((x, origin), (x[7:8], (1.5, -2.0, 0.7)), (x[10:12], (0.0, 3.0, -2.9))):
        pos, tr = dec(rows, origin=o)
        ref = decode_rootdelta(rows, SK, 25.0, origin=o)
        np.testing.assert_allclose(pos, ref.positions, rtol=0, atol=1e-9)
        np.testing.assert_allclose(tr, ref.root_translation, rtol=0, atol=1e-9)
    with pytest.raises(ParameterError, match=r"\(T, 155\)"):
        dec(x[:, :-1])


def test_rootdelta_decodes_from_the_origin_facing_forward(rng):
    """Default decoding = the dance moved to the origin and turned to face +z at frame 0 (a rigid motion)."""
    m = _random_motion(rng, T=60)
    back = decode_motion(encode_motion(m, "rotations_rootdelta"), SK, 25.0, "rotations_rootdelta")  # float32 path
    p, q = m.to_positions().astype(np.float64), back.to_positions().astype(np.float64)
    a = np.arctan2(m.rotations[0, SK.root, 0, 2], m.rotations[0, SK.root, 2, 2])
    c, s = np.cos(-a), np.sin(-a)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    shift = np.array([m.root_translation[0, 0], 0.0, m.root_translation[0, 2]])
    np.testing.assert_allclose(q, (p - shift) @ Ry.T, atol=2e-3)  # float32 features: ~1e-5 relative


def test_rootdelta_end_effectors_are_root_relative_in_the_heading_frame(rng):
    m = _random_motion(rng, T=10)
    x = encode_rootdelta(m)
    lay = rootdelta_layout(SK)
    toe = SK.index("left_toe")
    pos = m.to_positions()
    a = np.arctan2(m.rotations[:, SK.root, 0, 2], m.rotations[:, SK.root, 2, 2])
    rel = pos[:, toe] - m.root_translation
    local_x = np.cos(a) * rel[:, 0] - np.sin(a) * rel[:, 2]  # R_Y(a)ᵀ rel, x component
    np.testing.assert_allclose(x[:, list(lay.end_effector_col(toe))][:, 0], local_x, atol=1e-9)
    np.testing.assert_allclose(x[:, list(lay.end_effector_col(toe))][:, 1], rel[:, 1], atol=1e-9)


# Hand-checked from the printed toe heights (cm above the running floor) and speeds (cm/s) of the raw
# tang2018 markers (commit message of this test): (dance, foot, first frame, end frame, in contact?)
CONTACT_FIXTURE = [
    ("DANCE_R_4", 0, 464, 485, 1),  # left toe 0.7-1.8 cm up, 0.6-15 cm/s: planted
    ("DANCE_R_4", 0, 405, 413, 0),  # left toe gliding at 190-460 cm/s, 0.2-3.6 cm up: a step, not a contact
    ("DANCE_R_4", 0, 487, 496, 0),  # 90-400 cm/s
    ("DANCE_R_4", 0, 499, 520, 1),  # 0.3-1.0 cm up, 3-11 cm/s
    ("DANCE_R_4", 1, 442, 467, 1),  # right toe 0.6-2.5 cm up, 2-10 cm/s
    ("DANCE_R_4", 1, 425, 433, 0),  # 77-440 cm/s
    ("DANCE_R_4", 1, 506, 519, 0),  # 66-263 cm/s
    ("DANCE_W_10", 0, 1000, 1004, 0),  # left toe 147-152 cm up (a kick); slow (17 cm/s) at the top: height rules
]


def test_contacts_on_real_dances_match_the_hand_checked_fixture(tang2018_dir):
    from dancekit.motion.formats import read_tang2018

    for dance in sorted({d for d, *_ in CONTACT_FIXTURE}):
        motion, _ = read_tang2018(tang2018_dir / dance)
        contacts = encode_motion(motion, "rotations_rootdelta")[:, -2:]
        assert set(np.unique(contacts)) <= {0.0, 1.0}
        assert 0.1 < contacts.mean() < 0.8  # the thresholds flag a plausible share of frames
        for d, foot, start, end, expected in CONTACT_FIXTURE:
            if d == dance:
                got = contacts[start:end, foot]
                assert (got == expected).all(), f"{dance} foot {foot} frames {start}-{end}: {got}"


# ---------------------------------------------------------------------------------------------- the model

from dancekit.models.music2dance import (  # noqa: E402
    Music2DanceConfig,
    Music2DanceModel,
    gmm_nll,
    shift_right,
    split_params,
)


def _tiny(**kw) -> Music2DanceModel:
    cfg = dict(music_dim=5, pose_dim=12, n_genres=3, n_layers=7, channels=8, skip_channels=8, genre_dim=4,
               fmap_channels=(4, 4, 4), fmap_lstm_hidden=4, lstm_hidden=8, lstm_layers=2, n_mixtures=3)
    torch.manual_seed(0)
    return Music2DanceModel(Music2DanceConfig(**{**cfg, **kw})).double().eval()


@pytest.mark.parametrize("kw", [{}, {"music_condition": "raw"}, {"generator": "lstm"}])
def test_generator_is_causal_in_the_motion(kw):
    """Changing input frame t+1 never changes the outputs of frames <= t."""
    model = _tiny(**kw)
    g = torch.Generator().manual_seed(1)
    music, prev = torch.randn(2, 40, 5, generator=g, dtype=torch.float64), torch.randn(2, 40, 12, generator=g,
                                                                                       dtype=torch.float64)
    out = model(music, prev, torch.tensor([0, -1]))
    for t in (0, 9, 25, 38):
        changed = prev.clone()
        changed[:, t + 1 :] += torch.randn(2, 39 - t, 12, generator=g, dtype=torch.float64)
        again = model(music, changed, torch.tensor([0, -1]))
        torch.testing.assert_close(again[:, : t + 1], out[:, : t + 1], rtol=0, atol=0)
        assert (again[:, t + 1] - out[:, t + 1]).abs().max() > 1e-6  # ... and frame t+1 does see it


def test_wavenet_receptive_field_matches_the_dilations():
    model = _tiny()  # 7 layers: dilations 1 2 4 8 16 1 2
    assert model.config.dilations == (1, 2, 4, 8, 16, 1, 2)
    rf = model.config.receptive_field
    assert rf == 1 + 34
    music, prev = torch.zeros(1, 60, 5, dtype=torch.float64), torch.zeros(1, 60, 12, dtype=torch.float64)
    base = model(music, prev)
    poked = prev.clone()
    poked[0, 59 - rf] += 1.0  # just outside the receptive field of frame 59
    assert torch.equal(model(music, poked)[0, 59], base[0, 59])
    poked[0, 59 - rf + 1] += 1.0  # its oldest frame
    assert not torch.equal(model(music, poked)[0, 59], base[0, 59])


def test_gmm_nll_equals_torch_distributions():
    g = torch.Generator().manual_seed(2)
    B, T, N, D = 3, 5, 4, 7
    logit_w = torch.randn(B, T, N, generator=g, dtype=torch.float64)
    mu = torch.randn(B, T, N, D, generator=g, dtype=torch.float64)
    log_var = torch.randn(B, T, N, D, generator=g, dtype=torch.float64)
    x = torch.randn(B, T, D, generator=g, dtype=torch.float64) * 2
    D_ = torch.distributions
    mix = D_.MixtureSameFamily(D_.Categorical(logits=logit_w),
                               D_.Independent(D_.Normal(mu, torch.exp(0.5 * log_var)), 1))  # Σ = exp(σ̂)
    torch.testing.assert_close(gmm_nll(logit_w, mu, log_var, x), -mix.log_prob(x), rtol=1e-10, atol=1e-10)


def test_model_loss_is_the_gmm_nll_plus_weighted_bce():
    model = _tiny(n_mixtures=2)
    g = torch.Generator().manual_seed(3)
    params = torch.randn(2, 6, model.config.out_dim, generator=g, dtype=torch.float64)
    target = torch.randn(2, 6, 12, generator=g, dtype=torch.float64)
    target[..., -2:] = (target[..., -2:] > 0).double()
    logit_w, mu, log_var, logits = split_params(params, model.config)
    loss, logs = model.loss(params, target)
    nll = gmm_nll(logit_w, mu, log_var, target[..., :10]).mean()
    bce = torch.nn.functional.binary_cross_entropy_with_logits(logits, target[..., 10:])
    torch.testing.assert_close(loss, (nll + 0.1 * bce) / 10)


@pytest.mark.parametrize("kw", [{}, {"kernel": 3}, {"generator": "lstm"}])
def test_incremental_generation_equals_the_full_sequence(kw):
    """Per-layer activation queues (one frame at a time) give the full-sequence outputs to 1e-5."""
    model = _tiny(**kw)
    g = torch.Generator().manual_seed(4)
    music, prev = torch.randn(2, 70, 5, generator=g, dtype=torch.float64), torch.randn(2, 70, 12, generator=g,
                                                                                       dtype=torch.float64)
    genre = torch.tensor([2, -1])
    full = model(music, prev, genre)
    torch.testing.assert_close(model.forward_incremental(music, prev, genre), full, rtol=0, atol=1e-5)
    if model.config.generator == "wavenet":
        sizes = [len(q) for q in model.init_state(1)]  # a queue of (k-1)·d inputs per layer: O(layers) a frame
        assert sizes == [(model.config.kernel - 1) * d for d in model.config.dilations]


def test_generate_feeds_its_own_samples_back_and_seeds_differ():
    model = _tiny()
    music = torch.randn(1, 30, 5, dtype=torch.float64)
    a = model.generate(music, torch.tensor([1]), generator=torch.Generator().manual_seed(0))
    b = model.generate(music, torch.tensor([1]), generator=torch.Generator().manual_seed(0))
    c = model.generate(music, torch.tensor([1]), generator=torch.Generator().manual_seed(1))
    assert a.shape == (1, 30, 12) and torch.equal(a, b) and not torch.allclose(a, c)
    assert set(a[..., -2:].unique().tolist()) <= {0.0, 1.0}
    # the frames are the model's own predictions: replaying them as inputs reproduces the same means
    params = model(music, shift_right(a), torch.tensor([1]))
    mean = model.generate(music, torch.tensor([1]), temperature=0.0)
    torch.testing.assert_close(model.predict(model(music, shift_right(mean), torch.tensor([1])), temperature=0.0),
                               mean)
    assert params.shape == (1, 30, model.config.out_dim)


# ---------------------------------------------------------------------------------------------- training

def _ctx(training: bool, **train):
    from dancekit.training import StepContext, TrainConfig

    return StepContext(step=0, epoch=0, training=training, generator=torch.Generator().manual_seed(0),
                       config=TrainConfig(**train))


def _batch(model, B=2, T=24, seed=5):
    g = torch.Generator().manual_seed(seed)
    c = model.config
    dance = torch.randn(B, T, c.pose_dim, generator=g, dtype=torch.float64)
    dance[..., -2:] = (dance[..., -2:] > 0).double()
    return {"music": torch.randn(B, T, c.music_dim, generator=g, dtype=torch.float64), "dance": dance,
            "genre": torch.tensor([0, 2])[:B], "weight": torch.tensor([0.5, 2.0], dtype=torch.float64)[:B]}


def _record_forward(model, what):
    """Spy on ``model.forward``: each call appends ``what(music, prev).clone()`` to the returned list; also returns
    the original forward."""
    seen, forward = [], model.forward

    def spy(music, prev, genre=None):
        seen.append(what(music, prev).clone())
        return forward(music, prev, genre)

    model.forward = spy
    return seen, forward


def test_objective_phase_two_feeds_the_first_pass_predictions_back():
    from dancekit.training.m2d import music2dance_step

    model = _tiny(phase=2, input_noise=0.0, target_noise=0.0)
    calls, forward = _record_forward(model, lambda music, prev: prev)
    batch = _batch(model)
    loss, _ = music2dance_step(model, batch, _ctx(False))
    assert len(calls) == 2
    torch.testing.assert_close(calls[0], shift_right(batch["dance"]))  # pass 1: the ground truth
    first = model.predict(forward(batch["music"], calls[0], batch["genre"]), temperature=0.0)
    torch.testing.assert_close(calls[1], shift_right(first))  # pass 2: its own predictions
    params = forward(batch["music"], shift_right(first), batch["genre"])
    torch.testing.assert_close(loss, model.loss(params, batch["dance"])[0])


def test_objective_noise_and_cluster_weights_apply_in_training_only():
    from dancekit.training.m2d import music2dance_step

    model = _tiny(input_dropout=0.0)
    batch = _batch(model)
    val1, _ = music2dance_step(model, batch, _ctx(False))
    val2, _ = music2dance_step(model, batch, _ctx(False))
    assert float(val1.detach()) == float(val2.detach())  # validation: no noise, unweighted
    params = model(batch["music"], shift_right(batch["dance"]), batch["genre"])
    torch.testing.assert_close(val1, model.loss(params, batch["dance"])[0])
    quiet = _tiny(input_dropout=0.0, input_noise=0.0, target_noise=0.0)
    weighted, _ = music2dance_step(quiet, batch, _ctx(True, genre_dropout=0.0))
    params = quiet(batch["music"], shift_right(batch["dance"]), batch["genre"])
    torch.testing.assert_close(weighted, quiet.loss(params, batch["dance"], weights=batch["weight"])[0])
    noisy, _ = music2dance_step(model, batch, _ctx(True, genre_dropout=0.0))
    assert float(noisy.detach()) != float(val1.detach())


def test_objective_music_dropout_zeroes_whole_windows_in_training_only():
    from dancekit.training.m2d import music2dance_step

    model = _tiny()
    seen, _ = _record_forward(model, lambda music, prev: music)
    batch = _batch(model, B=64, T=6)
    batch["genre"] = torch.zeros(64, dtype=torch.long)
    batch["weight"] = torch.ones(64, dtype=torch.float64)
    batch["music"] = batch["music"] + 3.0  # no window is all zeros
    for training, share in [(True, 0.5), (True, 0.0), (False, 1.0)]:
        music2dance_step(model, batch, _ctx(training, music_dropout=share))
    dropped = (seen[0] == 0).all(dim=(1, 2))
    kept = (seen[0] == batch["music"]).all(dim=(1, 2))
    assert bool((dropped | kept).all()) and 16 < int(dropped.sum()) < 48  # whole windows, about half
    torch.testing.assert_close(seen[1], batch["music"])  # none asked
    torch.testing.assert_close(seen[2], batch["music"])  # validation never drops


def test_cluster_weights_balance_the_clusters(rng):
    from dancekit.training.m2d import cluster_weights

    feats = np.concatenate([rng.normal(0, 1, (30, 6)), rng.normal(50, 1, (10, 6))]).astype(np.float32)
    labels, weights = cluster_weights(feats, k=2)
    assert len(set(labels[:30])) == 1 and len(set(labels[30:])) == 1 and labels[0] != labels[30]
    np.testing.assert_allclose(weights[:30], 40 / (2 * 30), rtol=1e-6)
    np.testing.assert_allclose(weights[30:], 40 / (2 * 10), rtol=1e-6)
    assert weights.mean() == pytest.approx(1.0)


# ---------------------------------------------------------------------------------------------- pipeline

@pytest.fixture(scope="module")
def m2d_folder(tmp_path_factory):
    """A tiny untrained music2dance checkpoint on the tang2018 skeleton (stats: realistic rootdelta scales)."""
    from dancekit.checkpoints import NormStats, save_pretrained

    lay = rootdelta_layout(SK)
    torch.manual_seed(0)
    cfg = Music2DanceConfig(music_dim=15, pose_dim=lay.dim, n_genres=2, n_layers=4, channels=8, skip_channels=8,
                            genre_dim=4, fmap_channels=(4, 4, 4), fmap_lstm_hidden=4)
    model = Music2DanceModel(cfg)
    with torch.no_grad():  # a small output variance, so samples stay near the mean pose
        model.out2.bias[cfg.n_mixtures * (1 + cfg.gmm_dim):cfg.n_mixtures * (1 + 2 * cfg.gmm_dim)] = -4.0
    mean = encode_rootdelta(_random_motion(np.random.default_rng(0), T=50)).mean(0)
    std = np.full(lay.dim, 0.05)
    std[[1]] = 2.0  # root height, cm
    mean[list(lay.contact_cols)], std[list(lay.contact_cols)] = 0.0, 1.0
    stats = NormStats(music_mean=np.zeros(15, np.float32), music_std=np.ones(15, np.float32),
                      dance_mean=mean.astype(np.float32), dance_std=std.astype(np.float32))
    folder = tmp_path_factory.mktemp("m2d") / "model"
    save_pretrained(folder, model, cfg, stats=stats,
                    extra={"representation": "rotations_rootdelta", "preset": "music2dance", "fps": 25.0,
                           "hop_length": 512, "skeleton": SK.to_dict(), "genres": ["waltz", "rumba"]})
    return folder


@pytest.fixture(scope="module")
def song8(tmp_path_factory):
    from dancekit.audio import save_wav, synth

    path = tmp_path_factory.mktemp("song") / "tune.wav"
    save_wav(path, synth.ode_to_joy(sr=22050, repeats=2)[: 8 * 22050], sr=22050)
    return path


def test_pipeline_samples_different_dances_for_different_seeds_on_the_floor(m2d_folder, song8):
    from dancekit.motion.analysis import floor_curve
    from dancekit.pipelines.base import DanceResult, load_pipeline
    from dancekit.pipelines.music2dance import Music2DancePipeline

    pipe = Music2DancePipeline.from_pretrained(m2d_folder)
    assert type(load_pipeline(m2d_folder)) is Music2DancePipeline
    a = pipe(song8, seed=0, genre="waltz")
    b = pipe(song8, seed=0, genre="waltz")
    c = pipe(song8, seed=1, genre="waltz")
    assert isinstance(a, DanceResult) and a.genre == "waltz" and a.seed == 0
    assert a.motion.num_frames == 1 + 8 * 25 and a.motion.rotations is not None
    pa, pc = a.motion.to_positions(), c.motion.to_positions()
    np.testing.assert_array_equal(pa, b.motion.to_positions())
    assert np.abs(pa - pc).max() > 1.0  # another seed, another dance (cm)
    floor = floor_curve(pa, SK, fps=25.0)
    assert np.abs(floor).max() < 0.5  # feet on the floor all along
    assert pipe(song8, seed=0, genre="none").genre is None and pipe(song8, seed=0).genre is None  # no reader


def test_pipeline_rejects_unknown_genres_and_negative_temperatures(m2d_folder, song8):
    from dancekit.errors import ParameterError
    from dancekit.pipelines.music2dance import Music2DancePipeline

    pipe = Music2DancePipeline.from_pretrained(m2d_folder)
    with pytest.raises(ParameterError, match="unknown genre 'tango'.*waltz, rumba"):
        pipe(song8, genre="tango")
    with pytest.raises(ParameterError, match="temperature"):
        pipe(song8, temperature=-1)


def test_fmap_on_windows_matches_the_windows_where_it_reads_them():
    model = _tiny()
    music = torch.randn(1, 100, 5, dtype=torch.float64)
    torch.testing.assert_close(model.music_condition(music, window=200), model.music_condition(music))
    chunked = model.music_condition(music, window=40)  # windows at 0, 20, 40, 60 (flush); hop 20, margin 10
    assert chunked.shape == (1, 100, 8)
    torch.testing.assert_close(chunked[:, :30], model.music_condition(music[:, :40])[:, :30])
    torch.testing.assert_close(chunked[:, 30:50], model.music_condition(music[:, 20:60])[:, 10:30])
    torch.testing.assert_close(chunked[:, 70:], model.music_condition(music[:, 60:])[:, 10:])


def test_pipeline_takes_its_default_temperature_from_the_checkpoint(m2d_folder, song8, tmp_path):
    import json
    import shutil

    from dancekit.errors import CheckpointError
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = tmp_path / "t0"
    shutil.copytree(m2d_folder, folder)
    meta = json.loads((folder / "config.json").read_text())
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"temperature": 0.0}}))
    plain, cold = Music2DancePipeline.from_pretrained(m2d_folder), Music2DancePipeline.from_pretrained(folder)
    assert plain.temperature == 1.0 and cold.temperature == 0.0
    means = plain(song8, seed=0, temperature=0.0).motion.to_positions()
    np.testing.assert_array_equal(cold(song8, seed=0).motion.to_positions(), means)  # no temperature: the folder's
    np.testing.assert_array_equal(cold(song8, seed=5).motion.to_positions(), means)  # temperature 0: no randomness
    assert np.abs(plain(song8, seed=0).motion.to_positions() - means).max() > 1.0
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"temperature": -1}}))
    with pytest.raises(CheckpointError, match="temperature"):
        Music2DancePipeline.from_pretrained(folder)


def test_a_batch_of_seeds_equals_the_seeds_one_by_one(m2d_folder, song8):
    from dancekit.pipelines.music2dance import Music2DancePipeline

    pipe = Music2DancePipeline.from_pretrained(m2d_folder)
    batch = pipe.dances(song8, seeds=[3, 0, 7], genre="rumba", end=3.0)
    assert [r.seed for r in batch] == [3, 0, 7]
    for r in batch:
        alone = pipe(song8, seed=r.seed, genre="rumba", end=3.0).motion.to_positions()
        np.testing.assert_array_equal(r.motion.to_positions(), alone)  # bit for bit (tests/pipelines/test_seeds.py)
    assert np.abs(batch[0].motion.to_positions() - batch[1].motion.to_positions()).max() > 1.0
    mixed = pipe.dances(song8, seeds=[0, 0], genre=["waltz", "rumba"], end=3.0)
    assert [r.genre for r in mixed] == ["waltz", "rumba"]
    for r in mixed:
        alone = pipe(song8, seed=0, genre=r.genre, end=3.0).motion.to_positions()
        np.testing.assert_array_equal(r.motion.to_positions(), alone)


def test_the_embedded_model_loads_in_float32_with_its_parts_and_dances(song8):
    """`--model music2dance` needs no download: a float16 folder (<= 8 MB with its F_map, foot model and
    music attribute classifier) whose weights load as float32; its sampling settings come from its config."""
    import json

    from safetensors import safe_open

    from dancekit.checkpoints import available_models, resolve_model
    from dancekit.pipelines.foot_constraint import foot_constraint_folder, load_foot_constraint
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = resolve_model("music2dance")
    assert "music2dance" in available_models()
    assert sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) <= 8e6
    with safe_open(str(folder / "model.safetensors"), "pt") as f:
        assert {f.get_tensor(k).dtype for k in f.keys()} >= {torch.float16}
    pipe = Music2DancePipeline.from_pretrained("music2dance")
    assert {p.dtype for p in pipe.model.parameters()} == {torch.float32}
    assert int(pipe.model.fmap_loaded) == 1 and pipe.genre_reader is not None
    sampling = json.loads((folder / "config.json").read_text())["sampling"]
    assert (pipe.temperature, pipe.noise_correlation, pipe.smooth_sigma) == (
        sampling["temperature"], sampling["noise_correlation"], sampling["smooth_sigma"])
    # --genre chacha / tango: their own sampling and smoothing targets (docs/MUSIC2DANCE.md); waltz, rumba,
    # auto and none: the plain sampling above
    assert set(pipe.genre_sampling) == {"chacha", "tango"}
    from dancekit.pipelines.config import read_stage_config

    assert set(read_stage_config(folder).smooth.genre_targets) == {"chacha", "tango"}
    assert foot_constraint_folder() == folder / "foot_constraint"
    fix = load_foot_constraint()
    assert {p.dtype for p in fix.model.parameters()} == {torch.float32}
    r = pipe(song8, seed=0, genre="waltz", end=4.0)
    pos = r.motion.to_positions()
    assert r.genre == "waltz" and pos.shape[0] == 101 and np.isfinite(pos).all()
    assert np.linalg.norm(np.diff(pos, axis=0), axis=-1).mean() * 25 > 10.0  # moves (cm/s)
    assert fix(r.motion).num_frames == 101


def test_sampling_noise_given_and_correlated_over_frames():
    from dancekit.errors import ParameterError
    from dancekit.models.music2dance import gmm_sample

    g = torch.Generator().manual_seed(0)
    logit_w, mu, log_var = torch.zeros(3, 1), torch.randn(3, 1, 4, generator=g), torch.randn(3, 1, 4, generator=g)
    z = torch.randn(3, 4, generator=g)
    torch.testing.assert_close(gmm_sample(logit_w, mu, log_var, temperature=0.25, noise=z),
                               mu[:, 0] + torch.exp(0.5 * log_var[:, 0]) * 0.5 * z)  # σ·√t·ε
    model = _tiny()
    music = torch.randn(1, 400, 5, dtype=torch.float64)
    with torch.no_grad():  # outputs: the means at zero and unit variances, so the dance is the noise itself
        model.out2.weight.zero_()
        model.out2.bias.zero_()
    model.eval()
    D = model.config.gmm_dim

    def lag1(rho: float) -> float:
        x = model.generate(music, None, generator=torch.Generator().manual_seed(1), noise_correlation=rho)[0, :, :D]
        return float(torch.corrcoef(torch.stack([x[1:].reshape(-1), x[:-1].reshape(-1)]))[0, 1])

    assert abs(lag1(0.0)) < 0.1 and lag1(0.9) == pytest.approx(0.9, abs=0.05)
    with pytest.raises(ParameterError, match="noise_correlation"):
        model.generate(music, None, noise_correlation=1.0)


def test_genre_guidance_moves_the_dance_type_vector_away_from_no_type():
    """``genre_scale`` α: the dance type enters every gated layer as ``W_g (g_∅ + α (g - g_∅))``; checked
    against a copy of the model whose embedding rows are moved by hand (temperature 0: the means)."""
    import copy

    from dancekit.errors import ParameterError

    model = _tiny()
    music = torch.randn(3, 25, 5, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    genre = torch.tensor([0, 2, -1])
    alpha = 2.5
    moved = copy.deepcopy(model)
    with torch.no_grad():
        emb = moved.genre_embedding.weight  # rows 0..n-1: the types, row n: "no type"
        emb[:-1] = emb[-1] + alpha * (emb[:-1] - emb[-1])
    guided = model.generate(music, genre, temperature=0.0, genre_scale=alpha)
    torch.testing.assert_close(guided, moved.generate(music, genre, temperature=0.0), rtol=0, atol=1e-10)
    plain = model.generate(music, genre, temperature=0.0)
    assert torch.equal(model.generate(music, genre, temperature=0.0, genre_scale=1.0), plain)
    torch.testing.assert_close(guided[2], plain[2], rtol=0, atol=1e-12)  # no type: nothing to guide
    assert (guided[:2] - plain[:2]).abs().max() > 1e-3
    # α = 0: every row dances as "no type"
    none = model.generate(music, torch.tensor([-1, -1, -1]), temperature=0.0)
    torch.testing.assert_close(model.generate(music, genre, temperature=0.0, genre_scale=0.0), none,
                               rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match="genre_scale"):
        model.generate(music, genre, genre_scale=-1.0)


def test_genre_sampling_applies_when_a_genre_is_named_and_not_otherwise(m2d_folder, song8, tmp_path):
    """A checkpoint's ``"genre_sampling": {genre: settings}`` is how that genre is sampled when it is asked for
    by name (``--genre rumba``); other genres, "none" and "auto" sample with the plain settings; a batch
    mixing them gives each row what it would get alone."""
    import json
    import shutil

    from dancekit.errors import CheckpointError
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = tmp_path / "steered"
    shutil.copytree(m2d_folder, folder)
    meta = json.loads((folder / "config.json").read_text())
    steer = {"genre_scale": 3.0, "temperature": 0.5, "noise_correlation": 0.5, "smooth_sigma": 1.0}
    (folder / "config.json").write_text(json.dumps({**meta, "genre_sampling": {"rumba": steer}}))
    plain, steered = Music2DancePipeline.from_pretrained(m2d_folder), Music2DancePipeline.from_pretrained(folder)
    assert steered.genre_sampling == {"rumba": steer} and plain.genre_sampling == {}
    by_hand = Music2DancePipeline.from_pretrained(m2d_folder)
    by_hand.noise_correlation, by_hand.smooth_sigma = 0.5, 1.0

    def pos(pipe, genre, **kw):
        return pipe(song8, seed=0, genre=genre, end=3.0, **kw).motion.to_positions()

    rumba = pos(steered, "rumba")
    np.testing.assert_array_equal(rumba, pos(by_hand, "rumba", genre_scale=3.0, temperature=0.5))
    assert np.abs(rumba - pos(plain, "rumba")).max() > 1e-3
    for genre in ("waltz", "none", "auto"):
        np.testing.assert_array_equal(pos(steered, genre), pos(plain, genre))
    mixed = steered.dances(song8, seeds=[0, 0, 1], genre=["rumba", "waltz", "rumba"], end=3.0)
    assert [r.genre for r in mixed] == ["rumba", "waltz", "rumba"]
    alone = [rumba, pos(plain, "waltz"), steered(song8, seed=1, genre="rumba", end=3.0).motion.to_positions()]
    for r, a in zip(mixed, alone):  # a batch of two equals the rows alone, bit for bit
        np.testing.assert_array_equal(r.motion.to_positions(), a)
    for bad in ({"tango": steer}, {"rumba": {"speed": 2}}, {"rumba": {"noise_correlation": 1.0}}, ["rumba"]):
        (folder / "config.json").write_text(json.dumps({**meta, "genre_sampling": bad}))
        with pytest.raises(CheckpointError, match="genre_sampling|sampling.genres"):
            Music2DancePipeline.from_pretrained(folder)


def test_pipeline_takes_its_default_genre_scale_from_the_checkpoint(m2d_folder, song8, tmp_path):
    import json
    import shutil

    from dancekit.errors import CheckpointError, ParameterError
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = tmp_path / "g3"
    shutil.copytree(m2d_folder, folder)
    meta = json.loads((folder / "config.json").read_text())
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"genre_scale": 3.0}}))
    plain, steered = Music2DancePipeline.from_pretrained(m2d_folder), Music2DancePipeline.from_pretrained(folder)
    assert plain.genre_scale == 1.0 and steered.genre_scale == 3.0
    by_call = plain(song8, seed=0, genre="rumba", end=3.0, genre_scale=3.0).motion.to_positions()
    np.testing.assert_array_equal(steered(song8, seed=0, genre="rumba", end=3.0).motion.to_positions(), by_call)
    assert np.abs(plain(song8, seed=0, genre="rumba", end=3.0).motion.to_positions() - by_call).max() > 1e-3
    with pytest.raises(ParameterError, match="genre_scale"):
        plain(song8, seed=0, genre="rumba", end=3.0, genre_scale=float("nan"))
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"genre_scale": -2}}))
    with pytest.raises(CheckpointError, match="genre_scale"):
        Music2DancePipeline.from_pretrained(folder)


def test_the_jitter_cap_entry_calms_a_dance_to_its_genres_before_the_foot_lock(m2d_folder, song8, tmp_path):
    """A checkpoint's ``"jitter_cap": {"genre_jitter": {...}, "jitter_cap": s, "jitter_cap_min_ratio": ρ}``
    (issue 15, the Dance Revolution cap given to music2dance): a dance of a named genre G is finished with
    ``max_jitter = s × genre_jitter[G]`` (worked by hand: 1.5 × 0.002 m/s), i.e. bit for bit the model's own dance
    run through :func:`stages.finish` with that cap; "none" (no genre) is not capped; a bad entry names config.json."""
    import dataclasses
    import json
    import shutil

    from dancekit.errors import CheckpointError
    from dancekit.pipelines import stages
    from dancekit.pipelines.config import JitterCapConfig
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = tmp_path / "capped"
    shutil.copytree(m2d_folder, folder)
    meta = json.loads((folder / "config.json").read_text())
    entry = {"genre_jitter": {"waltz": 0.001, "rumba": 0.002}, "jitter_cap": 1.5, "jitter_cap_min_ratio": 0.7}
    (folder / "config.json").write_text(json.dumps({**meta, "jitter_cap": entry}))
    plain, capped = Music2DancePipeline.from_pretrained(m2d_folder), Music2DancePipeline.from_pretrained(folder)
    assert plain.stage_options().jitter_cap is None
    raw = plain(song8, seed=0, genre="rumba", end=3.0, beat_sync=False, cleanup=False)

    def cap(pipe, genre, probs):
        config = pipe.stage_options()
        return stages.jitter_cap_for(dataclasses.replace(raw, genre=genre, genre_probs=probs), config.jitter_cap,
                                     config.genre_stats)

    assert cap(capped, "rumba", {}) == pytest.approx(1.5 * 0.002)
    assert cap(capped, "rumba", {"rumba": 0.6, "waltz": 0.4}) == pytest.approx(1.5 * 0.002)  # 0.4 < 0.7 · 0.6
    assert cap(capped, "rumba", {"rumba": 0.5, "waltz": 0.4}) == pytest.approx(1.5 * 0.001)  # 0.4 ≥ 0.7 · 0.5
    assert cap(capped, None, {}) is None and cap(plain, "rumba", {}) is None

    fixed = dataclasses.replace(plain.stage_options(beat_sync=False), jitter_cap=JitterCapConfig(max_jitter=1.5 * 0.002))
    by_hand = stages.finish(raw, stages.Song(song8, end=3.0), fixed).motion.to_positions()
    got = capped(song8, seed=0, genre="rumba", end=3.0, beat_sync=False)
    np.testing.assert_array_equal(got.motion.to_positions(), by_hand)
    assert any(n.startswith("calmed to the song's genres") for n in got.notes)
    uncapped = plain(song8, seed=0, genre="rumba", end=3.0, beat_sync=False).motion.to_positions()
    assert np.abs(uncapped - by_hand).max() > 0.1  # the cap changed the dance (cm)
    np.testing.assert_array_equal(capped(song8, seed=0, genre="none", end=3.0, beat_sync=False).motion.to_positions(),
                                  plain(song8, seed=0, genre="none", end=3.0, beat_sync=False).motion.to_positions())
    for bad in ([1.5], {"jitter_cap": 1.5}, {**entry, "jitter_cap": 0}, {**entry, "jitter_cap_min_ratio": 2},
                {**entry, "genre_jitter": {"waltz": -1}}, {**entry, "cap": 1}):
        (folder / "config.json").write_text(json.dumps({**meta, "jitter_cap": bad}))
        with pytest.raises(CheckpointError, match=r"config\.json: .*(jitter_cap|genre_stats\.jitter)"):
            Music2DancePipeline.from_pretrained(folder)


def test_the_jitter_cap_entry_after_lock_calms_the_locked_dance(m2d_folder, song8, tmp_path):
    """``"after_lock": true`` in the ``"jitter_cap"`` entry (issue 15, second try): the cap's per-dance low-pass
    runs after the foot lock and its settle instead of before the lock, i.e. the dance is bit for bit the raw dance
    through the stages spelt out by hand (clean-up, smoothing, energy, lock, settle, *then* the cap of
    1.5 × 0.002 m/s), and not the before-the-lock dance; ``false`` is today's order; a non-boolean names
    config.json."""
    import json
    import shutil

    from dancekit.errors import CheckpointError
    from dancekit.pipelines import stages
    from dancekit.pipelines.music2dance import Music2DancePipeline

    folder = tmp_path / "after"
    shutil.copytree(m2d_folder, folder)
    meta = json.loads((folder / "config.json").read_text())
    entry = {"genre_jitter": {"waltz": 0.001, "rumba": 0.002}, "jitter_cap": 1.5, "jitter_cap_min_ratio": 0.7}
    plain = Music2DancePipeline.from_pretrained(m2d_folder)
    raw = plain(song8, seed=0, genre="rumba", end=3.0, beat_sync=False, cleanup=False)
    config = plain.stage_options()
    assert config.lift_energy is None and config.settle.settle_options() == {}  # the tiny model's: no lift, no settle
    r = stages.smooth(stages.clean_up(raw))
    locked = stages.settle(stages.foot_lock(r))
    by_hand_after = stages.settle(locked, max_jitter=1.5 * 0.002)
    by_hand_before = stages.settle(stages.settle(stages.foot_lock(stages.settle(r, max_jitter=1.5 * 0.002))))
    assert any(n.startswith("calmed to the song's genres") for n in by_hand_after.notes)
    got = {}
    for after in (True, False):
        (folder / "config.json").write_text(json.dumps({**meta, "jitter_cap": {**entry, "after_lock": after}}))
        capped = Music2DancePipeline.from_pretrained(folder)
        assert capped.stage_options().jitter_cap.after_lock is after
        got[after] = capped(song8, seed=0, genre="rumba", end=3.0, beat_sync=False).motion.to_positions()
    np.testing.assert_array_equal(got[True], by_hand_after.motion.to_positions())
    np.testing.assert_array_equal(got[False], by_hand_before.motion.to_positions())
    assert np.abs(got[True] - got[False]).max() > 1e-3  # the placement matters for this dance
    for bad in ("yes", 1, None):
        (folder / "config.json").write_text(json.dumps({**meta, "jitter_cap": {**entry, "after_lock": bad}}))
        with pytest.raises(CheckpointError, match=r"config\.json: stages\.jitter_cap\.after_lock must be true or false"):
            Music2DancePipeline.from_pretrained(folder)
