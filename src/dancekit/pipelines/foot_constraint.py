"""The Foot Constraint Model as a post-process: a :class:`Motion` in, the motion with less foot sliding out.

    >>> fix = FootConstraintPipeline.from_pretrained("runs/foot/model")      # doctest: +SKIP
    >>> fixed = fix(result.motion)                                           # doctest: +SKIP

Any dance on the checkpoint's skeleton works (Music2Dance's and Dance Revolution's alike): the motion is
encoded as ``rotations_rootdelta`` (its IK rotations when it has only positions), normalised with the
checkpoint's statistics, corrected by the model (lower body only), and decoded from the motion's own
start (position and heading of frame 0), so the corrected dance stays where it was.

:func:`load_foot_constraint` finds a foot model by name: the default is the one embedded with the
``music2dance`` model (its ``"foot_constraint"`` component), which ``dancekit dance --foot-constraint``
applies to the dance of any model on the tang2018 skeleton.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dancekit.checkpoints import NormStats, components, load_pretrained, resolve_model
from dancekit.checkpoints.hub import read_meta
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.foot_constraint import FootConstraintModel, detect_contacts
from dancekit.motion import Motion, Skeleton
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta, rootdelta_positions

#: the model whose ``"foot_constraint"`` component is the default foot model
DEFAULT_FOOT_HOST = "music2dance"
COMPONENT = "foot_constraint"


def foot_constraint_folder(model: str | os.PathLike | None = None) -> Path:
    """The folder of a Foot Constraint Model: ``model`` a foot_constraint checkpoint (folder or name), or a
    model that declares a ``"foot_constraint"`` component; None or ``"default"``: the embedded music2dance's.

    Raises
    ------
    CheckpointError
        For a folder that is neither a foot model nor declares one.
    """
    folder = resolve_model(DEFAULT_FOOT_HOST if model in (None, "default") else model)
    meta = read_meta(folder)
    if meta.get("model") == "foot_constraint":
        return Path(folder)
    parts = components(folder, meta)
    if COMPONENT not in parts:
        raise CheckpointError(f"{folder} is not a Foot Constraint Model and declares none (no {COMPONENT!r} component)")
    return Path(parts[COMPONENT])


def load_foot_constraint(model: str | os.PathLike | None = None, *, device: str = "cpu") -> FootConstraintPipeline:
    """The :class:`FootConstraintPipeline` of :func:`foot_constraint_folder` ``(model)``."""
    return FootConstraintPipeline.from_pretrained(foot_constraint_folder(model), device=device)


class FootConstraintPipeline:
    """Correct the lower body of a dance with a trained :class:`FootConstraintModel`."""

    def __init__(self, model: FootConstraintModel, *, meta: dict[str, Any], stats: NormStats, folder: str = "?"):
        if not isinstance(model, FootConstraintModel):
            raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a Foot Constraint Model")
        if "skeleton" not in meta:
            raise CheckpointError(f"checkpoint {folder}: config.json has no 'skeleton' entry")
        self.model, self.meta, self.stats, self.folder = model.eval(), meta, stats, str(folder)
        self.skeleton = Skeleton.from_dict(meta["skeleton"])
        if len(stats.dance_mean) != model.config.pose_dim:
            raise CheckpointError(f"checkpoint {folder}: statistics of {len(stats.dance_mean)} columns for a model "
                                  f"of {model.config.pose_dim}")

    @classmethod
    def from_pretrained(cls, folder: str | os.PathLike, *, device: str = "cpu") -> FootConstraintPipeline:
        """Load a checkpoint folder (``dancekit train foot_constraint``) or a model name."""
        folder = resolve_model(folder)
        model, meta, arrays = load_pretrained(folder, device=device)
        stats = NormStats.from_arrays(arrays, source=str(folder))
        return cls(model, meta=meta, stats=stats, folder=str(Path(folder)))

    def contacts(self, x: np.ndarray) -> np.ndarray:
        """Toe contacts ``(T, 2)`` of ``rotations_rootdelta`` features ``x (T, P)`` as the model was trained
        with: within 5 cm of the running floor and slower than ``config.contact_speed`` m/s."""
        sk, c = self.skeleton, self.model.config
        feet = tuple(sk.index(n) for n in sk.feet)
        toes = (feet.index(sk.index("left_toe")), feet.index(sk.index("right_toe")))
        p = rootdelta_positions(torch.from_numpy(x), sk, joints=feet)
        return detect_contacts(p, toes, fps=c.fps, unit_scale=sk.unit_scale, speed_m_s=c.contact_speed).numpy()

    @torch.no_grad()
    def __call__(self, motion: Motion) -> Motion:
        """The motion with its lower body corrected (rotations on the rig, FK positions, same fps and start).

        Raises
        ------
        ParameterError
            For a motion on another skeleton.
        """
        if not isinstance(motion, Motion):
            raise ParameterError(f"the Foot Constraint Model post-processes a Motion, got {type(motion).__name__}")
        if motion.skeleton.joint_names != self.skeleton.joint_names:
            raise ParameterError(f"this Foot Constraint Model was trained on the {self.skeleton.name!r} skeleton, "
                                 f"the motion is on {motion.skeleton.name!r}")
        x = encode_rootdelta(motion)  # (T, P) float64
        c = self.model.config
        if c.contact_speed > 0:  # the contacts the model was trained with (see foot_constraint_step)
            x[:, list(c.contact_idx)] = self.contacts(x)
        z = torch.from_numpy(self.stats.normalize_dance(x))[None]  # (1, T, P)
        y = self.model(z.to(next(self.model.parameters()).device))[0].cpu().numpy()
        fixed = self.stats.denormalize_dance(y).astype(np.float64)
        R0 = motion.rotations if motion.rotations is not None else None
        if R0 is None:
            from dancekit.motion.kinematics import inverse_kinematics

            R0, _ = inverse_kinematics(np.asarray(motion.positions[:1], np.float64), motion.skeleton)
        root = motion.skeleton.root
        heading0 = float(np.arctan2(R0[0, root, 0, 2], R0[0, root, 2, 2]))
        tr0 = np.asarray(motion.root_translation if motion.root_translation is not None
                         else motion.positions[:, root], np.float64)[0]
        return decode_rootdelta(fixed, motion.skeleton, motion.fps, origin=(tr0[0], tr0[2], heading0))


def compose_gated(plant: str | os.PathLike, swing: str | os.PathLike | None, out: str | os.PathLike, *,
                  gate_frames: int = 5, gate_root: str = "any", strength: float = 1.0,
                  swing_strength: float = 1.0) -> Path:
    """Write one contact-gated Foot Constraint Model (``gate=True``, two heads) to the checkpoint folder ``out``.

    ``plant``: a conv foot model whose increment is used on each leg's contact frames (one that plants the
    feet); ``swing``: one used elsewhere (one that keeps the legs' speed), None for no increment there. Both
    must be trained on the same columns and statistics. The heads are blended per leg by the model's own
    contact inputs over ``gate_frames`` frames (see :meth:`FootConstraintModel.gate_weights`); ``strength``
    and ``swing_strength`` scale the two increments. ``config.json`` records both heads' configurations and
    training (``"heads"``).

    Raises
    ------
    CheckpointError
        For heads that are not conv foot models of the same columns and statistics.
    """
    import dataclasses

    from dancekit.checkpoints import save_pretrained
    from dancekit.models.foot_constraint import FootConstraintConfig

    heads = {"plant": plant} if swing is None else {"plant": plant, "swing": swing}
    loaded = {name: load_pretrained(resolve_model(folder)) for name, folder in heads.items()}
    base_model, base_meta, base_arrays = loaded["plant"]
    keys = ("pose_dim", "lower_idx", "foot_idx", "contact_idx", "arch", "channels", "kernel", "dilations",
            "keep_root_path", "contact_speed", "fps", "skeleton")
    for name, (model, _, arrays) in loaded.items():
        bad = [k for k in keys if getattr(model.config, k) != getattr(base_model.config, k)]
        if not isinstance(model, FootConstraintModel) or model.config.gate or model.config.arch != "conv" or bad:
            raise CheckpointError(f"{heads[name]}: the {name} head must be an ungated conv Foot Constraint Model "
                                  f"like {plant}" + (f" (differs in {', '.join(bad)})" if bad else ""))
        if any(not np.array_equal(arrays[k], base_arrays[k]) for k in ("dance_mean", "dance_std")):
            raise CheckpointError(f"{heads[name]}: the {name} head was trained with other statistics than {plant}")
    c = base_model.config
    stats = NormStats.from_arrays(base_arrays, source=str(plant))
    ci = list(c.contact_idx)
    cfg = FootConstraintConfig(**{**dataclasses.asdict(c), "gate": True, "gate_frames": gate_frames,
                                  "gate_root": gate_root, "strength": strength, "swing_strength": swing_strength,
                                  "contact_mean": tuple(np.asarray(stats.dance_mean)[ci].tolist()),
                                  "contact_std": tuple(np.asarray(stats.dance_std)[ci].tolist())})
    model = FootConstraintModel(cfg)
    state = {k: v for k, v in base_model.state_dict().items() if k.startswith("convs.")}
    if swing is not None:
        state.update({"swing_" + k: v for k, v in loaded["swing"][0].state_dict().items() if k.startswith("convs.")})
    else:
        state.update({k: torch.zeros_like(v) for k, v in model.state_dict().items() if k.startswith("swing_convs.")})
    model.load_state_dict(state)
    extra = {k: v for k, v in base_meta.items() if k not in ("model", "config", "train", "init", "step", "components")}
    extra["heads"] = {name: {"folder": str(heads[name]), **{k: meta.get(k) for k in ("config", "train", "init", "step")}}
                      for name, (_, meta, _) in loaded.items()}
    return save_pretrained(out, model, cfg, stats=stats, extra=extra)
