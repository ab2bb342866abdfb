"""Stateless schedules: pure functions of the epoch or step, kept outside the models.

* :func:`auto_condition_p` — the length ``p`` of the generated runs of the dynamic auto-condition
  curriculum (Dance Revolution §3.3 and Table 3): ``const``, ``⌊λt⌋``, ``⌊λt²⌋``, ``⌊λeᵗ⌋``.
* :func:`learning_rate` — linear warm-up then cosine decay (or a constant rate).
"""

from __future__ import annotations

import math

from dancekit.errors import ParameterError

CURRICULA = ("teacher_forcing", "const", "linear", "quadratic", "exponential")
LR_SCHEDULES = ("cosine", "constant")


def auto_condition_p(
    epoch: int,
    *,
    kind: str = "linear",
    lam: float = 0.01,
    p_const: int = 10,
    p_max: int | None = None,
) -> int:
    """Number of generated frames per period of the decoder input at training epoch ``epoch``.

    Parameters
    ----------
    epoch : t, the number of completed training epochs (>= 0)
    kind : ``"teacher_forcing"`` (always 0), ``"const"`` (``p_const``, the static auto-condition of
        Li et al. 2017), ``"linear"`` (⌊λt⌋, the paper's choice), ``"quadratic"`` (⌊λt²⌋) or
        ``"exponential"`` (⌊λeᵗ⌋)
    lam : λ, how fast p grows (the paper uses 0.01 with its epochs of ~700 one-minute clips)
    p_const : p of the ``"const"`` kind
    p_max : upper bound on p (None: unbounded)

    Returns
    -------
    p : int >= 0

    Raises
    ------
    ParameterError
        For a negative epoch, λ or bound, or an unknown kind.

    Examples
    --------
    >>> [auto_condition_p(t, kind="linear", lam=0.25) for t in (0, 3, 4, 10)]
    [0, 0, 1, 2]
    >>> auto_condition_p(5, kind="exponential", lam=0.1, p_max=10)
    10
    """
    if epoch < 0:
        raise ParameterError(f"epoch must be >= 0, got {epoch}")
    if lam < 0:
        raise ParameterError(f"curriculum lambda must be >= 0, got {lam}")
    if p_max is not None and p_max < 0:
        raise ParameterError(f"p_max must be >= 0, got {p_max}")
    if kind == "teacher_forcing":
        return 0
    if kind == "const":
        if p_const < 0:
            raise ParameterError(f"p_const must be >= 0, got {p_const}")
        value = float(p_const)
    elif kind == "linear":
        value = lam * epoch
    elif kind == "quadratic":
        value = lam * float(epoch) ** 2
    elif kind == "exponential":
        value = lam * math.exp(min(float(epoch), 700.0))  # e^700 ≈ 1e304, still finite
    else:
        raise ParameterError(f"unknown curriculum kind {kind!r}; choose one of {CURRICULA}")
    if p_max is not None:
        value = min(value, float(p_max))
    return int(math.floor(value + 1e-9))  # the epsilon keeps e.g. 0.1 * 30 = 3 from flooring to 2


def learning_rate(
    step: int,
    *,
    base_lr: float,
    total_steps: int,
    warmup_steps: int = 0,
    kind: str = "cosine",
    min_lr: float = 0.0,
) -> float:
    """Learning rate at optimisation step ``step`` (0-based).

    Linear warm-up from ``base_lr / warmup_steps`` to ``base_lr`` over the first ``warmup_steps``
    steps, then ``base_lr`` (``kind="constant"``) or a cosine decay reaching ``min_lr`` at
    ``total_steps`` (and staying there).

    Examples
    --------
    >>> learning_rate(0, base_lr=1e-3, total_steps=100, warmup_steps=10)
    0.0001
    >>> learning_rate(100, base_lr=1e-3, total_steps=100, warmup_steps=10, min_lr=1e-5)
    1e-05
    """
    if step < 0:
        raise ParameterError(f"step must be >= 0, got {step}")
    if base_lr <= 0 or min_lr < 0:
        raise ParameterError(f"learning rates must be positive, got base_lr={base_lr}, min_lr={min_lr}")
    if kind not in LR_SCHEDULES:
        raise ParameterError(f"unknown learning-rate schedule {kind!r}; choose one of {LR_SCHEDULES}")
    if step < warmup_steps:
        return base_lr * (step + 1) / warmup_steps
    if kind == "constant":
        return base_lr
    span = max(1, total_steps - warmup_steps)
    progress = min(1.0, (step - warmup_steps) / span)
    return min_lr + 0.5 * (base_lr - min_lr) * (1.0 + math.cos(math.pi * progress))
