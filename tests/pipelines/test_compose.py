"""G_D→M's cached decoding and ``ComposePipeline`` with the arranger that follows the dance."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.models.dual import DualConfig, DualModel, chord_token


def _model(layers=2, seed=0):
    cfg = DualConfig(music_dim=17, music_raw_from=4, pose_dim=15, window=12, m2d_d_model=16, m2d_layers=1,
                     m2d_heads=2, m2d_ff=16, d2m_d_model=16, d2m_layers=layers, d2m_heads=4, d2m_ff=32, dropout=0.1)
    torch.manual_seed(seed)
    return DualModel(cfg).eval()


@pytest.mark.parametrize("layers", [1, 2])
def test_cached_rollout_is_the_rollout(layers):
    """The projected-key/value cache decodes the same frames as the plain incremental decoding (to float
    rounding), for a batch of two and a window of 12, with dropout layers present (eval mode)."""
    model = _model(layers)
    net = model.d2m
    src = torch.randn(2, 12, 15)
    start = torch.rand(2, 13)
    with torch.no_grad():
        memory = net.encode(src)
        want = net.rollout(memory, start, 12)
        got = net.rollout_cached(memory, start, 12)
    assert got.shape == want.shape == (2, 12, 13)
    torch.testing.assert_close(got, want, atol=2e-6, rtol=1e-5)
    assert not torch.allclose(got[:, 1:], start[:, None].expand(-1, 11, -1))  # it does decode something
    with torch.no_grad():
        fast = net.rollout_numpy(memory, start, 12)  # the same in NumPy (what composing runs)
    assert fast.dtype == torch.float32 and fast.shape == want.shape
    torch.testing.assert_close(fast, want, atol=2e-6, rtol=1e-5)


def test_generate_music_uses_the_cache_over_windows():
    model = _model(2)
    dance = torch.randn(1, 40, 15)  # 4 windows of 12 overlapping by one
    start = chord_token("A", True)[None]
    got = model.generate_music(dance, start=start)
    want = model._generate(model.d2m, dance, start, cached=False)
    torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)


def test_compose_pipeline_default_follows_the_dance_in_the_printed_key():
    """The embedded dual model composes for a stepping dance: the default arranger reads the steps' tempo,
    and every piano / bass note is in the key of the printed start chord."""
    from dancekit.audio.arrange import key_scale
    from dancekit.motion import Motion, get_skeleton
    from dancekit.pipelines.dual import PITCH_CLASSES, ComposePipeline

    sk = get_skeleton("tang2018")
    fps, T = 25.0, 500
    t = np.arange(T) / fps
    plants = np.arange(0.3, T / fps, 0.6)  # 100 BPM
    speed = 1.0 - np.exp(-0.5 * ((t[:, None] - plants[None]) / 0.06) ** 2).sum(1)
    pos = np.zeros((T, sk.num_joints, 3), np.float32)
    pos[:, :, 1] = 80.0 + 3.0 * np.arange(sk.num_joints)
    pos[:, :, 0] = (np.cumsum(speed) / fps * 30.0)[:, None]
    piece = ComposePipeline.from_pretrained("dual")(Motion(skeleton=sk, fps=fps, positions=pos), seed=5)
    arr = piece.arrangement
    root, mode = piece.start_chord.split()
    assert arr.key == (PITCH_CLASSES.index(root), mode == "minor") and arr.key_name() == piece.start_chord
    assert arr.tempo == pytest.approx(100.0, rel=0.03)
    scale = key_scale(*arr.key)
    notes = [n for inst in arr.midi.instruments if not inst.is_drum for n in inst.notes]
    assert notes and {n.pitch % 12 for n in notes} <= scale
