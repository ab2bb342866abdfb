"""The Foot Constraint Model (Music2Dance §4.5): shapes, the upper body untouched, the objective, the pipeline."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.models.foot_constraint import FootConstraintConfig, FootConstraintModel, gaussian_smooth
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.root_delta import lower_body_cols, rootdelta_layout

SK = get_skeleton("tang2018")


@pytest.fixture(autouse=True)
def _one_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _model(**kw) -> FootConstraintModel:
    torch.manual_seed(0)
    model = FootConstraintModel(FootConstraintConfig(channels=8, lstm_hidden=8, **kw)).double()
    with torch.no_grad():  # the last layer starts at zero (identity): give it weights so the test can see a change
        for p in model.parameters():
            if not p.abs().sum():
                p.normal_(0, 0.1)
    return model


def test_default_columns_are_the_tang2018_lower_body():
    c = FootConstraintConfig()
    lay = rootdelta_layout(SK)
    assert c.lower_idx == lower_body_cols(SK) and len(c.lower_idx) == 6 + 6 * 10
    assert c.foot_idx == lay.toe_cols and c.contact_idx == (153, 154) and c.in_dim == 66 + 6 + 2
    names = {SK.rig().joint_names[j] for j in lay.rot_joints if lay.rot_cols(j)[0] in c.lower_idx}
    assert "left_knee" in names and "pelvis_to_right_hip" in names and not any("shoulder" in n for n in names)


@pytest.mark.parametrize("arch", ["conv", "lstm"])
def test_output_shape_and_upper_body_untouched(arch):
    model = _model(arch=arch)
    x = torch.randn(2, 40, 155, dtype=torch.float64)
    y = model(x)
    assert y.shape == x.shape
    lower = list(model.config.lower_idx)
    others = [i for i in range(155) if i not in set(lower)]
    torch.testing.assert_close(y[..., others], x[..., others], rtol=0, atol=0)  # upper body, effectors, contacts
    path = [rootdelta_layout(SK).root_cols[i] for i in (0, 2, 3)]  # Δt_x, Δt_z, Δr_y: the root's path
    assert path == [lower[0], lower[2], lower[3]]
    torch.testing.assert_close(y[..., path], x[..., path], rtol=0, atol=0)
    legs = [i for i in lower if i not in path]
    assert (y[..., legs] - x[..., legs]).abs().min() > 0  # every other lower-body column is corrected
    free = _model(arch=arch, keep_root_path=False)(x)
    assert (free[..., path] - x[..., path]).abs().max() > 1e-3
    assert model.increment(x).shape == (2, 40, len(lower))


def test_untrained_model_is_the_identity():
    model = FootConstraintModel(FootConstraintConfig(channels=8))
    x = torch.randn(1, 30, 155)
    assert torch.equal(model(x), x)


def test_conv_receptive_field_is_27_frames_centred():
    model = _model()
    x = torch.zeros(1, 60, 155, dtype=torch.float64)
    base = model.increment(x)
    x[0, 30, list(model.config.lower_idx)] = 1.0
    changed = (model.increment(x) - base).abs().sum(-1)[0] > 0  # (T,)
    assert changed.nonzero().flatten().tolist() == list(range(30 - 13, 30 + 14))  # 1 + 2·(1 + 3 + 9)


def test_gaussian_smooth_keeps_constants_and_lowers_noise(rng):
    x = torch.from_numpy(rng.normal(size=(1, 200, 3)))
    torch.testing.assert_close(gaussian_smooth(torch.ones(1, 50, 2), 2.0), torch.ones(1, 50, 2))
    assert gaussian_smooth(x, 2.0).std() < 0.5 * x.std()


@pytest.mark.parametrize("corruption", ["glide", "paper"])
def test_objective_corrupts_the_lower_body_and_the_model_can_undo_it(corruption):
    from dancekit.training import StepContext, TrainConfig
    from dancekit.training.m2d import foot_constraint_step

    t = torch.linspace(0, 6, 48, dtype=torch.float64)
    x = torch.sin(t[None, :, None] * torch.linspace(0.5, 3, 155, dtype=torch.float64)).repeat(2, 1, 1)
    ctx = StepContext(step=0, epoch=0, training=True, generator=torch.Generator().manual_seed(0), config=TrainConfig())
    kw = dict(clean_share=0.0, contact_weight=0.0, corruption=corruption)  # the MSE alone (contacts: below)
    identity = FootConstraintModel(FootConstraintConfig(channels=8, **kw)).double()
    loss, logs = foot_constraint_step(identity, {"dance": x}, ctx)
    assert logs["mse_input"] > 0.005 and logs["mse"] == pytest.approx(logs["mse_input"])  # identity: no fix
    model = FootConstraintModel(FootConstraintConfig(channels=16, **kw)).double()
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(60):
        ctx.generator.manual_seed(0)  # the same corruption every step: the model can learn to undo it
        loss, logs = foot_constraint_step(model, {"dance": x}, ctx)
        first = first if first is not None else logs["mse"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert logs["mse"] < 0.75 * first and logs["mse"] < logs["mse_input"]


def test_objective_leaves_a_clean_share_of_the_windows_alone():
    from dancekit.training import StepContext, TrainConfig
    from dancekit.training.m2d import foot_constraint_step

    t = torch.linspace(0, 6, 48, dtype=torch.float64)
    wave = torch.sin(t[None, :, None] * torch.linspace(0.5, 3, 155, dtype=torch.float64))
    x = wave.repeat(400, 1, 1)
    ctx = StepContext(step=0, epoch=0, training=True, generator=torch.Generator().manual_seed(0), config=TrainConfig())
    clean = FootConstraintModel(FootConstraintConfig(channels=8, clean_share=1.0)).double()
    assert foot_constraint_step(clean, {"dance": x[:4]}, ctx)[1]["mse_input"] == 0.0
    slid = foot_constraint_step(FootConstraintModel(FootConstraintConfig(channels=8, clean_share=0.0)).double(),
                                {"dance": x}, ctx)[1]["mse_input"]
    half = foot_constraint_step(FootConstraintModel(FootConstraintConfig(channels=8, clean_share=0.25)).double(),
                                {"dance": x}, ctx)[1]["mse_input"]
    assert half / slid == pytest.approx(0.75, abs=0.07)  # 400 windows: 3/4 ± 3 binomial standard deviations


def test_pipeline_post_processes_a_motion_in_place(tmp_path, rng):
    from dancekit.checkpoints import NormStats, save_pretrained
    from dancekit.motion.kinematics import rig_forward_kinematics
    from dancekit.motion.root_delta import encode_rootdelta
    from dancekit.pipelines.foot_constraint import FootConstraintPipeline

    T = 50
    R = np.broadcast_to(np.eye(3), (T, SK.rig().num_joints, 3, 3)).copy()
    tr = np.stack([np.linspace(0, 50, T), np.full(T, 90.0), np.zeros(T)], -1)
    pos = rig_forward_kinematics(R, tr, SK).numpy()
    motion = Motion(skeleton=SK, fps=25.0, positions=pos.astype(np.float32))
    std = np.full(155, 0.05, np.float32)
    std[-2:] = 1.0
    mean = encode_rootdelta(motion).mean(0).astype(np.float32)
    mean[-2:] = 0.0
    model = _model().float()
    stats = NormStats(music_mean=np.zeros(15, np.float32), music_std=np.ones(15, np.float32),
                      dance_mean=mean, dance_std=std)
    save_pretrained(tmp_path / "fc", model, model.config, stats=stats, extra={"skeleton": SK.to_dict(), "fps": 25.0})
    pipe = FootConstraintPipeline.from_pretrained(tmp_path / "fc")
    out = pipe(motion)
    assert out.num_frames == T and out.fps == 25.0
    np.testing.assert_allclose(out.root_translation[0, [0, 2]], pos[0, SK.root, [0, 2]], atol=1e-3)  # in place
    assert np.abs(out.to_positions() - pos).max() > 1e-3  # the model did correct something
    assert np.abs(out.to_positions() - pos).max() < 20.0


def test_dance_cli_foot_constraint_option(tmp_path, capsys):
    """`dancekit dance --foot-constraint MODEL` corrects the lower body of any model's dance on the skeleton,
    leaves the upper body's rotations alone; a folder that is no foot model is a one-line error."""
    from dancekit.audio import save_wav, synth
    from dancekit.checkpoints import NormStats, save_pretrained
    from dancekit.cli.main import main
    from dancekit.models.music2dance import Music2DanceConfig, Music2DanceModel
    from dancekit.motion.formats import read_motion
    from dancekit.pipelines.foot_constraint import foot_constraint_folder

    lay = rootdelta_layout(SK)
    stats = NormStats(music_mean=np.zeros(15, np.float32), music_std=np.ones(15, np.float32),
                      dance_mean=np.zeros(lay.dim, np.float32), dance_std=np.full(lay.dim, 0.05, np.float32))
    stats.dance_mean[1], stats.dance_std[1] = 90.0, 1.0  # root height, cm
    stats.dance_std[list(lay.contact_cols)] = 1.0
    meta = {"skeleton": SK.to_dict(), "fps": 25.0, "representation": "rotations_rootdelta", "preset": "music2dance",
            "hop_length": 512}
    torch.manual_seed(0)
    cfg = Music2DanceConfig(pose_dim=lay.dim, n_genres=0, n_layers=2, channels=4, skip_channels=4, genre_dim=2,
                            fmap_channels=(2, 2, 2), fmap_lstm_hidden=2)
    dancer = save_pretrained(tmp_path / "m2d", Music2DanceModel(cfg), cfg, stats=stats,
                             extra={**meta, "sampling": {"temperature": 0.0}})
    fc = _model().float()
    save_pretrained(tmp_path / "fc", fc, fc.config, stats=stats, extra=meta)
    assert foot_constraint_folder(tmp_path / "fc") == tmp_path / "fc"
    song = tmp_path / "tune.wav"
    save_wav(song, synth.ode_to_joy(sr=22050)[: 2 * 22050], sr=22050)
    runs = {}
    for label, extra in (("plain", []), ("fixed", ["--foot-constraint", str(tmp_path / "fc")])):
        code = main(["dance", str(song), "-o", str(tmp_path / label), "--checkpoint", str(dancer), "--quiet",
                     "--format", "npz", *extra])
        assert code == 0
        runs[label] = read_motion(tmp_path / label / "tune.npz")
    legs = [j for j in range(SK.rig().num_joints) if "knee" in SK.rig().joint_names[j]]
    arms = [j for j in range(SK.rig().num_joints) if "elbow" in SK.rig().joint_names[j]]
    assert legs and arms
    a, b = runs["plain"].rotations, runs["fixed"].rotations
    assert np.abs(a[:, legs] - b[:, legs]).max() > 1e-3  # the legs are corrected
    np.testing.assert_allclose(a[:, arms], b[:, arms], atol=1e-5)  # the arms are not
    capsys.readouterr()
    out = tmp_path / "bad"
    assert main(["dance", str(song), "-o", str(out), "--checkpoint", str(dancer), "--foot-constraint", str(dancer)]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a Foot Constraint Model" in err and not out.exists()


def _toes_moving(v_m_s: float, T: int = 26, fps: float = 25.0) -> torch.Tensor:
    """Two toes ``(1, T, 2, 3)`` (metres): the left one still, the right one moving along x at ``v_m_s``."""
    toes = torch.zeros(1, T, 2, 3, dtype=torch.float64)
    toes[0, :, 1, 0] = v_m_s * torch.arange(T, dtype=torch.float64) / fps
    return toes


def test_contact_velocity_loss_known_answers():
    from dancekit.models.foot_constraint import contact_velocity_loss

    on = torch.ones(1, 26, 2, dtype=torch.float64)
    assert float(contact_velocity_loss(_toes_moving(0.0), on, fps=25.0)) == 0.0  # planted feet cost nothing
    # the right toe glides at 0.5 m/s through its contact, the left stands: mean over both toes' steps 0.25 / 2
    assert float(contact_velocity_loss(_toes_moving(0.5), on, fps=25.0)) == pytest.approx(0.125, rel=1e-12)
    right = on.clone()
    right[..., 0] = 0.0  # only the moving toe in contact: exactly v² = 0.25 (m/s)²
    assert float(contact_velocity_loss(_toes_moving(0.5), right, fps=25.0)) == pytest.approx(0.25, rel=1e-12)
    assert float(contact_velocity_loss(_toes_moving(0.5), torch.zeros_like(on), fps=25.0)) == 0.0  # no contact
    # a step counts only when the toe is in contact at both ends: contact on frames 0-9 → steps 0→1 ... 8→9
    part = torch.zeros_like(on)
    part[0, :10, 1] = 1.0
    toes = _toes_moving(0.5)
    toes[0, 10:, 1, 0] += 1.0  # a jump on leaving the contact (step 9→10): not a contact step
    assert float(contact_velocity_loss(toes, part, fps=25.0)) == pytest.approx(0.25, rel=1e-12)


def test_contact_velocity_loss_pulls_a_gliding_foot_to_a_stop():
    from dancekit.models.foot_constraint import contact_velocity_loss

    toes = _toes_moving(0.5).requires_grad_(True)
    contact_velocity_loss(toes, torch.ones(1, 26, 2, dtype=torch.float64), fps=25.0).backward()
    g = toes.grad[0, :, 1, 0]
    assert g[0] < 0 < g[-1] and toes.grad[0, :, 0].abs().max() == 0  # first frame forward, last back; still toe: 0


def _legs_moving(v_left: float, v_right: float, T: int = 26, K: int = 4, fps: float = 25.0) -> torch.Tensor:
    """Leg joints ``(1, T, 2, K, 3)`` (metres): every joint of the left leg moving along z at ``v_left`` m/s,
    of the right leg along x at ``v_right``."""
    legs = torch.zeros(1, T, 2, K, 3, dtype=torch.float64)
    steps = torch.arange(T, dtype=torch.float64)[:, None] / fps
    legs[0, :, 0, :, 2] = v_left * steps
    legs[0, :, 1, :, 0] = v_right * steps
    return legs


def test_swing_speed_loss_known_answers():
    from dancekit.models.foot_constraint import swing_speed_loss

    off = torch.zeros(1, 26, 2, dtype=torch.float64)
    target = _legs_moving(0.5, 0.5)
    assert float(swing_speed_loss(target, target, off, fps=25.0)) == 0.0  # as fast as the target: free
    assert float(swing_speed_loss(_legs_moving(0.8, 0.9), target, off, fps=25.0)) == 0.0  # faster: free too
    # both legs still where the target's move at 0.5 m/s: 0.5² = 0.25 (m/s)²
    assert float(swing_speed_loss(_legs_moving(0.0, 0.0), target, off, fps=25.0)) == pytest.approx(0.25, rel=1e-6)
    # left at 0.2, right at 0.5 where the target's left moves at 0.5: shortfall 0.3 on half the terms → 0.09 / 2
    assert float(swing_speed_loss(_legs_moving(0.2, 0.5), target, off, fps=25.0)) == pytest.approx(0.045, rel=1e-6)
    # the direction does not matter, only the speed: the right leg moving along z at the target's speed is free
    turned = _legs_moving(0.5, 0.0)
    turned[0, :, 1, :, 2] = 0.5 * torch.arange(26, dtype=torch.float64)[:, None] / 25.0
    assert float(swing_speed_loss(turned, target, off, fps=25.0)) == pytest.approx(0.0, abs=1e-12)
    # steps on which the toe is in contact at both ends do not count: left planted all along → the right alone
    left = off.clone()
    left[..., 0] = 1.0
    assert float(swing_speed_loss(_legs_moving(0.0, 0.3), target, left, fps=25.0)) == pytest.approx(0.04, rel=1e-6)
    assert float(swing_speed_loss(_legs_moving(0.0, 0.0), target, torch.ones_like(off), fps=25.0)) == 0.0


def test_swing_speed_loss_speeds_a_slow_leg_up():
    from dancekit.models.foot_constraint import swing_speed_loss

    legs = _legs_moving(0.0, 0.25).requires_grad_(True)
    swing_speed_loss(legs, _legs_moving(0.0, 0.5), torch.zeros(1, 26, 2, dtype=torch.float64), fps=25.0).backward()
    g = legs.grad[0, :, 1, :, 0]  # right leg along its motion: first frame pulled back, last pushed on (faster)
    assert (g[0] > 0).all() and (g[-1] < 0).all() and legs.grad[0, :, 0].abs().max() == 0  # left: as fast as its target


def test_objective_swing_term_is_logged_and_weighted():
    from dancekit.training import StepContext, TrainConfig
    from dancekit.training.m2d import foot_constraint_step

    rng = torch.Generator().manual_seed(3)
    x = 0.3 * torch.randn(2, 40, 155, generator=rng, dtype=torch.float64)
    x[..., -2:] = 0.0  # no contacts: every step counts

    def run(weight: float) -> tuple[float, dict]:
        ctx = StepContext(step=0, epoch=0, training=True, generator=torch.Generator().manual_seed(0),
                          config=TrainConfig())
        torch.manual_seed(0)
        model = FootConstraintModel(FootConstraintConfig(channels=8, clean_share=0.0, contact_weight=0.0,
                                                         swing_weight=weight)).double()
        loss, logs = foot_constraint_step(model, {"dance": x}, ctx)
        return float(loss.detach()), logs

    base, _ = run(0.0)
    loss, logs = run(2.0)
    assert logs["swing_short2"] > 0  # the glide changes the legs' speeds: some joints are slower than the target's
    assert loss == pytest.approx(base + 2.0 * logs["swing_short2"], rel=1e-9)


def test_detect_contacts_reads_height_and_speed():
    from dancekit.models.foot_constraint import detect_contacts

    T, fps = 50, 25.0
    feet = torch.zeros(T, 2, 3, dtype=torch.float64)  # left toe, right toe (skeleton units: cm)
    feet[:, 1, 0] = 200.0 * torch.arange(T, dtype=torch.float64) / fps  # right toe: 2 m/s along the floor
    c = detect_contacts(feet, (0, 1), fps=fps, unit_scale=0.01, speed_m_s=1.0)
    assert c.shape == (T, 2) and c[:, 0].min() == 1 and c[:, 1].max() == 0
    assert detect_contacts(feet, (0, 1), fps=fps, unit_scale=0.01, speed_m_s=3.0)[:, 1].min() == 1
    feet[:, 0, 1] = 10.0  # left toe 10 cm above the right one (the floor): not in contact
    assert detect_contacts(feet, (0, 1), fps=fps, unit_scale=0.01, speed_m_s=3.0)[:, 0].max() == 0


def test_rootdelta_positions_is_decode_rootdelta_in_torch(rng):
    from dancekit.motion.root_delta import decode_rootdelta, rootdelta_positions

    T = 30
    x = rng.normal(size=(T, 155))
    x[:, [0, 2]] *= 3.0  # steps of a few cm
    x[:, 1] += 90.0
    want = decode_rootdelta(x, SK, 25.0).to_positions()
    got = rootdelta_positions(torch.from_numpy(x), SK)
    np.testing.assert_allclose(got.numpy(), want, atol=1e-9)
    toes = (SK.index("left_toe"), SK.index("right_toe"))
    np.testing.assert_allclose(rootdelta_positions(torch.from_numpy(x)[None], SK, joints=toes)[0].numpy(),
                               want[:, list(toes)], atol=1e-9)
    xt = torch.from_numpy(x).requires_grad_(True)
    rootdelta_positions(xt, SK, joints=toes).sum().backward()
    lower = set(lower_body_cols(SK))
    upper = [i for i in range(6, 155) if i not in lower]
    assert xt.grad[:, upper].abs().max() == 0 and xt.grad[:, sorted(lower)].abs().max() > 0  # only the legs move toes


# --- the contact-gated two-head model (issue 13, fcm3) ---------------------------------------------------------

def _contacts_input(model: FootConstraintModel, left: list[int], right: list[int], T: int) -> torch.Tensor:
    """Random motion ``(1, T, 155)`` whose normalised contact columns read back as the 0/1 flags given."""
    c = model.config
    x = torch.randn(1, T, c.pose_dim, dtype=torch.float64)
    for k, flags in enumerate((left, right)):
        x[0, :, c.contact_idx[k]] = (torch.tensor(flags, dtype=torch.float64) - c.contact_mean[k]) / c.contact_std[k]
    return x


def test_gate_weights_known_answer():
    """A left contact from frame 10 on, none on the right; raised-cosine window of 5 frames: sin²(πk/6),
    k = 1..5, is (1/4, 3/4, 1, 3/4, 1/4), sum 3, so the weight climbs 0, 1/12, 1/3, 2/3, 11/12, 1 over
    frames 7..12 (worked by hand)."""
    T = 20
    model = _model(gate=True, gate_frames=5, contact_mean=(0.4, 0.3), contact_std=(0.5, 0.45))
    x = _contacts_input(model, [0] * 10 + [1] * 10, [0] * T, T)
    w = model.gate_weights(x)[0]  # (T, lower)
    sides = model.side
    left, right, shared = (w[:, sides == k] for k in (0, 1, 2))
    expect = torch.tensor([0.0] * 8 + [1 / 12, 1 / 3, 2 / 3, 11 / 12] + [1.0] * 8, dtype=torch.float64)
    torch.testing.assert_close(left, expect[:, None].expand_as(left), rtol=0, atol=1e-6)
    torch.testing.assert_close(shared, expect[:, None].expand_as(shared), rtol=0, atol=1e-6)  # gate_root "any"
    assert right.abs().max() == 0
    names = SK.rig().joint_names
    lay = rootdelta_layout(SK)
    knee = lay.rot_cols(names.index("left_knee"))[0]
    assert int(sides[list(model.config.lower_idx).index(knee)]) == 0 and (sides == 2).sum() == 6 + 12
    own = _model(gate=True, gate_frames=5, gate_root="swing", contact_mean=(0.4, 0.3), contact_std=(0.5, 0.45))
    assert own.gate_weights(x)[0][:, sides == 2].abs().max() == 0  # the root follows the swing head


def test_gated_increment_blends_the_two_heads():
    """All contacts on: the plant head's increment x strength; all off: the swing head's x swing_strength;
    in between the blend by the gate weights; the upper body is untouched either way."""
    T = 30
    model = _model(gate=True, strength=0.5, swing_strength=0.25, keep_root_path=False)
    plant = FootConstraintModel(FootConstraintConfig(channels=8, keep_root_path=False)).double()
    swing = FootConstraintModel(FootConstraintConfig(channels=8, keep_root_path=False)).double()
    plant.convs.load_state_dict(model.convs.state_dict())
    swing.convs.load_state_dict(model.swing_convs.state_dict())
    for flags, expect in ((1, lambda x: 0.5 * plant.increment(x)), (0, lambda x: 0.25 * swing.increment(x))):
        x = _contacts_input(model, [flags] * T, [flags] * T, T)
        torch.testing.assert_close(model.increment(x), expect(x), rtol=0, atol=1e-12)
    x = _contacts_input(model, [0] * 12 + [1] * 18, [1] * 5 + [0] * 25, T)
    w = model.gate_weights(x)
    assert ((w > 0) & (w < 1)).any()
    torch.testing.assert_close(model.increment(x), w * 0.5 * plant.increment(x) + (1 - w) * 0.25 * swing.increment(x),
                               rtol=0, atol=1e-12)
    y = model(x)
    others = [i for i in range(155) if i not in set(model.config.lower_idx)]
    torch.testing.assert_close(y[..., others], x[..., others], rtol=0, atol=0)
    assert y.shape == x.shape


def test_compose_gated_checkpoint(tmp_path):
    """Two saved foot models → one gated checkpoint whose pipeline model is their blend and whose config.json
    records both heads; heads of other columns are refused."""
    from dancekit.checkpoints import NormStats, save_pretrained
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.foot_constraint import FootConstraintPipeline, compose_gated

    rng = np.random.default_rng(0)
    stats = NormStats(music_mean=np.zeros(15, np.float32), music_std=np.ones(15, np.float32),
                      dance_mean=rng.normal(size=155).astype(np.float32),
                      dance_std=rng.uniform(0.5, 1.5, 155).astype(np.float32))
    meta = {"skeleton": SK.to_dict(), "fps": 25.0}
    heads = {}
    for k, name in enumerate(("plant", "swing")):
        torch.manual_seed(k)
        m = _model(keep_root_path=False).float()
        save_pretrained(tmp_path / name, m, m.config, stats=stats, extra={**meta, "train": {"steps": 10 + k}})
        heads[name] = m
    out = compose_gated(tmp_path / "plant", tmp_path / "swing", tmp_path / "gated", gate_frames=3, strength=0.5)
    pipe = FootConstraintPipeline.from_pretrained(out)
    c = pipe.model.config
    assert c.gate and c.gate_frames == 3 and c.strength == 0.5
    np.testing.assert_allclose(c.contact_mean, stats.dance_mean[[153, 154]], rtol=1e-6)
    import json
    doc = json.loads((out / "config.json").read_text())
    assert doc["heads"]["plant"]["train"]["steps"] == 10 and doc["heads"]["swing"]["train"]["steps"] == 11
    x = _contacts_input(pipe.model.double(), [0] * 10 + [1] * 10, [1] * 20, 20).float()
    pipe.model.float()
    w = pipe.model.gate_weights(x)
    expect = w * 0.5 * heads["plant"].increment(x) + (1 - w) * heads["swing"].increment(x)
    torch.testing.assert_close(pipe.model.increment(x), expect, rtol=1e-5, atol=1e-6)
    other = FootConstraintModel(FootConstraintConfig(channels=4))
    save_pretrained(tmp_path / "other", other, other.config, stats=stats, extra=meta)
    with pytest.raises(CheckpointError, match="swing head"):
        compose_gated(tmp_path / "plant", tmp_path / "other", tmp_path / "bad")
    assert not (tmp_path / "bad").exists()


def test_objective_mse_to_the_input():
    """``mse_target="input"``: an untrained model (the identity) on corrupted windows costs only its smoothness
    term (it returns its input); with the clean target it also pays the corruption's MSE (logged as mse)."""
    from dancekit.training import StepContext, TrainConfig
    from dancekit.training.m2d import foot_constraint_step

    rng = torch.Generator().manual_seed(3)
    x = 0.3 * torch.randn(2, 40, 155, generator=rng, dtype=torch.float64)
    x[..., -2:] = 0.0

    def run(target: str, smooth: float) -> tuple[float, dict]:
        ctx = StepContext(step=0, epoch=0, training=True, generator=torch.Generator().manual_seed(0),
                          config=TrainConfig())
        model = FootConstraintModel(FootConstraintConfig(channels=8, clean_share=0.0, contact_weight=0.0,
                                                         smooth_weight=smooth, mse_target=target)).double()
        loss, logs = foot_constraint_step(model, {"dance": x}, ctx)
        return float(loss.detach()), logs

    loss, logs = run("input", 0.0)
    assert loss == 0.0 and logs["mse"] > 1e-3  # the identity fits its input; the clean dance it does not
    clean, clogs = run("clean", 0.0)
    assert clean == pytest.approx(clogs["mse"], rel=1e-12) and clean == pytest.approx(logs["mse"], rel=1e-12)
    assert run("input", 0.1)[0] > 0  # the smoothness term still counts
    with pytest.raises(Exception, match="mse_target"):
        FootConstraintConfig(mse_target="target")
