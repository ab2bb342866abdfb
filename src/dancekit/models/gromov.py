"""Entropic Gromov-Wasserstein distance between two batches of embeddings (Wu et al., MM 2021, Algorithm 1).

Pure torch, differentiable end to end (autograd through every unrolled iteration), in the log domain so
that large costs (L1 distances between 512-d embeddings reach hundreds; ``exp(-E / 0.2)`` underflows in
float64 well before that) stay finite.

Algorithm 1 of the paper, for music embeddings ``Z^x (m, d_x)`` and dance embeddings ``Z^y (m, d_y)``::

    C_ij = ||z^x_i - z^x_j||_1,   D_ij = ||z^y_i - z^y_j||_1           (L1 cost matrices, m × m)
    π^(0) = uniform
    for l = 1..M:                                                      (projection iterations, M = 20)
        E = D² p 1ᵀ + 1 qᵀ C² - 2 D π^(l-1) Cᵀ                         (= L ⊗ π for the square loss)
        K = exp(-E / ε)
        b = 1;  L times: a = p ⊘ K b,  b = q ⊘ Kᵀ a                    (Sinkhorn, L = 30)
        π^(l) = diag(a) K diag(b)
    GW_ε = Σ_ijkl (D_ik - C_jl)² π_ij π_kl

Rows of ``π`` index the dance batch, columns the music batch, as in the paper. The marginals are those of
Eq. 4, ``p = q = 1/m`` (as in Peyré et al. 2016 and POT). The paper's printed Algorithm 1 writes the
Sinkhorn step with unit marginals (``a = 1 ⊘ K b``), which is the same plan scaled by ``m`` (so an ε
``m`` times smaller and a GW value ``m²`` times larger); ``marginals="unit"`` reproduces that reading.

Relation to POT: ``ot.gromov.entropic_gromov_wasserstein`` runs Sinkhorn on ``2 E`` (its ``gwggrad`` carries
the factor 2 that Peyré et al.'s Prop. 2 omits), so POT's ``epsilon = 2 ε`` gives this function's plan
(tests/models/test_dual.py compares them). POT updates ``v`` before ``u`` in Sinkhorn and this function ``a``
before ``b`` (Algorithm 1); with few iterations the plans differ by that, at convergence they agree.

Scale (``normalize``): ε is absolute. When the costs are much larger than ε (e.g. 8 random 5-d points
with unit spread scaled by 2–3: L1 distances ≈ 10–20 against ε = 0.2) the kernel is so sharp that L = 30
Sinkhorn iterations do not converge and the projections stall at a poor plan (GW(x, x) > 0), and during
training the embeddings' scale drifts, so the loss is noisy (the GW term of a 128-d encoder started near
1000 and jumped by hundreds between steps). ``normalize="mean"`` divides each L1 cost matrix by its mean
off-diagonal entry, which makes GW invariant to the scale of either batch. With the uniform marginals at
ε = 0.2 the normalised costs blur the plan to uniform (a batch is no nearer itself than another batch);
with the printed Algorithm 1's unit marginals (``marginals="unit"``, i.e. an effective ε of 0.2 / m) the
plan resolves: for 16 random 64-d points GW(x, x) = 0.07 against 1.6 for a noisy copy or another batch,
and 30 Sinkhorn iterations give the same value as 300. The dual model trains with ``normalize="mean"``,
``marginals="unit"`` (:class:`dancekit.models.dual.DualConfig`); ``normalize="none"`` is the paper's raw
costs (and the reading tested against POT).
"""

from __future__ import annotations

import math

import torch

from dancekit.errors import ParameterError

MARGINALS = ("uniform", "unit")
NORMALIZE = ("none", "mean")


def l1_cost_matrix(z: torch.Tensor) -> torch.Tensor:
    """Embeddings ``(m, d)`` → pairwise L1 distances ``(m, m)`` (differentiable; subgradient 0 on the diagonal)."""
    if z.ndim != 2:
        raise ParameterError(f"embeddings must have shape (m, d), got {tuple(z.shape)}")
    return (z[:, None, :] - z[None, :, :]).abs().sum(-1)


def entropic_gromov_wasserstein(
    music: torch.Tensor,
    dance: torch.Tensor,
    *,
    epsilon: float = 0.2,
    sinkhorn_iters: int = 30,
    projection_iters: int = 20,
    marginals: str = "uniform",
    normalize: str = "none",
    return_plan: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    """Entropic GW distance between a batch of music embeddings and a batch of dance embeddings (Algorithm 1).

    Parameters
    ----------
    music : (m, d_x) music embeddings ``Z^x``
    dance : (m, d_y) dance embeddings ``Z^y`` (d_y may differ from d_x)
    epsilon : entropic regularisation ε (0.2 in the paper)
    sinkhorn_iters : L, Sinkhorn iterations per projection (30)
    projection_iters : M, projection iterations (20)
    marginals : ``"uniform"`` (p = q = 1/m, Eq. 4) or ``"unit"`` (the printed Algorithm 1: a = 1 ⊘ K b)
    normalize : ``"none"`` (the paper's raw L1 costs) or ``"mean"`` (each cost matrix divided by its mean
        off-diagonal entry: scale-invariant, see the module docstring)
    return_plan : also return the plan π (m, m), rows = dance, columns = music

    Returns
    -------
    The scalar ``Σ (D_ik - C_jl)² π_ij π_kl`` (no entropy term), differentiable in both inputs
    (and the plan when ``return_plan``).
    """
    if music.ndim != 2 or dance.ndim != 2 or music.shape[0] != dance.shape[0]:
        raise ParameterError(f"music and dance embeddings must be (m, d_x) and (m, d_y) with the same m, got "
                             f"{tuple(music.shape)} and {tuple(dance.shape)}")
    if not epsilon > 0 or sinkhorn_iters < 1 or projection_iters < 1:
        raise ParameterError(f"need epsilon > 0 and at least one iteration, got epsilon={epsilon}, "
                             f"L={sinkhorn_iters}, M={projection_iters}")
    if marginals not in MARGINALS:
        raise ParameterError(f"marginals must be one of {MARGINALS}, got {marginals!r}")
    if normalize not in NORMALIZE:
        raise ParameterError(f"normalize must be one of {NORMALIZE}, got {normalize!r}")
    m = music.shape[0]
    C = l1_cost_matrix(music)  # (m, m) music
    D = l1_cost_matrix(dance.to(C.dtype))  # (m, m) dance
    if normalize == "mean" and m > 1:
        tiny = torch.finfo(C.dtype).tiny
        C = C / (C.sum() / (m * (m - 1))).clamp_min(tiny)
        D = D / (D.sum() / (m * (m - 1))).clamp_min(tiny)
    mass = 1.0 if marginals == "unit" else 1.0 / m
    log_p = torch.full((m,), math.log(mass), dtype=C.dtype, device=C.device)  # log p = log q (rows: dance)
    const = (D**2).sum(1, keepdim=True) * mass + (C**2).sum(1)[None, :] * mass  # (m, m): D² p 1ᵀ + 1 qᵀ C²ᵀ
    plan = torch.full((m, m), mass / m, dtype=C.dtype, device=C.device)  # π^(0): uniform with these marginals
    for _ in range(projection_iters):
        E = const - 2.0 * D @ plan @ C.T  # (m, m)
        log_K = -E / epsilon
        log_b = torch.zeros(m, dtype=C.dtype, device=C.device)  # b^(0) = 1
        for _ in range(sinkhorn_iters):
            log_a = log_p - torch.logsumexp(log_K + log_b[None, :], dim=1)  # a = p ⊘ K b
            log_b = log_p - torch.logsumexp(log_K + log_a[:, None], dim=0)  # b = q ⊘ Kᵀ a
        plan = torch.exp(log_a[:, None] + log_K + log_b[None, :])  # diag(a) K diag(b)
    # Σ_ijkl (D_ik - C_jl)² π_ij π_kl = Σ_ij π_ij [(D² r)_i + (C² c)_j - 2 (D π Cᵀ)_ij], r / c the row / column
    # sums of π: the m⁴ tensor is never built
    cost = (D**2 @ plan.sum(1))[:, None] + (C**2 @ plan.sum(0))[None, :]  # (m, m)
    gw = (plan * (cost - 2.0 * D @ plan @ C.T)).sum()
    return (gw, plan) if return_plan else gw
