"""Music2Dance (paper §4.4): the rotations_rootdelta representation, the WaveNet generator, its GMM head,
incremental generation, the training objective and the pipeline. Tiny configurations, CPU, float64 maths."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.motion import Motion, get_skeleton
from dancekit.motion.representations import decode_motion, encode_motion, pose_dim
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta, rootdelta_layout
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
