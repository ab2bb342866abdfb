"""The velocity and speed terms of Dance Revolution's training loss (RevolutionConfig.velocity_weight / speed_weight)."""

import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel


def _model(**kw) -> RevolutionModel:
    return RevolutionModel(RevolutionConfig(music_dim=4, pose_dim=3, d_model=8, n_heads=2, d_ff=16, window=4,
                                            decoder_hidden=8, dropout=0.0, **kw))


def test_the_terms_have_their_hand_computed_values():
    # one window, one coordinate: ŷ = 0, 1, 1, 3 (Δ 1, 0, 2) against y = 0, 0, 2, 2 (Δ 0, 2, 0)
    pred = torch.tensor([0.0, 1.0, 1.0, 3.0]).view(1, 4, 1).expand(1, 4, 3)
    dance = torch.tensor([0.0, 0.0, 2.0, 2.0]).view(1, 4, 1).expand(1, 4, 3)
    # velocity: mean(|1-0|, |0-2|, |2-0|) = 5/3; speed: |mean(1, 0, 2) - mean(0, 2, 0)| = |1 - 2/3| = 1/3
    assert _model().motion_loss(pred, dance).item() == 0.0
    assert _model(velocity_weight=2.0).motion_loss(pred, dance).item() == pytest.approx(10 / 3)
    assert _model(speed_weight=3.0).motion_loss(pred, dance).item() == pytest.approx(1.0)
    both = _model(velocity_weight=2.0, speed_weight=3.0).motion_loss(pred, dance).item()
    assert both == pytest.approx(10 / 3 + 1.0)


def test_the_kinetic_term_has_its_hand_computed_value_and_weighs_bursts():
    # ŷ Δ = 1, 0, 2 (rms sqrt(5/3)) against y Δ = 0, 2, 0 (rms sqrt(4/3)): |1.29099 - 1.15470| = 0.13629
    pred = torch.tensor([0.0, 1.0, 1.0, 3.0]).view(1, 4, 1).expand(1, 4, 3)
    dance = torch.tensor([0.0, 0.0, 2.0, 2.0]).view(1, 4, 1).expand(1, 4, 3)
    want = (5 / 3) ** 0.5 - (4 / 3) ** 0.5
    assert _model(kinetic_weight=2.0).motion_loss(pred, dance).item() == pytest.approx(2 * want, rel=1e-5)
    # a steady drift (Δ 1, 1, 1, 1) and a burst (Δ 0, 0, 0, 4) move as far: the speed term sees no difference,
    # the kinetic one does (rms 1 against 2)
    steady = torch.arange(5, dtype=torch.float32).view(1, 5, 1).expand(1, 5, 3)
    burst = torch.tensor([0.0, 0.0, 0.0, 0.0, 4.0]).view(1, 5, 1).expand(1, 5, 3)
    assert _model(speed_weight=1.0).motion_loss(steady, burst).item() == pytest.approx(0.0, abs=1e-7)
    assert _model(kinetic_weight=1.0).motion_loss(steady, burst).item() == pytest.approx(1.0, rel=1e-5)


def test_the_speed_term_ignores_phase_and_the_velocity_term_does_not():
    t = torch.arange(40, dtype=torch.float32)
    y = torch.sin(t / 3).view(1, 40, 1).expand(1, 40, 3)
    shifted = torch.sin(t / 3 + 1.5).view(1, 40, 1).expand(1, 40, 3)
    calm = 0.3 * y
    speed = _model(speed_weight=1.0)
    velocity = _model(velocity_weight=1.0)
    # a phase shift moves as much (speed term ~0) but with other velocities; a calm copy moves less
    assert speed.motion_loss(shifted, y).item() < 0.02
    assert velocity.motion_loss(shifted, y).item() > 0.1
    assert speed.motion_loss(calm, y).item() > 0.1


def test_forward_adds_the_terms_to_the_l1_loss():
    torch.manual_seed(0)
    music, dance = torch.randn(2, 12, 4), torch.randn(2, 12, 3)
    plain = _model().eval()
    lively = _model(velocity_weight=1.0, speed_weight=1.0).eval()
    lively.load_state_dict(plain.state_dict())
    pred, loss = plain(music, dance, generator=torch.Generator().manual_seed(1))
    pred2, loss2 = lively(music, dance, generator=torch.Generator().manual_seed(1))
    assert torch.equal(pred, pred2)
    assert loss2.item() == pytest.approx(loss.item() + lively.motion_loss(pred, dance).item(), rel=1e-6)
    assert loss2.item() > loss.item()


def test_negative_weights_are_refused():
    with pytest.raises(ParameterError, match="velocity_weight"):
        RevolutionConfig(velocity_weight=-1.0)
    with pytest.raises(ParameterError, match="kinetic_weight"):
        RevolutionConfig(kinetic_weight=-0.5)
