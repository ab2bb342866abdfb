"""Dual learning of music and dance (MM 2021): rot6d, the losses, Gromov-Wasserstein, the two generators."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.dual import (
    DualConfig,
    DualModel,
    chord_token,
    dance_difference_loss,
    dance_loss,
    geodesic_squared,
    music_loss,
    sinusoidal_encoding,
)
from dancekit.models.gromov import entropic_gromov_wasserstein, l1_cost_matrix
from dancekit.motion.rotations import axis_angle_to_matrix, matrix_to_rotation_6d, rotation_6d_to_matrix

# ---------------------------------------------------------------------------------------------- rot6d


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_6d_always_decodes_to_a_proper_rotation(scale):
    g = torch.Generator().manual_seed(0)
    d6 = torch.randn(500, 6, generator=g, dtype=torch.float64) * scale
    d6[0] = 0.0  # degenerate: zeros
    d6[1, 3:] = 2.0 * d6[1, :3]  # degenerate: parallel columns
    R = rotation_6d_to_matrix(d6)
    eye = torch.eye(3, dtype=torch.float64).expand_as(R)
    assert torch.allclose(R.transpose(-1, -2) @ R, eye, atol=1e-10)
    assert torch.allclose(torch.linalg.det(R), torch.ones(500, dtype=torch.float64), atol=1e-10)


def test_6d_round_trip():
    g = torch.Generator().manual_seed(1)
    R = axis_angle_to_matrix(torch.randn(200, 3, generator=g, dtype=torch.float64))
    assert torch.allclose(rotation_6d_to_matrix(matrix_to_rotation_6d(R)), R, atol=1e-12)


def test_rot6d_representation_round_trip(rng):
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.representations import decode_motion, encode_motion, pose_dim

    sk = get_skeleton("tang2018")
    assert pose_dim(sk, "rot6d") == 3 + 6 * sk.rig().num_joints == 171
    pos = rng.normal(0, 10, (12, sk.num_joints, 3)).astype(np.float32)
    x = encode_motion(Motion(skeleton=sk, fps=25.0, positions=pos), "rot6d")
    assert x.shape == (12, 171) and x.dtype == np.float32
    m = decode_motion(x, sk, 25.0, "rot6d")
    assert m.rotations is not None and m.positions is not None
    np.testing.assert_allclose(encode_motion(m, "rot6d"), x, atol=1e-5)
    # the translation columns are the root; the decoded positions are the IK'd ones (rest bone lengths)
    np.testing.assert_allclose(m.positions[:, sk.root], x[:, :3], atol=1e-4)
    # the root decoded by Procrustes: the same for unit, orthogonal 6D columns, and only the root changes when
    # they are not (the up column three times as long as a root heading column that leans 45 degrees)
    from dancekit.errors import ParameterError
    from dancekit.motion.representations import decode_rot6d

    same = decode_rot6d(x, sk, 25.0, root_decode="procrustes")
    np.testing.assert_allclose(same.rotations, m.rotations, atol=1e-5)
    r = 3 + 6 * sk.root
    bent = x.copy()
    bent[:, r : r + 6] = [0.0, 0.1, 0.1, 0.0, 3.0, 0.0]
    gs, pr = decode_motion(bent, sk, 25.0, "rot6d"), decode_rot6d(bent, sk, 25.0, root_decode="procrustes")
    assert pr.rotations[:, sk.root, 1, 1].min() > 0.99 > 0.75 > gs.rotations[:, sk.root, 1, 1].max()
    others = [j for j in range(sk.rig().num_joints) if j != sk.root]
    np.testing.assert_allclose(pr.rotations[:, others], gs.rotations[:, others], atol=1e-6)
    with pytest.raises(ParameterError, match="root_decode"):
        decode_rot6d(x, sk, 25.0, root_decode="svd")


# ---------------------------------------------------------------------------------------------- losses


def test_geodesic_is_zero_for_identical_and_pi_squared_for_opposite_rotations():
    g = torch.Generator().manual_seed(2)
    R = axis_angle_to_matrix(torch.randn(50, 3, generator=g, dtype=torch.float64))
    assert geodesic_squared(R, R).max() < 1e-12
    axis = torch.nn.functional.normalize(torch.randn(50, 3, generator=g, dtype=torch.float64), dim=-1)
    flip = axis_angle_to_matrix(math.pi * axis)  # a rotation by π: the opposite
    torch.testing.assert_close(geodesic_squared(R, R @ flip), torch.full((50,), math.pi**2, dtype=torch.float64))
    half = axis_angle_to_matrix(0.5 * axis)
    torch.testing.assert_close(geodesic_squared(R, R @ half), torch.full((50,), 0.25, dtype=torch.float64))


def test_geodesic_gradient_is_finite_at_zero_and_pi():
    R = torch.eye(3, dtype=torch.float64)
    d6 = matrix_to_rotation_6d(torch.stack([R, axis_angle_to_matrix(torch.tensor([math.pi, 0, 0.0]))]))
    d6 = d6.double().requires_grad_(True)
    geodesic_squared(rotation_6d_to_matrix(d6), R.expand(2, 3, 3)).sum().backward()
    assert torch.isfinite(d6.grad).all()


def test_dance_and_music_losses():
    g = torch.Generator().manual_seed(3)
    R = axis_angle_to_matrix(torch.randn(2, 5, 4, 3, generator=g))
    y = torch.cat([torch.randn(2, 5, 3, generator=g), matrix_to_rotation_6d(R).reshape(2, 5, 24)], -1)
    assert float(dance_loss(y, y)) < 1e-6
    shifted = y.clone()
    shifted[..., 0] += 2.0  # translation: L1
    assert float(dance_loss(shifted, y)) == pytest.approx(2.0, abs=1e-5)
    flipped = y.clone()
    flip = axis_angle_to_matrix(torch.tensor([0.0, 0.0, math.pi]))
    flipped[..., 3:9] = matrix_to_rotation_6d(R[..., 0, :, :] @ flip)  # one joint of four turned by π
    assert float(dance_loss(flipped, y)) == pytest.approx(math.pi**2, rel=1e-4)
    x = torch.rand(2, 5, 13, generator=g)
    x2 = x.clone()
    x2[..., :12] += 0.1
    x2[..., 12] += 0.5
    assert float(music_loss(x2, x)) == pytest.approx(12 * 0.1 + 0.5, rel=1e-5)


def test_chord_token():
    assert chord_token("C").nonzero().flatten().tolist() == [0, 4, 7]
    assert chord_token("A", minor=True).nonzero().flatten().tolist() == [0, 4, 9]  # A C E
    assert chord_token(11)[12] == 0.0 and chord_token(11).shape == (13,)


# ---------------------------------------------------------------------------------------------- GW


def _points(m, d, *, seed, scale=1.0):
    return torch.randn(m, d, generator=torch.Generator().manual_seed(seed), dtype=torch.float64) * scale


def test_gw_of_a_batch_with_itself_is_zero():
    """≈ 0 up to the entropic blur of the plan (ε = 0.2 on O(1)-spaced points): 1e-4 of another batch's GW."""
    x = _points(8, 5, seed=0)
    other = float(entropic_gromov_wasserstein(x, _points(8, 5, seed=1)))
    assert other > 1.0
    assert float(entropic_gromov_wasserstein(x, x)) < 1e-4 * other
    # costs ≫ ε: L = 30 Sinkhorn iterations do not converge and the plan stalls (a limit of Algorithm 1's
    # settings); more iterations find the identity
    assert float(entropic_gromov_wasserstein(3 * x, 3 * x)) > 1.0
    assert float(entropic_gromov_wasserstein(3 * x, 3 * x, sinkhorn_iters=300)) < 1e-12



def test_gw_is_invariant_to_permuting_one_batch():
    x, y = _points(8, 5, seed=2, scale=0.3), _points(8, 3, seed=3, scale=0.3)
    perm = torch.randperm(8, generator=torch.Generator().manual_seed(4))
    a = entropic_gromov_wasserstein(x, y)
    torch.testing.assert_close(entropic_gromov_wasserstein(x, y[perm]), a, rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(entropic_gromov_wasserstein(x[perm], y), a, rtol=1e-9, atol=1e-12)


def test_gw_gradient_matches_finite_differences():
    x = _points(6, 4, seed=5, scale=0.5).requires_grad_(True)
    y = _points(6, 3, seed=6, scale=0.5).requires_grad_(True)

    def f(a, b):
        return entropic_gromov_wasserstein(a, b, sinkhorn_iters=10, projection_iters=5)

    assert torch.autograd.gradcheck(f, (x, y), eps=1e-6, atol=1e-5, rtol=1e-4)
    gx, = torch.autograd.grad(entropic_gromov_wasserstein(x, y), x)  # the paper's settings: finite
    assert torch.isfinite(gx).all() and gx.abs().sum() > 0


def test_gw_stays_finite_for_large_costs():
    x, y = _points(16, 512, seed=7, scale=3.0).float(), _points(16, 256, seed=8, scale=3.0).float()
    x.requires_grad_(True)
    gw = entropic_gromov_wasserstein(x, y)
    gw.backward()
    assert torch.isfinite(gw) and torch.isfinite(x.grad).all()


@pytest.mark.filterwarnings("ignore:Sinkhorn did not converge")  # POT run at the paper's L = 30 on purpose
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gw_agrees_with_pot(seed):
    """POT runs Sinkhorn on 2·E (its gwggrad has the factor 2), so POT's epsilon = 2 ε. Costs O(1): both
    converge within the paper's iterations, and the values agree to 1e-9 relative."""
    ot = pytest.importorskip("ot")
    m = 8
    x, y = _points(m, 5, seed=10 + seed, scale=0.2), _points(m, 3, seed=20 + seed, scale=0.2)
    gw, plan = entropic_gromov_wasserstein(x, y, return_plan=True)
    C, D, p = l1_cost_matrix(x).numpy(), l1_cost_matrix(y).numpy(), np.full(m, 1.0 / m)
    T, log = ot.gromov.entropic_gromov_wasserstein(D, C, p, p, "square_loss", epsilon=0.4, max_iter=20, tol=0.0,
                                                   numItermax=30, stopThr=0.0, log=True)
    assert float(gw) == pytest.approx(float(log["gw_dist"]), rel=1e-9)
    np.testing.assert_allclose(plan.numpy(), T, atol=1e-9)


# ---------------------------------------------------------------------------------------------- the model

TINY = dict(music_dim=17, music_raw_from=4, pose_dim=3 + 6 * 2, window=8, m2d_d_model=16, m2d_layers=1,
            m2d_heads=2, m2d_ff=16, d2m_d_model=8, d2m_layers=1, d2m_heads=2, d2m_ff=16, dropout=0.0,
            gw_sinkhorn_iters=5, gw_projection_iters=3)  # GW itself is tested at the paper's L, M above


def _batch(seed=0, B=4, T=8):
    g = torch.Generator().manual_seed(seed)
    music = torch.randn(B, T, 17, generator=g)
    music[..., 4:] = torch.rand(B, T, 13, generator=g)
    R = axis_angle_to_matrix(torch.randn(B, T, 2, 3, generator=g))
    dance = torch.cat([torch.randn(B, T, 3, generator=g), matrix_to_rotation_6d(R).reshape(B, T, 12)], -1)
    return music, dance


def _reached(model, loss):
    """{part: whether any gradient reaches it} for m2d.encoder, m2d.decoder, d2m.encoder, d2m.decoder."""
    model.zero_grad(set_to_none=True)
    loss.backward(retain_graph=True)
    groups = {
        "m2d.enc": ("m2d.src_embed", "m2d.encoder"),
        "m2d.dec": ("m2d.tgt_embed", "m2d.decoder", "m2d.head"),
        "d2m.enc": ("d2m.src_embed", "d2m.encoder"),
        "d2m.dec": ("d2m.tgt_embed", "d2m.decoder", "d2m.head"),
    }
    out = {}
    for name, prefixes in groups.items():
        grads = [p.grad for n, p in model.named_parameters() if n.startswith(prefixes)]
        out[name] = any(g is not None and float(g.abs().sum()) > 0 for g in grads)
    return out


def test_each_loss_reaches_the_networks_the_paper_says():
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY))
    _, parts = model(*_batch())
    assert set(parts) == {"dance_rec", "music_rec", "gw", "dance_cycle", "music_cycle"}
    expect = {  # the paper: GW + dance losses → G_M→D (GW: its encoder only); music losses → G_D→M
        "gw": {"m2d.enc": True, "m2d.dec": False, "d2m.enc": False, "d2m.dec": False},
        "dance_rec": {"m2d.enc": True, "m2d.dec": True, "d2m.enc": False, "d2m.dec": False},
        "dance_cycle": {"m2d.enc": True, "m2d.dec": True, "d2m.enc": False, "d2m.dec": False},
        "music_rec": {"m2d.enc": False, "m2d.dec": False, "d2m.enc": True, "d2m.dec": True},
        "music_cycle": {"m2d.enc": False, "m2d.dec": False, "d2m.enc": True, "d2m.dec": True},
    }
    for name, reached in expect.items():
        assert _reached(model, parts[name]) == reached, name


@pytest.mark.parametrize("self_feed", [0.0, 0.5])
def test_velocity_and_acceleration_terms_reach_g_m2d_only(self_feed):
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY, velocity_weight=2.0, accel_weight=0.5, self_feed=self_feed))
    loss, parts = model(*_batch())
    assert set(parts) == {"dance_rec", "music_rec", "gw", "dance_cycle", "music_cycle", "dance_vel", "dance_acc"}
    only_m2d = {"m2d.enc": True, "m2d.dec": True, "d2m.enc": False, "d2m.dec": False}
    for name in ("dance_vel", "dance_acc", "dance_rec"):
        assert _reached(model, parts[name]) == only_m2d, name
    weights = {"gw": 1.0, "dance_cycle": 1.0, "music_cycle": 1.0, "dance_vel": 2.0, "dance_acc": 0.5}
    expect = sum(weights.get(k, 1.0) * float(v.detach()) for k, v in parts.items())
    assert float(loss.detach()) == pytest.approx(expect, rel=1e-6)


def test_rollout_term_reaches_g_m2d_only_and_rollout_is_free_running_generation():
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY, rollout_frames=4, rollout_weight=1.0))
    music, dance = _batch()
    _, parts = model(music, dance)
    assert _reached(model, parts["dance_roll"]) == {"m2d.enc": True, "m2d.dec": True, "d2m.enc": False,
                                                    "d2m.dec": False}
    model.eval()
    _, parts = model(music, dance)
    assert "dance_roll" not in parts  # training only
    with torch.no_grad():
        torch.testing.assert_close(model.m2d.rollout(model.m2d.encode(music), dance[:, 0], 8),
                                   model.m2d.generate_full(music, dance[:, 0]))
    with pytest.raises(Exception, match="rollout_frames"):
        DualConfig(**TINY, rollout_frames=8)  # not below the window


def test_difference_loss_known_answers():
    g = torch.Generator().manual_seed(5)
    y = torch.randn(2, 6, 15, generator=g)
    for order in (1, 2):
        assert float(dance_difference_loss(y + 3.0, y, order=order)) < 1e-5  # a constant offset moves nothing
    ramp = y.clone()
    ramp[..., 4] += 0.25 * torch.arange(6)  # one column drifts by 0.25 per frame: velocity off by 0.25
    assert float(dance_difference_loss(ramp, y, order=1)) == pytest.approx(0.25, rel=1e-5)
    assert float(dance_difference_loss(ramp, y, order=2)) < 1e-5
    flicker = y.clone()
    flicker[..., 1] += 0.1 * (-1.0) ** torch.arange(6)  # ±0.1 around the truth: differences ±0.2, second ±0.4
    assert float(dance_difference_loss(flicker, y, order=1)) == pytest.approx(0.2, rel=1e-5)
    assert float(dance_difference_loss(flicker, y, order=2)) == pytest.approx(0.4, rel=1e-5)
    assert float(dance_loss(flicker, y)) > 0  # L_Y (L1 on the translation) sees it as a
    offset = y.clone()  # constant 0.1 offset, which moves nothing
    offset[..., 1] += 0.1
    assert float(dance_loss(offset, y)) == pytest.approx(float(dance_loss(flicker, y)), rel=1e-5)
    assert float(dance_difference_loss(y[:, :1], y[:, :1], order=1)) == 0.0  # one frame: no difference


def test_paper_objective_by_default_and_new_settings_checked():
    from dancekit.errors import ParameterError

    c = DualConfig()
    assert (c.velocity_weight, c.accel_weight, c.self_feed) == (0.0, 0.0, 0.0)
    _, parts = DualModel(DualConfig(**TINY))(*_batch())
    assert "dance_vel" not in parts and "dance_acc" not in parts
    for bad in (dict(velocity_weight=-1.0), dict(accel_weight=float("nan")), dict(self_feed=1.5),
                dict(self_feed=True)):
        with pytest.raises(ParameterError):
            DualConfig(**TINY, **bad)


def test_self_feed_replaces_decoder_inputs_by_the_models_predictions():
    torch.manual_seed(0)
    music, dance = _batch()
    model = DualModel(DualConfig(**TINY, self_feed=1.0, decoder_noise=0.0))
    model.train()
    memory = model.m2d.encode(music)
    fed = model._self_fed(dance, memory)
    torch.testing.assert_close(fed[:, :1], dance[:, :1])  # the start token stays the true first frame
    torch.testing.assert_close(fed[:, 1:], model.m2d.decode(dance[:, :-1], memory))
    model.config.self_feed = 0.0
    torch.testing.assert_close(model._self_fed(dance, memory), dance)
    # in eval mode (validation) the inputs stay the true frames even with self_feed on
    model.config.self_feed = 1.0
    model.eval()
    a, _ = model(music, dance)
    model.config.self_feed = 0.0
    b, _ = model(music, dance)
    assert float(a.detach()) == pytest.approx(float(b.detach()), rel=1e-6)


@pytest.mark.parametrize("gw,cycle,generators,parts", [
    (True, True, "both", {"dance_rec", "music_rec", "gw", "dance_cycle", "music_cycle"}),
    (False, True, "both", {"dance_rec", "music_rec", "dance_cycle", "music_cycle"}),
    (True, False, "both", {"dance_rec", "music_rec", "gw"}),
    (False, False, "both", {"dance_rec", "music_rec"}),
    (False, False, "m2d", {"dance_rec"}),
    (False, False, "d2m", {"music_rec"}),
])
def test_ablation_switches(gw, cycle, generators, parts):
    model = DualModel(DualConfig(**TINY, gw=gw, cycle=cycle, generators=generators))
    loss, got = model(*_batch())
    assert set(got) == parts
    assert float(loss.detach()) == pytest.approx(sum(float(v.detach()) for v in got.values()), rel=1e-6)


def test_separate_training_refuses_coupling_losses():
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError, match="separate training"):
        DualConfig(**TINY, generators="m2d")  # gw and cycle default on


def test_paper_sizes():
    c = DualConfig.paper()
    assert (c.m2d_layers, c.m2d_heads, c.m2d_d_model, c.d2m_layers, c.d2m_heads, c.d2m_d_model) == (6, 8, 512, 6, 8, 256)


def test_long_generation_chains_windows_from_the_last_frame():
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY)).eval()
    music, dance = _batch(B=1, T=20)
    start = dance[:, 0]
    out = model.generate_dance(music, start=start)
    assert out.shape == (1, 20, 15)
    torch.testing.assert_close(out[:, 0], start)
    # window 2 covers frames 7..14 and starts from generated frame 7
    second = model.m2d.generate(music[:, 7:15], out[:, 7])
    torch.testing.assert_close(out[:, 7:15], second)
    notes = model.generate_music(dance, start=chord_token("G")[None])
    assert notes.shape == (1, 20, 13) and float(notes.min()) >= 0.0 and float(notes.max()) <= 1.0


def test_start_pose_pool():
    model = DualModel(DualConfig(**TINY, pool_size=3))
    empty = model.sample_start_pose()
    assert torch.equal(empty[3:9], torch.tensor([1.0, 0, 0, 0, 1, 0]))
    _, dance = _batch(B=4)
    model.remember_start_poses(dance)
    assert int(model.pool_count) == 4
    pose = model.sample_start_pose(torch.Generator().manual_seed(0))
    assert any(torch.equal(pose, p) for p in model.pose_pool)


# ---------------------------------------------------------------------------------------------- pipelines


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory):
    """An untrained tang2018-sized dual model saved as a checkpoint folder (rot6d, the dual preset)."""
    from dancekit.checkpoints import save_pretrained
    from dancekit.motion import get_skeleton

    sk = get_skeleton("tang2018")
    cfg = DualConfig(**{**TINY, "music_dim": 53, "music_raw_from": 40, "pose_dim": 171, "window": 10})
    torch.manual_seed(0)
    model = DualModel(cfg)
    stats = {"music_mean": np.zeros(53, np.float32), "music_std": np.ones(53, np.float32),
             "dance_mean": np.full(171, 5.0, np.float32), "dance_std": np.full(171, 2.0, np.float32)}
    folder = tmp_path_factory.mktemp("dual") / "model"
    save_pretrained(folder, model, cfg, stats=stats, extra={"representation": "rot6d", "preset": "dual", "fps": 25.0,
                                                           "hop_length": 512, "skeleton": sk.to_dict()})
    return folder


def _motion(T=30):
    from dancekit.motion import Motion, get_skeleton

    sk = get_skeleton("tang2018")
    pos = np.random.default_rng(0).normal(0, 10, (T, sk.num_joints, 3)).astype(np.float32)
    return Motion(skeleton=sk, fps=25.0, positions=pos)


def test_compose_pipeline_writes_midi_and_wav(tiny_checkpoint, tmp_path):
    from dancekit.pipelines.dual import ComposePipeline

    pipe = ComposePipeline.from_pretrained(tiny_checkpoint)
    a = pipe(_motion(), seed=3, tempo=120)
    b = pipe(_motion(), seed=3, tempo=120)
    np.testing.assert_array_equal(a.chroma, b.chroma)  # deterministic under a seed
    assert a.chroma.shape == (30, 12) and a.beat.shape == (30,) and a.arrangement.tempo == pytest.approx(120.0)
    given = pipe(_motion(), root="A", minor=True)
    assert given.start_chord == "A minor"
    np.testing.assert_array_equal(given.chroma[0], chord_token("A", True)[:12].numpy())  # frame 0 = start token
    files = a.write(tmp_path, stem="dance")
    assert files["midi"].stat().st_size > 0 and files["wav"].stat().st_size > 0


def test_compose_refuses_another_skeleton(tiny_checkpoint):
    from dancekit.errors import ParameterError
    from dancekit.motion import Motion, get_skeleton
    from dancekit.pipelines.dual import ComposePipeline

    other = get_skeleton("body25")
    m = Motion(skeleton=other, fps=25.0, positions=np.zeros((10, other.num_joints, other.dims), np.float32))
    with pytest.raises(ParameterError, match="skeleton"):
        ComposePipeline.from_pretrained(tiny_checkpoint)(m)


def test_dance_pipeline_start_pose_and_denormalisation(tiny_checkpoint):
    from dancekit.pipelines.dual import DualPipeline

    pipe = DualPipeline.from_pretrained(tiny_checkpoint)
    motion = _motion(T=5)
    s = pipe.start_pose(motion, seed=0)
    # translation normalised with the stats (mean 5, std 2), 6D raw
    np.testing.assert_allclose(s[:3].numpy(), (motion.with_rotations().root_translation[0] - 5.0) / 2.0, rtol=1e-5)
    from dancekit.motion.representations import encode_motion

    np.testing.assert_allclose(s[3:].numpy(), encode_motion(motion, "rot6d")[0, 3:], atol=1e-6)


def test_compose_cli_writes_midi_and_wav(tiny_checkpoint, tmp_path):
    from dancekit.cli.main import main
    from dancekit.motion.formats import write_motion

    write_motion(tmp_path / "dance.npz", _motion())
    out = tmp_path / "out"
    assert main(["compose", str(tmp_path / "dance.npz"), "-o", str(out), "--checkpoint", str(tiny_checkpoint),
                 "--tempo", "110", "--render", "builtin", "--quiet"]) == 0
    assert (out / "dance.mid").stat().st_size > 0 and (out / "dance.wav").stat().st_size > 0
    assert main(["compose", str(tmp_path / "dance.npz"), "-o", str(out), "--checkpoint", str(tiny_checkpoint),
                 "--tempo", "fast"]) == 2


def test_dual_windows_keep_chroma_beat_and_6d_raw():
    from dancekit.checkpoints import NormStats
    from dancekit.errors import ParameterError
    from dancekit.training.datasets import partial_stats, raw_columns

    assert raw_columns(preset="dual", representation="rot6d") == (40, 3)
    with pytest.raises(ParameterError, match="rot6d"):
        raw_columns(preset="dual", representation="positions3d")
    stats = NormStats(music_mean=np.full(53, 2.0, np.float32), music_std=np.full(53, 3.0, np.float32),
                      dance_mean=np.full(171, 2.0, np.float32), dance_std=np.full(171, 3.0, np.float32))
    p = partial_stats(stats, music_raw_from=40, dance_raw_from=3)
    assert (p.music_mean[:40] == 2).all() and (p.music_mean[40:] == 0).all() and (p.music_std[40:] == 1).all()
    assert (p.dance_std[:3] == 3).all() and (p.dance_mean[3:] == 0).all() and (p.dance_std[3:] == 1).all()
    assert (stats.music_mean == 2).all()  # the saved statistics are left as they are


def test_teacher_forcing_is_causal_and_matches_free_running_generation():
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY)).eval()
    music, dance = _batch(B=2, T=8)
    with torch.no_grad():
        out = model.m2d.teacher_forced(music, dance)
        changed = dance.clone()
        changed[:, 5:] += 1.0
        # ŷ_t depends on frames < t only
        torch.testing.assert_close(model.m2d.teacher_forced(music, changed)[:, :6], out[:, :6])
        # feeding the generated frames back reproduces them: training and inference are the same decoder
        gen = model.m2d.generate(music, dance[:, 0])
        torch.testing.assert_close(model.m2d.teacher_forced(music, gen), gen, atol=1e-5, rtol=1e-5)


# ---------------------------------------------------------------------------------- this session's additions


def test_gw_with_mean_normalised_costs_is_scale_invariant_and_resolves_the_plan():
    """normalize="mean" divides each L1 cost matrix by its mean off-diagonal entry: GW no longer depends on the
    embeddings' scale; with the printed Algorithm 1's unit marginals a batch is far nearer itself (and a
    permutation of itself) than a noisy copy or another batch, within the paper's L = 30 iterations."""
    x, y = _points(16, 64, seed=30), _points(16, 64, seed=31)
    noisy = x + 0.5 * _points(16, 64, seed=32)
    kw = dict(normalize="mean", marginals="unit")
    a = entropic_gromov_wasserstein(x, y, **kw)
    torch.testing.assert_close(entropic_gromov_wasserstein(7.0 * x, 0.01 * y, **kw), a, rtol=1e-9, atol=1e-12)
    self_gw = float(entropic_gromov_wasserstein(x, x, **kw))
    perm = torch.randperm(16, generator=torch.Generator().manual_seed(0))
    assert float(entropic_gromov_wasserstein(x, x[perm], **kw)) == pytest.approx(self_gw, rel=1e-9)
    assert self_gw < 0.1 * float(entropic_gromov_wasserstein(x, noisy, **kw))
    assert self_gw < 0.1 * float(a)
    # 30 Sinkhorn iterations have converged: 300 give the same value
    assert float(entropic_gromov_wasserstein(x, noisy, **kw)) == pytest.approx(
        float(entropic_gromov_wasserstein(x, noisy, sinkhorn_iters=300, **kw)), rel=1e-3)
    # without normalisation the same points' GW grows with their scale
    assert float(entropic_gromov_wasserstein(2 * x, 2 * y)) > 3 * float(entropic_gromov_wasserstein(x, y))


@pytest.mark.slow
def test_gw_with_normalised_costs_and_unit_marginals_agrees_with_pot():
    """Unit marginals are uniform marginals with ε / m and a GW m² times larger; POT's epsilon is 2 ε (its
    factor 2): POT on the mean-normalised cost matrices with epsilon = 2 ε / m, times m², is this value. With
    the sharper effective ε the two Sinkhorn update orders differ by 0.4 % after L = 30 iterations (tolerance
    1 %) and agree to 1e-4 relative at 3000."""
    ot = pytest.importorskip("ot")
    m, eps = 8, 0.2
    x, y = _points(m, 5, seed=40), _points(m, 3, seed=41)
    C, D = l1_cost_matrix(x).numpy(), l1_cost_matrix(y).numpy()
    C, D = C / (C.sum() / (m * (m - 1))), D / (D.sum() / (m * (m - 1)))
    p = np.full(m, 1.0 / m)
    for iters, rel in ((30, 1e-2), (3000, 1e-4)):
        gw = entropic_gromov_wasserstein(x, y, epsilon=eps, normalize="mean", marginals="unit", sinkhorn_iters=iters)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # POT's "Sinkhorn did not converge" with stopThr=0
            _, log = ot.gromov.entropic_gromov_wasserstein(D, C, p, p, "square_loss", epsilon=2 * eps / m,
                                                           max_iter=20, tol=0.0, numItermax=iters, stopThr=0.0,
                                                           log=True)
        assert float(gw) == pytest.approx(m**2 * float(log["gw_dist"]), rel=rel)


def test_beat_weight_of_the_music_loss():
    """Known answer: one frame of four is a beat; a silent prediction costs 1 per beat frame times the weight."""
    target = torch.zeros(1, 4, 13)
    target[0, 1, 12] = 1.0
    pred = torch.zeros(1, 4, 13)
    assert float(music_loss(pred, target)) == pytest.approx(1 / 4)
    assert float(music_loss(pred, target, beat_pos_weight=5.0)) == pytest.approx(5 / 4)
    pred[0, :, 12] = 1.0  # beats everywhere: the non-beat frames cost 1 each, unweighted
    assert float(music_loss(pred, target, beat_pos_weight=5.0)) == pytest.approx(3 / 4)
    pred[0, 0, 0] = 0.5  # chroma is never weighted
    assert float(music_loss(pred, target, beat_pos_weight=5.0)) == pytest.approx(3.5 / 4)


def test_decoder_noise_only_in_training():
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY, decoder_noise=0.5))
    music, dance = _batch()
    model.train()
    a, b = model.m2d.teacher_forced(music, dance, noise=0.5), model.m2d.teacher_forced(music, dance, noise=0.5)
    assert not torch.allclose(a, b)
    model.eval()
    torch.testing.assert_close(model.m2d.teacher_forced(music, dance, noise=0.5), model.m2d.teacher_forced(music, dance))
    with pytest.raises(Exception, match="decoder_noise"):
        DualConfig(**TINY, decoder_noise=-1.0)


@pytest.mark.parametrize("which", ["m2d", "d2m"])
def test_incremental_decoding_equals_re_decoding_the_prefix(which):
    torch.manual_seed(0)
    model = DualModel(DualConfig(**{**TINY, "m2d_layers": 2, "d2m_layers": 2})).eval()
    music, dance = _batch(B=2, T=8)
    net, src, start = (model.m2d, music, dance[:, 0]) if which == "m2d" else (model.d2m, dance, music[:, 0, 4:])
    with torch.no_grad():
        torch.testing.assert_close(net.generate(src, start), net.generate_full(src, start), atol=1e-5, rtol=1e-5)


def _real_like_motion(T=40):
    """A moving tang2018 dance: the rest pose, swaying and turning (positions in cm)."""
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.analysis import rest_pose

    sk = get_skeleton("tang2018")
    rest = rest_pose(sk)  # (J, 3)
    t = np.arange(T)[:, None] / 25.0
    ang = 0.3 * np.sin(2 * np.pi * 0.5 * t)[:, 0]
    R = np.stack([np.stack([np.cos(ang), np.zeros(T), np.sin(ang)], -1), np.tile([0.0, 1.0, 0.0], (T, 1)),
                  np.stack([-np.sin(ang), np.zeros(T), np.cos(ang)], -1)], 1)  # (T, 3, 3) about y
    pos = np.einsum("tij,kj->tki", R, rest) + np.stack([10 * np.sin(t[:, 0]), 90 + 0 * t[:, 0], 5 * t[:, 0]], -1)[:, None]
    return Motion(skeleton=sk, fps=25.0, positions=pos)


def _dancing_motion(skeleton, *, root_scale: float = 1.0, T: int = 60):
    """A dance on ``skeleton`` by forward kinematics: every joint turning by its own smooth random angles (a fixed
    draw, the same for any skeleton with the same joints), the root walking a curve (cm, times ``root_scale``)."""
    from dancekit.motion import Motion
    from dancekit.motion.rotations import axis_angle_to_matrix

    rng = np.random.default_rng(7)
    J = skeleton.num_joints
    t = np.arange(T)[:, None, None] / 25.0
    amp, freq, phase = rng.uniform(0.1, 0.5, (1, J, 3)), rng.uniform(0.3, 1.5, (1, J, 3)), rng.uniform(0, 6, (1, J, 3))
    rot = axis_angle_to_matrix(torch.from_numpy(amp * np.sin(2 * np.pi * freq * t + phase))).numpy()  # (T, J, 3, 3)
    s = t[:, 0, 0]
    root = root_scale * np.stack([60 * np.sin(0.8 * s), 95 + 3 * np.sin(4 * s), 40 * s], -1)
    return Motion(skeleton=skeleton, fps=25.0, rotations=rot, root_translation=root).with_positions()


def _bone(p, sk, a, b):
    return p[:, sk.index(b)] - p[:, sk.index(a)]


def test_map_by_role_keeps_a_dance_on_the_targets_proportions():
    """A dance on the target's own proportions (its torso rigid, as tang2018's joints from the pelvis are) comes back
    where it was: every joint with a role, to float precision."""
    from dancekit.motion import get_skeleton
    from dancekit.motion.retarget import map_by_role

    tang = get_skeleton("tang2018")
    dance = _dancing_motion(tang)
    p, q = dance.to_positions(), map_by_role(dance, tang).to_positions()
    for role in tang.roles:
        j = tang.index(role)
        np.testing.assert_allclose(q[:, j], p[:, j], atol=1e-6, err_msg=role)


def test_map_by_role_takes_the_directions_and_the_size_not_the_proportions():
    """The same dance on a rig of other proportions (thighs 30 % longer, shins shorter, arms longer, the torso
    and the walk scaled to the legs) maps onto tang2018 as the dance on tang2018 itself: the rig's bone directions
    on tang2018's bone lengths, the root's path scaled to tang2018's size (leg + trunk)."""
    from dancekit.motion import get_skeleton
    from dancekit.motion.retarget import map_by_role

    tang = get_skeleton("tang2018")
    off = np.asarray(tang.offsets, np.float64).copy()
    thigh = np.mean([np.linalg.norm(off[tang.index(f"{s}_knee")]) for s in ("left", "right")])
    shin = np.mean([np.linalg.norm(off[tang.index(f"{s}_ankle")]) for s in ("left", "right")])
    k = 1.1  # the rig's leg (thigh + shin) is k times tang2018's ...
    shin_scale = (k * (thigh + shin) - 1.3 * thigh) / shin
    for s in ("left", "right"):
        off[tang.index(f"{s}_knee")] *= 1.3
        off[tang.index(f"{s}_ankle")] *= shin_scale
        off[tang.index(f"{s}_elbow")] *= 1.25
        off[tang.index(f"{s}_wrist")] *= 0.8
    for j in tang.children(tang.root):  # ... and so is its torso, so the whole body is k times the size
        off[j] *= k
    rig = tang.replace(name="long_legs", offsets=off)
    assert not rig.same_as(tang)
    mapped = map_by_role(_dancing_motion(rig, root_scale=k), tang).to_positions()
    own = _dancing_motion(tang).to_positions()
    for role in ("pelvis", "left_hip", "right_knee", "left_ankle", "right_toe", "left_wrist", "right_elbow", "head"):
        j = tang.index(role)
        np.testing.assert_allclose(mapped[:, j], own[:, j], atol=1e-6, err_msg=role)
    # where the rig's proportions are kept instead (its joints' positions scaled by k), the feet slide: not this
    assert np.abs(_dancing_motion(rig, root_scale=k).to_positions()[:, tang.index("left_ankle")] / k
                  - own[:, tang.index("left_ankle")]).max() > 5.0


def test_map_by_role_from_smpl_keeps_the_bone_directions_on_tang2018_lengths():
    from dancekit.motion import get_skeleton
    from dancekit.motion.analysis import rest_pose
    from dancekit.motion.retarget import map_by_role, retarget_to_smpl

    tang = get_skeleton("tang2018")
    smpl_motion, _ = retarget_to_smpl(_real_like_motion())
    mapped = map_by_role(smpl_motion, tang)
    p, src, ssk = mapped.to_positions(), smpl_motion.to_positions(), smpl_motion.skeleton
    rest = rest_pose(tang)
    assert p.shape == (40, 23, 3) and np.isfinite(p).all()
    for a, b in (("left_hip", "left_knee"), ("right_knee", "right_ankle"), ("left_shoulder", "left_elbow"),
                 ("right_elbow", "right_wrist")):
        got, want = _bone(p, tang, a, b), _bone(src, ssk, a, b)
        np.testing.assert_allclose(got / np.linalg.norm(got, axis=-1, keepdims=True),
                                   want / np.linalg.norm(want, axis=-1, keepdims=True), atol=1e-9)
        rest_length = np.linalg.norm(rest[tang.index(b)] - rest[tang.index(a)])
        np.testing.assert_allclose(np.linalg.norm(got, axis=-1), rest_length, rtol=1e-9)
    # the forearm marker lies between the elbow and the wrist
    e, f, w = (p[:, tang.index(n)] for n in ("right_elbow", "right_forearm", "right_wrist"))
    np.testing.assert_allclose(np.linalg.norm(f - e, axis=-1) + np.linalg.norm(w - f, axis=-1),
                               np.linalg.norm(w - e, axis=-1), rtol=1e-9)
    # the heel is behind the ankle (forward = the body's facing) and below it
    heel, ankle, toe = (p[:, tang.index(n)] for n in ("left_heel", "left_ankle", "left_toe"))
    assert (np.einsum("ti,ti->t", heel - ankle, toe - ankle) < 0).mean() > 0.9


def test_map_by_role_refuses_a_skeleton_without_the_limb_roles():
    from dancekit.errors import ParameterError
    from dancekit.motion import Motion, Skeleton, get_skeleton
    from dancekit.motion.retarget import map_by_role

    sk = Skeleton(name="stick", joint_names=("root", "a"), parents=(-1, 0), offsets=np.zeros((2, 3)), up_axis="y",
                  units="m", roles={"pelvis": "root"})
    m = Motion(skeleton=sk, fps=25.0, positions=np.zeros((3, 2, 3)))
    with pytest.raises(ParameterError, match="left_hip"):
        map_by_role(m, get_skeleton("tang2018"))


def test_compose_maps_another_skeleton_by_role(tiny_checkpoint):
    from dancekit.motion.retarget import retarget_to_smpl
    from dancekit.pipelines.dual import ComposePipeline

    smpl_motion, _ = retarget_to_smpl(_real_like_motion())
    res = ComposePipeline.from_pretrained(tiny_checkpoint)(smpl_motion, seed=0)
    assert res.chroma.shape == (40, 12)


def test_compose_cli_writes_midi_wav_mp4_and_html(tiny_checkpoint, tmp_path):
    from dancekit.cli.main import main
    from dancekit.motion.formats import write_motion

    write_motion(tmp_path / "dance.npz", _real_like_motion(T=30))
    out = tmp_path / "out"
    assert main(["compose", str(tmp_path / "dance.npz"), "-o", str(out), "--checkpoint", str(tiny_checkpoint),
                 "--tempo", "120", "--render", "builtin", "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["dance.html", "dance.mid", "dance.mp4", "dance.wav"]
    assert all(p.stat().st_size > 0 for p in out.iterdir())
    # a bad tempo: one error line, nothing written
    bad = tmp_path / "bad"
    assert main(["compose", str(tmp_path / "dance.npz"), "-o", str(bad), "--checkpoint", str(tiny_checkpoint),
                 "--tempo", "fast"]) == 2
    assert not bad.exists()


def test_moving_average_known_answer():
    from dancekit.errors import ParameterError
    from dancekit.pipelines.dual import moving_average

    y = (np.arange(6, dtype=np.float64) ** 2)[:, None]  # 0 1 4 9 16 25
    np.testing.assert_allclose(moving_average(y, 3)[:, 0], [0.5, 5 / 3, 14 / 3, 29 / 3, 50 / 3, 20.5])
    np.testing.assert_allclose(moving_average(y, 2)[:, 0], [0.5, 2.5, 6.5, 12.5, 20.5, 25.0])
    assert moving_average(y, 1) is y
    with pytest.raises(ParameterError, match="smooth_frames"):
        moving_average(y, 0)


def test_lowpass_known_answers():
    """The zero-phase Butterworth low-pass: a constant is kept, a sinusoid keeps 1 / (1 + (f / fc)^8) of its
    amplitude (order 4, run forwards and backwards: the squared magnitude response), ½ at the cut-off, with
    no phase shift; short inputs and bad cut-offs."""
    from dancekit.errors import ParameterError
    from dancekit.pipelines.dual import lowpass

    fps, fc = 25.0, 1.5
    t = np.arange(2000) / fps
    np.testing.assert_allclose(lowpass(np.full((50, 3), 2.5), cutoff_hz=fc, fps=fps), 2.5, atol=1e-9)
    for f in (0.5, 1.5, 3.0):
        y = np.sin(2 * np.pi * f * t)[:, None]
        out = lowpass(y, cutoff_hz=fc, fps=fps)[500:-500, 0]  # away from the ends
        gain = 1.0 / (1.0 + (f / fc) ** 8)
        np.testing.assert_allclose(out, gain * y[500:-500, 0], atol=2e-3)
    # a sinusoid below the cut-off plus flicker above it: the flicker is gone, the motion stays
    y = np.sin(2 * np.pi * 0.5 * t) + 0.3 * np.sin(2 * np.pi * 8.0 * t)
    np.testing.assert_allclose(lowpass(y[:, None], cutoff_hz=fc, fps=fps)[500:-500, 0],
                               np.sin(2 * np.pi * 0.5 * t)[500:-500], atol=2e-3)
    assert lowpass(np.ones((1, 4)), cutoff_hz=fc, fps=fps).shape == (1, 4)
    assert lowpass(np.ones((5, 4), np.float32), cutoff_hz=fc, fps=fps).dtype == np.float32
    for bad in (0.0, -1.0, 12.5, 20.0):
        with pytest.raises(ParameterError, match="lowpass_hz"):
            lowpass(np.ones((10, 2)), cutoff_hz=bad, fps=fps)


def test_dance_pipeline_lowpass_setting(tiny_checkpoint, tmp_path):
    """A checkpoint's ``lowpass_hz`` replaces the moving average; explicit arguments override it."""
    import json
    import shutil

    from dancekit.errors import ParameterError
    from dancekit.pipelines.dual import DualPipeline, lowpass, moving_average

    folder = tmp_path / "lowpassed"
    shutil.copytree(tiny_checkpoint, folder)
    meta = json.loads((folder / "config.json").read_text())
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"smooth_frames": 5, "lowpass_hz": 2.0}}))
    pipe = DualPipeline.from_pretrained(folder)
    assert pipe.lowpass_hz == 2.0 and DualPipeline.from_pretrained(tiny_checkpoint).lowpass_hz is None
    y = np.random.default_rng(0).normal(size=(60, 4))
    np.testing.assert_allclose(pipe.output_filter(y), lowpass(y, cutoff_hz=2.0, fps=pipe.fps))
    np.testing.assert_allclose(pipe.output_filter(y, smooth_frames=3), moving_average(y, 3))
    np.testing.assert_allclose(pipe.output_filter(y, lowpass_hz=1.0), lowpass(y, cutoff_hz=1.0, fps=pipe.fps))
    np.testing.assert_allclose(DualPipeline.from_pretrained(tiny_checkpoint).output_filter(y), y)
    with pytest.raises(ParameterError, match="not both"):
        pipe.output_filter(y, smooth_frames=3, lowpass_hz=1.0)


def test_dance_pipeline_smoothing_setting(tiny_checkpoint, tmp_path):
    import json
    import shutil

    from dancekit.errors import CheckpointError
    from dancekit.pipelines.dual import DualPipeline

    folder = tmp_path / "smoothed"
    shutil.copytree(tiny_checkpoint, folder)
    meta = json.loads((folder / "config.json").read_text())
    (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"smooth_frames": 5}}))
    assert DualPipeline.from_pretrained(folder).smooth_frames == 5
    assert DualPipeline.from_pretrained(tiny_checkpoint).smooth_frames == 1
    (folder / "config.json").write_text(json.dumps({**meta, "smooth_frames": 7}))  # the old layout: converted
    assert DualPipeline.from_pretrained(folder).smooth_frames == 7
    for bad in (0, 2.5, "5", True):
        (folder / "config.json").write_text(json.dumps({**meta, "sampling": {"smooth_frames": bad}}))
        with pytest.raises(CheckpointError, match=f"{folder}: config.json: sampling.smooth_frames must be an integer"):
            DualPipeline.from_pretrained(folder)


def test_embedded_dual_model_is_small_float16_and_loads_as_float32():
    from safetensors.numpy import load_file

    from dancekit.checkpoints import resolve_model
    from dancekit.pipelines.dual import ComposePipeline

    folder = resolve_model("dual")
    size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    assert size <= 12e6
    weights = load_file(str(folder / "model.safetensors"))
    assert {v.dtype for k, v in weights.items() if k != "pool_count"} == {np.dtype("float16")}
    pipe = ComposePipeline.from_pretrained("dual")
    assert all(p.dtype == torch.float32 for p in pipe.model.parameters())
    assert pipe.model.pose_pool.dtype == torch.float32 and int(pipe.model.pool_count) > 0


def test_compose_cli_uses_the_embedded_model_by_default(tmp_path):
    from dancekit.cli.main import main
    from dancekit.motion.formats import write_motion

    write_motion(tmp_path / "dance.npz", _real_like_motion(T=50))
    out = tmp_path / "out"
    assert main(["compose", str(tmp_path / "dance.npz"), "-o", str(out), "--render", "builtin", "--no-video",
                 "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["dance.mid", "dance.wav"]


def test_dances_batches_the_seeds_and_equals_one_call_per_seed(tiny_checkpoint, tmp_path):
    """``DualPipeline.dances`` (what ``dancekit evaluate --seeds N`` calls) decodes the seeds as one batch: each
    dance equals the one-seed call with the same seed, and the seeds' start poses give different dances."""
    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy
    from dancekit.pipelines.dual import DualPipeline

    song = tmp_path / "ode.wav"
    save_wav(song, ode_to_joy(sr=22050, bpm=120)[: 3 * 22050], sr=22050)
    pipe = DualPipeline.from_pretrained(tiny_checkpoint)
    with torch.no_grad():  # a pool of start poses, as training fills it
        pipe.model.pose_pool.copy_(torch.randn(pipe.model.pose_pool.shape, generator=torch.Generator().manual_seed(0)))
        pipe.model.pool_count.fill_(pipe.model.pose_pool.shape[0])
    kw = dict(beat_sync=False, cleanup=False, smooth_frames=3)
    batch = pipe.dances(song, seeds=[4, 1], **kw)
    assert [r.seed for r in batch] == [4, 1]
    for seed, result in zip([4, 1], batch):
        one = pipe(song, seed=seed, **kw)
        np.testing.assert_allclose(result.motion.to_positions(), one.motion.to_positions(), atol=1e-3, rtol=1e-3)
    assert np.abs(batch[0].motion.to_positions() - batch[1].motion.to_positions()).max() > 1e-2


def test_embedded_dual_dances_upright_with_its_jitter_cap(tmp_path):
    """The shipped dual decodes its root by Procrustes (docs/DUAL.md): its torso leans like the real tang2018
    dances (6-20 degrees per dance), not the 35-48 degrees of the Gram-Schmidt decode; its jitter cap applies
    to a song that reads as music."""
    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy
    from dancekit.metrics import torso_lean
    from dancekit.pipelines.dual import DualPipeline

    song = tmp_path / "ode.wav"
    save_wav(song, ode_to_joy(sr=22050, bpm=120)[: 12 * 22050], sr=22050)
    pipe = DualPipeline.from_pretrained("dual")
    from dancekit.pipelines.stages import jitter_cap_for

    config = pipe.stage_options()
    assert pipe.root_decode == "procrustes" and config.jitter_cap is not None and config.jitter_cap.to_end
    result = pipe(song, seed=0)
    lean = torso_lean(result.motion.to_positions(), skeleton=result.motion.skeleton)["median_deg"]
    assert lean < 28.0
    assert jitter_cap_for(result, config.jitter_cap, config.genre_stats) > 0



# ---------------------------------------------------------------------------------------------- the latent


def _latent_model(**kw):
    cfg = DualConfig(music_dim=17, music_raw_from=4, pose_dim=15, window=8, m2d_d_model=16, m2d_heads=2, m2d_ff=32,
                     d2m_d_model=8, d2m_heads=2, d2m_ff=16, m2d_layers=1, d2m_layers=1, latent_dim=4, **kw)
    torch.manual_seed(0)
    return DualModel(cfg)


def test_latent_kl_known_answer_and_free_bits():
    model = _latent_model(kl_free_bits=0.0)
    dance = torch.randn(3, 8, 15)
    # a posterior whose last layer outputs mu = 1, log variance = 0 in every dimension: KL = 0.5 * mu² = 0.5 nats
    last = model.m2d_posterior[-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.copy_(torch.tensor([1.0] * 4 + [0.0] * 4))
    model.eval()
    cond, kl = model._posterior(dance)
    assert float(kl.detach()) == pytest.approx(4 * 0.5, rel=1e-6)
    # in eval mode z is the mean: cond is the projection of mu = 1
    expected = model.m2d_latent(torch.ones(1, 4)).expand(3, -1)
    assert torch.allclose(cond, expected, atol=1e-6)
    # free bits: below 0.75 nats a dimension costs 0.75 and passes no gradient
    model = _latent_model(kl_free_bits=0.75)
    with torch.no_grad():
        model.m2d_posterior[-1].weight.zero_()
        model.m2d_posterior[-1].bias.copy_(torch.tensor([1.0] * 4 + [0.0] * 4))
    _, kl = model._posterior(dance)
    assert float(kl.detach()) == pytest.approx(4 * 0.75, rel=1e-6)
    kl.backward()
    assert all(p.grad is None or float(p.grad.abs().max()) == 0.0 for p in model.m2d_posterior.parameters())


def test_latent_reaches_g_m2d_only_and_is_logged():
    model = _latent_model()
    music, dance = torch.randn(4, 8, 17), torch.randn(4, 8, 15)
    loss, parts = model(music, dance)
    assert "kl" in parts
    loss.backward()
    assert model.m2d_latent.weight.grad is not None and float(model.m2d_latent.weight.grad.abs().sum()) > 0
    assert float(model.m2d_posterior[0].weight.grad.abs().sum()) > 0


def test_latent_seeds_give_different_dances_and_a_seed_repeats():
    model = _latent_model()
    music, start = torch.randn(1, 22, 17), torch.randn(1, 15)
    a = model.generate_dance(music, start=start, generator=torch.Generator().manual_seed(0))
    b = model.generate_dance(music, start=start, generator=torch.Generator().manual_seed(1))
    c = model.generate_dance(music, start=start, generator=torch.Generator().manual_seed(0))
    assert torch.equal(a, c)
    # every window after the first frame differs between the seeds (one z per window)
    for s in (1, 8, 15):
        assert float((a[0, s: s + 7] - b[0, s: s + 7]).abs().max()) > 1e-4
    # the window's z is the one the decoder sees: decoding window 1 by hand with the first prior draw gives it
    z = torch.randn(1, 4, generator=torch.Generator().manual_seed(0))
    model.eval()
    with torch.no_grad():
        first = model.m2d.generate(music[:, :8], start, model.m2d_latent(z))
    assert torch.allclose(a[:, :8], first, atol=1e-6)


def test_no_latent_ignores_the_generator():
    cfg = DualConfig(music_dim=17, music_raw_from=4, pose_dim=15, window=8, m2d_d_model=16, m2d_heads=2, m2d_ff=32,
                     d2m_d_model=8, d2m_heads=2, d2m_ff=16, m2d_layers=1, d2m_layers=1)
    model = DualModel(cfg)
    music, start = torch.randn(1, 20, 17), torch.randn(1, 15)
    a = model.generate_dance(music, start=start, generator=torch.Generator().manual_seed(0))
    b = model.generate_dance(music, start=start, generator=torch.Generator().manual_seed(5))
    assert torch.equal(a, b) and not hasattr(model, "m2d_latent")
    with pytest.raises(Exception, match="latent_dim"):
        DualConfig(latent_dim=-1)


def test_a_prefix_is_the_dance_and_the_decoders_context_across_windows():
    """generate_dance(prefix=...): the first N frames (N longer than a window) are the prefix; the frame after it is
    the decoder's output from the prefix as its inputs (known answer: :meth:`Seq2Seq.decode`, the whole-window
    teacher-forced pass, over the window holding the seam)."""
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY)).eval()
    music, dance = _batch(B=1, T=30)
    N = 11  # window 8: windows start at frames 0, 7, 14, ...; the seam (frame 11) is in the second window
    prefix = dance[:, :N]
    with torch.no_grad():
        out = model.generate_dance(music, start=dance[:, 5], prefix=prefix)
        assert out.shape == (1, 30, 15) and torch.equal(out[:, :N], prefix)
        window = music[:, 7:15]
        want = model.m2d.decode(prefix[:, 7:N], model.m2d.encode(window))[:, -1]  # frame N from frames 7..N-1
    torch.testing.assert_close(out[:, N], want, atol=1e-5, rtol=1e-5)
    free = model.generate_dance(music, start=dance[:, 0])
    assert not torch.allclose(free[:, N], out[:, N])
    with pytest.raises(ParameterError, match="prefix"):
        model.generate_dance(music, start=dance[:, 0], prefix=dance[:, :4, :5])


def test_parallel_decoder_reads_only_the_start_pose_and_generates_as_it_trains():
    """m2d_decoder="parallel": a window's frames come from its first frame (and the music, and z) alone, in one
    pass, so the training output and the generated dance are the same numbers (the autoregressive decoder's
    teacher-forced output is not its free-running one: the closed loop differs)."""
    torch.manual_seed(0)
    model = DualModel(DualConfig(**TINY, m2d_decoder="parallel")).eval()
    music, dance = _batch(B=2, T=8)
    with torch.no_grad():
        trained = model._m2d_predict(music, dance, None, None)
        changed = dance.clone()
        changed[:, 1:] += 1.0  # every frame after the first changed: the prediction is the same
        torch.testing.assert_close(model._m2d_predict(music, changed, None, None), trained)
        assert torch.equal(trained[:, 0], dance[:, 0])
        # known answer: each frame is the decoder over the start pose repeated, no causal mask
        memory = model.m2d.encode(music)
        x = model.m2d.tgt_embed(dance[:, :1].expand(2, 7, 15))
        x = x + sinusoidal_encoding(7, 16)
        torch.testing.assert_close(trained[:, 1:], model.m2d.head(model.m2d.decoder(x, memory)))
        for k in range(2):  # one window: the generated dance is the training output
            gen = model.generate_dance(music[k : k + 1], start=dance[k : k + 1, 0])
            torch.testing.assert_close(gen, trained[k : k + 1], atol=1e-5, rtol=1e-5)
    # the autoregressive decoder (the paper's) differs between the two
    ar = DualModel(DualConfig(**TINY)).eval()
    with torch.no_grad():
        gen = ar.generate_dance(music[:1], start=dance[:1, 0])
        assert not torch.allclose(gen, ar._m2d_predict(music[:1], dance[:1], None, None), atol=1e-3)


def test_parallel_decoder_trains_with_the_latent_and_refuses_the_closed_loop_settings():
    model = _latent_model(m2d_decoder="parallel")
    music, dance = torch.randn(4, 8, 17), torch.randn(4, 8, 15)
    loss, parts = model(music, dance)
    assert {"kl", "dance_rec", "dance_cycle"} <= set(parts)
    loss.backward()
    assert float(model.m2d_latent.weight.grad.abs().sum()) > 0
    a = model.generate_dance(music[:1].repeat(1, 3, 1), start=dance[0, :1], generator=torch.Generator().manual_seed(0))
    b = model.generate_dance(music[:1].repeat(1, 3, 1), start=dance[0, :1], generator=torch.Generator().manual_seed(1))
    assert a.shape == (1, 24, 15) and float((a[0, 1:] - b[0, 1:]).abs().min(dim=-1).values.max()) > 0
    for bad in (dict(m2d_decoder="nar"), dict(m2d_decoder="parallel", self_feed=0.5),
                dict(m2d_decoder="parallel", rollout_frames=4)):
        with pytest.raises(ParameterError, match="m2d_decoder|self_feed"):
            DualConfig(**bad)
    with pytest.raises(ParameterError, match="prefix"):
        model.generate_dance(music[:1], start=dance[0, :1], prefix=dance[:1, :3])


def test_posterior_with_positions_tells_the_order_of_a_windows_frames():
    """q(z | window) averages its frames' features: without positions the window's frames in reverse order give the
    same z (a bag of frames); with ``posterior_position`` they do not, and z is the known answer below."""
    dance = torch.randn(2, 8, 15)
    backwards = dance.flip(1)
    bag = _latent_model().eval()
    with torch.no_grad():
        torch.testing.assert_close(bag._posterior(dance)[0], bag._posterior(backwards)[0])
    pos = _latent_model(posterior_position=True).eval()
    with torch.no_grad():
        assert not torch.allclose(pos._posterior(dance)[0], pos._posterior(backwards)[0], atol=1e-4)
        # known answer: the mean over time of last(gelu(first(pose_t) + pe_t))
        first, act, last = pos.m2d_posterior
        mu = last(act(first(dance) + sinusoidal_encoding(8, 16))).mean(1)[:, :4]
        torch.testing.assert_close(pos._posterior(dance)[0], pos.m2d_latent(mu))
    with pytest.raises(ParameterError, match="posterior_position"):
        DualConfig(posterior_position=1)
