"""The Foot Constraint Model of Music2Dance (§4.5, supplement §1.3): a post-process against foot sliding.

One file, one model: :class:`FootConstraintConfig` and :class:`FootConstraintModel`.

Architecture
    The input per frame is the lower body's motion ``x'_lrot`` (the root's six columns and the 6D rotations
    of the legs, :func:`~dancekit.motion.root_delta.lower_body_cols`), the toe end-effector positions
    ``p'_fend`` and the foot contacts ``c'_foot`` of a ``rotations_rootdelta`` vector (normalised columns,
    contacts 0/1). Three temporal convolutions (kernel 3, dilations 1, 3, 9, "same" padding, ReLU between;
    a receptive field of 27 frames, centred) predict an increment of the lower body (Eq. 14):
    ``x̂'_lrot = x'_lrot + F_post(x'_lrot, p'_fend, c'_foot)``. Every other column (the upper body, the end
    effectors, the contacts) is passed through unchanged. The last convolution starts at zero, so an
    untrained model is the identity. With ``keep_root_path`` (default) the root's horizontal step and
    heading change (``Δt_x, Δt_z, Δr_y``, the first, third and fourth of ``lower_idx``, which starts with the
    root's six columns) get no increment either: the dancer's path over the floor stays the generator's,
    the legs alone are corrected.
    The paper's baseline (Table 2, ``arch="lstm"``): one fully connected layer, an LSTM, one fully connected
    layer, predicting the same increment.
    ``strength`` scales the increment. With ``gate`` the model has two conv heads of the same shape, "plant"
    and "swing": each leg's columns take ``strength`` x the plant head's increment on the frames where that
    leg's toe contact input is on and ``swing_strength`` x the swing head's elsewhere (the root and the branch
    joints above the hips: either toe, ``gate_root``), blended over ``gate_frames`` frames by a raised-cosine
    window (:meth:`FootConstraintModel.gate_weights`); ``dancekit.pipelines.foot_constraint.compose_gated``
    builds one from two trained models (the embedded one: issue 13, docs/BENCHMARKS.md).
Training (``dancekit.training.m2d.foot_constraint_step``)
    Ground-truth windows with simulated foot sliding; the target is the clean lower body. ``corruption=
    "glide"`` (default): a slow drift on every lower-body column (``glide_amp`` x unit-std noise smoothed over
    ``glide_sigma`` frames), the toes recomputed by forward kinematics, as the generated dances slide
    (``benchmarks/fcm_sliding.py``); ``"paper"``: Gaussian smoothing (``smooth_sigma``) + noise (``noise_std``).
    A share ``clean_share`` of the windows is left clean (the identity is their target). Loss: MSE +
    ``smooth_weight`` (0.1) x the mean squared second difference of the corrected lower body +
    ``contact_weight`` x :func:`contact_velocity_loss` of its toes (world, differentiable FK) on the clean
    dance's planted frames + ``swing_weight`` x :func:`swing_speed_loss` of its legs (how much slower than the
    clean dance's they move off contact). With ``contact_speed > 0`` the model's contact inputs are
    :func:`detect_contacts` (< 5 cm, slower than ``contact_speed`` m/s), in training and in the pipeline.
    Checkpoints written before these settings existed record ``corruption="paper"``, ``contact_weight=0``,
    ``contact_speed=0`` in their config.json.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
import torch.nn.functional as F
from torch import nn

from dancekit.errors import ParameterError

ARCHS = ("conv", "lstm")
CORRUPTIONS = ("glide", "paper")
GATE_ROOTS = ("any", "swing")


def _tang2018_columns() -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    from dancekit.motion import get_skeleton
    from dancekit.motion.root_delta import lower_body_cols, rootdelta_layout

    sk = get_skeleton("tang2018")
    lay = rootdelta_layout(sk)
    return lower_body_cols(sk), lay.toe_cols, lay.contact_cols


@dataclass
class FootConstraintConfig:
    """Hyper-parameters of :class:`FootConstraintModel`; the column indices come from the data (defaults:
    ``rotations_rootdelta`` of tang2018, P = 155: 66 lower-body, 6 toe and 2 contact columns)."""

    pose_dim: int = 155
    lower_idx: tuple[int, ...] = ()  # columns corrected (root + legs); () : tang2018's
    foot_idx: tuple[int, ...] = ()  # toe end-effector columns (read only)
    contact_idx: tuple[int, ...] = ()  # contact columns (read only)
    arch: str = "conv"  # conv (the paper's model) | lstm (its FC + LSTM + FC baseline)
    channels: int = 64
    kernel: int = 3
    dilations: tuple[int, ...] = (1, 3, 9)
    lstm_hidden: int = 64
    noise_std: float = 0.1  # simulated sliding: Gaussian noise (normalised units) ...
    smooth_sigma: float = 2.0  # ... after Gaussian smoothing (frames)
    smooth_weight: float = 0.1  # the smoothness loss factor
    clean_share: float = 0.5  # share of training windows without simulated sliding (identity target)
    keep_root_path: bool = True  # no increment for the root's Δt_x, Δt_z, Δr_y (lower_idx[0], [2], [3])
    corruption: str = "glide"  # glide (slow drifts of the lower body, as generated dances slide) | paper
    glide_amp: float = 0.3  # glide: std of the drift added to each lower-body column (normalised units) ...
    glide_sigma: float = 6.0  # ... Gaussian-smoothed white noise of this correlation (frames)
    contact_weight: float = 1.0  # weight of the contact-velocity loss ((m/s)² of the toes on target contacts)
    swing_weight: float = 0.0  # weight of the leg-speed-keeping loss ((m/s)² the legs are slower than the target's
    #                            off contact, :func:`swing_speed_loss`)
    contact_speed: float = 1.0  # contact: toe ≤ 5 cm over the running floor and slower than this (m/s); 0: the
    #                             representation's own contact columns (30 cm/s) are the input and the target
    fps: float = 25.0  # frame rate of the training data (the contact velocities)
    skeleton: str = "tang2018"  # the skeleton of the differentiable forward kinematics (the contact loss)
    mse_target: str = "clean"  # the MSE's target: the clean dance (the paper) | the model's own (corrupted) input:
    #                            change nothing but what the contact term asks for
    strength: float = 1.0  # the increment is scaled by this (the plant head's with ``gate``)
    gate: bool = False  # two heads: "plant" on a leg's contact frames, "swing" elsewhere (conv only)
    gate_frames: int = 5  # width (frames, odd) of the raised-cosine window that blends the heads at contact edges
    gate_root: str = "any"  # the root's and the hips' branch columns: plant head while any toe is planted | swing
    swing_strength: float = 1.0  # the swing head's increment is scaled by this
    contact_mean: tuple[float, ...] = (0.0, 0.0)  # the gate reads the contact inputs (normalised columns) back
    contact_std: tuple[float, ...] = (1.0, 1.0)  # as 0/1 with these statistics (the checkpoint's, left, right)

    def __post_init__(self) -> None:
        if not self.lower_idx and not self.foot_idx and not self.contact_idx:
            self.lower_idx, self.foot_idx, self.contact_idx = _tang2018_columns()
        self.lower_idx, self.foot_idx, self.contact_idx, self.dilations = (
            tuple(int(i) for i in v) for v in (self.lower_idx, self.foot_idx, self.contact_idx, self.dilations))
        for name in ("pose_dim", "channels", "kernel", "lstm_hidden"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ParameterError(f"FootConstraintConfig.{name} must be a positive integer, got {value!r}")
        cols = self.lower_idx + self.foot_idx + self.contact_idx
        if not self.lower_idx or len(set(cols)) != len(cols) or min(cols) < 0 or max(cols) >= self.pose_dim:
            raise ParameterError(f"FootConstraintConfig: lower_idx, foot_idx and contact_idx must be distinct columns "
                                 f"in [0, {self.pose_dim}) with lower_idx non-empty")
        if self.arch not in ARCHS:
            raise ParameterError(f"FootConstraintConfig.arch must be one of {ARCHS}, got {self.arch!r}")
        if self.kernel % 2 == 0 or not self.dilations or min(self.dilations) < 1:
            raise ParameterError("FootConstraintConfig: kernel must be odd and dilations positive")
        if not 0.0 <= self.clean_share <= 1.0:
            raise ParameterError(f"FootConstraintConfig.clean_share must be in [0, 1], got {self.clean_share!r}")
        if self.keep_root_path and len(self.lower_idx) < 4:
            raise ParameterError("FootConstraintConfig.keep_root_path needs lower_idx to start with the root's 6 columns")
        if min(self.noise_std, self.smooth_sigma, self.smooth_weight, self.glide_amp, self.glide_sigma,
               self.contact_weight, self.contact_speed, self.swing_weight) < 0:
            raise ParameterError("FootConstraintConfig: noise_std, smooth_sigma, smooth_weight, glide_amp, glide_sigma, "
                                 "contact_weight, contact_speed and swing_weight must be >= 0")
        if self.mse_target not in ("clean", "input"):
            raise ParameterError(f"FootConstraintConfig.mse_target must be 'clean' or 'input', got {self.mse_target!r}")
        if self.corruption not in CORRUPTIONS:
            raise ParameterError(f"FootConstraintConfig.corruption must be one of {CORRUPTIONS}, got {self.corruption!r}")
        if not self.fps > 0:
            raise ParameterError(f"FootConstraintConfig.fps must be positive, got {self.fps!r}")
        self.contact_mean, self.contact_std = (tuple(float(v) for v in a) for a in (self.contact_mean, self.contact_std))
        if not (0.0 <= self.strength <= 1.0 and 0.0 <= self.swing_strength <= 1.0):
            raise ParameterError("FootConstraintConfig: strength and swing_strength must be in [0, 1]")
        if self.gate:
            if self.arch != "conv":
                raise ParameterError("FootConstraintConfig.gate needs arch='conv'")
            if isinstance(self.gate_frames, bool) or not isinstance(self.gate_frames, int) or self.gate_frames < 1 \
                    or self.gate_frames % 2 == 0:
                raise ParameterError(f"FootConstraintConfig.gate_frames must be a positive odd integer, got {self.gate_frames!r}")
            if self.gate_root not in GATE_ROOTS:
                raise ParameterError(f"FootConstraintConfig.gate_root must be one of {GATE_ROOTS}, got {self.gate_root!r}")
            if len(self.contact_idx) != 2 or len(self.contact_mean) != 2 or len(self.contact_std) != 2 \
                    or min(self.contact_std) <= 0:
                raise ParameterError("FootConstraintConfig.gate needs two contact columns (left, right) and their "
                                     "statistics contact_mean, contact_std (std > 0)")

    @property
    def in_dim(self) -> int:
        return len(self.lower_idx) + len(self.foot_idx) + len(self.contact_idx)


class FootConstraintModel(nn.Module):
    """Motion ``(B, T, P)`` → the same motion with its lower body corrected ``(B, T, P)``.

    Examples
    --------
    >>> model = FootConstraintModel(FootConstraintConfig())
    >>> model(torch.randn(2, 50, 155)).shape
    torch.Size([2, 50, 155])
    """

    family: ClassVar[str] = "foot_constraint"

    def __init__(self, config: FootConstraintConfig):
        super().__init__()
        self.config = c = config
        self.register_buffer("inputs", torch.tensor(c.lower_idx + c.foot_idx + c.contact_idx), persistent=False)
        self.register_buffer("lower", torch.tensor(c.lower_idx), persistent=False)
        mask = torch.ones(len(c.lower_idx))
        if c.keep_root_path:
            mask[[0, 2, 3]] = 0.0  # Δt_x, Δt_z, Δr_y of the root (rotations_rootdelta order)
        self.register_buffer("mask", mask, persistent=False)
        out = len(c.lower_idx)
        if c.arch == "conv":
            widths = [c.in_dim] + [c.channels] * (len(c.dilations) - 1) + [out]
            self.convs = nn.ModuleList(
                nn.Conv1d(widths[i], widths[i + 1], c.kernel, dilation=d, padding=d * (c.kernel // 2))
                for i, d in enumerate(c.dilations))
            last = self.convs[-1]
        else:
            self.fc_in = nn.Linear(c.in_dim, c.lstm_hidden)
            self.lstm = nn.LSTM(c.lstm_hidden, c.lstm_hidden, batch_first=True)
            self.fc_out = nn.Linear(c.lstm_hidden, out)
            last = self.fc_out
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)
        if c.gate:
            self.swing_convs = nn.ModuleList(
                nn.Conv1d(widths[i], widths[i + 1], c.kernel, dilation=d, padding=d * (c.kernel // 2))
                for i, d in enumerate(c.dilations))
            nn.init.zeros_(self.swing_convs[-1].weight)
            nn.init.zeros_(self.swing_convs[-1].bias)
            self.register_buffer("side", torch.tensor(lower_body_sides(c)), persistent=False)

    @staticmethod
    def _convs(h: torch.Tensor, convs: nn.ModuleList) -> torch.Tensor:
        h = h.transpose(1, 2)  # (B, in_dim, T)
        for i, conv in enumerate(convs):
            h = conv(h)
            if i < len(convs) - 1:
                h = F.relu(h)
        return h.transpose(1, 2)  # (B, T, lower)

    def gate_weights(self, x: torch.Tensor) -> torch.Tensor:
        """The plant head's weight ``(B, T, len(lower_idx))`` in [0, 1] per lower-body column (``gate``): each
        leg's columns follow its toe's contact input (read back as 0/1 with ``contact_mean``/``contact_std``),
        the root's and the branch joints' the contact of either toe (``gate_root="any"``) or none (``"swing"``),
        blended over ``gate_frames`` frames by a normalised raised-cosine window (edges replicated)."""
        c = self.config
        mean, std = (torch.tensor(v, dtype=x.dtype, device=x.device) for v in (c.contact_mean, c.contact_std))
        planted = ((x[..., list(c.contact_idx)] * std + mean) > 0.5).to(x.dtype)  # (B, T, 2) left, right
        either = planted.amax(-1, keepdim=True) if c.gate_root == "any" else torch.zeros_like(planted[..., :1])
        g = torch.cat([planted, either], -1)  # (B, T, 3)
        r = c.gate_frames // 2
        h = F.pad(g.transpose(1, 2), (r, r), mode="replicate") if r else g.transpose(1, 2)
        window = raised_cosine(c.gate_frames).to(x)
        g = F.conv1d(h, window.expand(3, 1, -1), groups=3).transpose(1, 2)
        return g[..., self.side]  # (B, T, lower)

    def increment(self, x: torch.Tensor) -> torch.Tensor:
        """``F_post``: the lower-body increment ``(B, T, len(lower_idx))`` for motion ``x (B, T, P)`` (zero on
        the root's path columns with ``keep_root_path``), scaled by ``strength``; with ``gate`` the blend
        ``w · strength · plant + (1 - w) · swing_strength · swing`` of the two heads (:meth:`gate_weights`)."""
        c = self.config
        if x.dim() != 3 or x.shape[-1] != c.pose_dim:
            raise ParameterError(f"motion must be (B, T, {c.pose_dim}), got {tuple(x.shape)}")
        h = x[..., self.inputs]  # (B, T, in_dim)
        if c.arch == "lstm":
            h, _ = self.lstm(self.fc_in(h))
            return self.fc_out(h) * self.mask * c.strength
        inc = self._convs(h, self.convs) * c.strength
        if c.gate:
            w = self.gate_weights(x)
            inc = w * inc + (1.0 - w) * (self._convs(h, self.swing_convs) * c.swing_strength)
        return inc * self.mask  # (B, T, lower)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Eq. 14: ``x`` with ``x[..., lower_idx] + F_post(...)``; every other column unchanged."""
        out = x.clone()
        out[..., self.lower] = x[..., self.lower] + self.increment(x)
        return out


def raised_cosine(n: int) -> torch.Tensor:
    """The normalised raised-cosine (Hann) window of ``n`` points without its zero ends, ``(n,)`` float64 summing to 1:
    ``sin²(π k / (n + 1))``, k = 1…n. A 0/1 step convolved with it rises smoothly over ``n`` frames."""
    k = torch.arange(1, n + 1, dtype=torch.float64)
    w = torch.sin(torch.pi * k / (n + 1)) ** 2
    return w / w.sum()


def lower_body_sides(config: FootConstraintConfig) -> list[int]:
    """Per ``lower_idx`` column, the leg it moves: 0 left (the left hip and below), 1 right, 2 neither (the
    root's six columns and the branch joints the hips hang from), from the rig of ``config.skeleton``."""
    from dancekit.motion import get_skeleton
    from dancekit.motion.root_delta import rootdelta_layout

    sk = get_skeleton(config.skeleton)
    lay, parents = rootdelta_layout(sk), sk.rig().parents
    hips = {sk.index("left_hip"): 0, sk.index("right_hip"): 1}
    owner = {}
    for j in lay.rot_joints:
        side, a = 2, j
        while a >= 0:
            if a in hips:
                side = hips[a]
                break
            a = parents[a]
        owner.update({col: side for col in lay.rot_cols(j)})
    return [owner.get(col, 2) for col in config.lower_idx]


def gaussian_smooth(x: torch.Tensor, sigma: float) -> torch.Tensor:
    """``x (B, T, C)`` smoothed along time with a Gaussian of ``sigma`` frames (edges replicated)."""
    if sigma <= 0:
        return x
    r = max(1, int(round(3 * sigma)))
    t = torch.arange(-r, r + 1, dtype=x.dtype, device=x.device)
    w = torch.exp(-0.5 * (t / sigma) ** 2)
    w = (w / w.sum()).expand(x.shape[-1], 1, -1)  # (C, 1, 2r+1)
    h = F.pad(x.transpose(1, 2), (r, r), mode="replicate")
    return F.conv1d(h, w, groups=x.shape[-1]).transpose(1, 2)


def unit_smooth_noise(shape: tuple[int, ...], sigma: float, *, generator: torch.Generator | None = None,
                      dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Gaussian white noise ``shape = (B, T, C)`` smoothed along time with a Gaussian of ``sigma`` frames and
    rescaled to unit standard deviation: a slow random drift whose correlation time is ``sigma`` frames."""
    g = generator
    noise = torch.randn(shape, generator=g, device=None if g is None else g.device).to(dtype)
    if sigma <= 0:
        return noise
    r = max(1, int(round(3 * sigma)))
    t = torch.arange(-r, r + 1, dtype=torch.float64)
    w = torch.exp(-0.5 * (t / sigma) ** 2)
    w = w / w.sum()
    return gaussian_smooth(noise, sigma) / float(w.pow(2).sum().sqrt())


def _time_gradient(p: torch.Tensor) -> torch.Tensor:
    """``np.gradient`` along axis -3 of ``p (..., T, F, 3)`` (central differences, one-sided at the ends)."""
    if p.shape[-3] < 2:
        return torch.zeros_like(p)
    first, last = p[..., 1:2, :, :] - p[..., :1, :, :], p[..., -1:, :, :] - p[..., -2:-1, :, :]
    mid = 0.5 * (p[..., 2:, :, :] - p[..., :-2, :, :])
    return torch.cat([first, mid, last], -3)


def detect_contacts(feet: torch.Tensor, toes: tuple[int, int], *, fps: float, up: int = 1, unit_scale: float = 0.01,
                    height_m: float = 0.05, speed_m_s: float = 1.0) -> torch.Tensor:
    """Contact flags ``(..., T, 2)`` (0/1, float) of the two toes: within ``height_m`` of the running floor and
    slower than ``speed_m_s`` (3D, central differences), as :func:`dancekit.metrics.foot_skating` defines a
    contact.

    ``feet (..., T, F, 3)``: world positions (skeleton units) of the foot joints, ``toes`` the indices of the
    left and right toe among them; the floor is the lowest foot joint's running minimum over ±1 s.
    """
    h = feet[..., up] * unit_scale  # (..., T, F) metres
    lowest = h.min(-1).values  # (..., T)
    r = max(1, int(round(fps)))
    flat = -lowest.reshape(-1, 1, lowest.shape[-1])
    floor = -F.max_pool1d(flat, 2 * r + 1, stride=1, padding=r).reshape(lowest.shape)  # running minimum
    speed = _time_gradient(feet).norm(dim=-1) * fps * unit_scale  # (..., T, F) m/s
    t = list(toes)
    return ((h[..., t] - floor[..., None] <= height_m) & (speed[..., t] < speed_m_s)).to(feet.dtype)


def contact_velocity_loss(toes: torch.Tensor, contacts: torch.Tensor, *, fps: float) -> torch.Tensor:
    """Mean squared velocity (m/s)² of the toes ``(..., T, 2, 3)`` (metres) over the steps ``t → t+1`` on which
    the toe is in contact at both ends (``contacts (..., T, 2)``, 0/1); 0 without such a step.

    A planted foot that stays put costs nothing; a foot gliding at ``v`` m/s through a contact costs ``v²``.
    """
    v = (toes[..., 1:, :, :] - toes[..., :-1, :, :]) * fps  # (..., T-1, 2, 3)
    both = contacts[..., 1:, :] * contacts[..., :-1, :]  # (..., T-1, 2)
    return (both * v.pow(2).sum(-1)).sum() / both.sum().clamp_min(1.0)


def swing_speed_loss(legs: torch.Tensor, target: torch.Tensor, contacts: torch.Tensor, *, fps: float) -> torch.Tensor:
    """Mean squared shortfall (m/s)² of the leg joints' speed below the target's, off contact.

    ``legs``, ``target``: positions ``(..., T, 2, K, 3)`` (metres) of K joints of the left (index 0) and
    right (1) leg, the model's and the clean dance's; ``contacts (..., T, 2)`` (0/1, left, right) the target's
    toe contacts. A step ``t → t+1`` counts for a leg unless its toe is in contact at both ends; its cost per
    joint is ``max(|v_target| - |v|, 0)²``: a leg as fast as the target's or faster costs nothing, a leg
    still where the target's moves at ``v`` m/s costs ``v²``. 0 without such a step.
    """
    v = (legs[..., 1:, :, :, :] - legs[..., :-1, :, :, :]) * fps  # (..., T-1, 2, K, 3)
    vt = (target[..., 1:, :, :, :] - target[..., :-1, :, :, :]) * fps
    off = (1.0 - contacts[..., 1:, :] * contacts[..., :-1, :])[..., None]  # (..., T-1, 2, 1)
    speed = v.pow(2).sum(-1).clamp_min(1e-18).sqrt()  # (..., T-1, 2, K); clamped: a finite gradient at rest
    short = (vt.pow(2).sum(-1).sqrt() - speed).clamp_min(0.0)
    return (off * short.pow(2)).sum() / (off.sum() * legs.shape[-2]).clamp_min(1.0)
