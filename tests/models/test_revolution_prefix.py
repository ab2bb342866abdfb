"""A Dance Revolution dance that continues given poses (issue 44, ``--prefix``): the decoder fed the prefix as its
previous poses (teacher forcing), the dance continuing from the prefix's last pose."""

from __future__ import annotations

import pytest
import torch

from dancekit.errors import ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel, SeedVariety, decode_seeds

D, P, N, T = 8, 6, 7, 30  # music dim, pose dim, prefix frames, song frames


def model(seed: int = 0) -> RevolutionModel:
    torch.manual_seed(seed)
    return RevolutionModel(RevolutionConfig(music_dim=D, pose_dim=P, d_model=16, n_heads=2, d_ff=32, window=6,
                                            decoder_hidden=24, decoder_layers=2, dropout=0.0)).eval()


def latents(m: RevolutionModel) -> torch.Tensor:
    music = torch.randn(1, T, D, generator=torch.Generator().manual_seed(7))
    with torch.no_grad():
        return m._latents(music, None)  # (1, T, d)


def prefix() -> torch.Tensor:
    return torch.randn(1, N, P, generator=torch.Generator().manual_seed(3))


@torch.no_grad()
def test_the_prefix_is_kept_and_the_decoder_state_is_built_from_it():
    """Known answer from the decoder run as one ``nn.LSTM`` pass (not the step loop): frames [0, N) are the prefix,
    and frame N is the model's prediction from the inputs [begin-of-pose, prefix[0], ..., prefix[N - 1]]."""
    m, pre = model(), prefix()
    z = latents(m)
    y = m._decode(z, torch.Generator().manual_seed(5), SeedVariety(), device="cpu", prefix=pre)  # (1, T, P)
    assert torch.equal(y[:, :N], pre)
    state = m.initial_state(1, generator=torch.Generator().manual_seed(5), device="cpu")
    inputs = torch.cat([m.bop.expand(1, 1, -1), pre], dim=1)  # (1, N + 1, P): the pose before each frame
    want, _ = m._step(inputs, z[:, : N + 1], state)  # (1, N + 1, P), teacher forcing in one pass
    torch.testing.assert_close(y[:, N], want[:, N], rtol=1e-5, atol=1e-5)
    # and the dance goes on from there as the model's own steps from frame N
    free = m._decode(z, torch.Generator().manual_seed(5), SeedVariety(), device="cpu")
    assert not torch.allclose(free[:, N], y[:, N])


@torch.no_grad()
def test_prefixed_rows_decoded_together_equal_each_row_alone():
    """decode_seeds with prefixes: rows of one architecture in one frame loop (and in two lanes) give each row's
    dance alone, bit for bit, with the seed variety's phrase noise on."""
    models = [model(0), model(1), model(0)]
    zs = [latents(m) for m in models]
    pres = [prefix(), prefix() * 0.5, prefix()]
    variety = SeedVariety(phrase=5, state_noise=0.3)
    together = decode_seeds(models, zs, [torch.Generator().manual_seed(s) for s in (0, 1, 2)], variety,
                            prefixes=pres, workers=2)
    for k, (m, z, pre) in enumerate(zip(models, zs, pres)):
        alone = m._decode(z, [torch.Generator().manual_seed(k)], variety, device="cpu", prefix=pre)
        assert torch.equal(together[k : k + 1], alone)
        assert torch.equal(together[k, :N], pre[0])


def test_prefixes_of_other_shapes_are_refused():
    m = model()
    with pytest.raises(ParameterError, match="prefixes"):
        decode_seeds([m, m], [latents(m)] * 2, [torch.Generator(), torch.Generator()],
                     prefixes=[prefix(), prefix()[:, :3]])
