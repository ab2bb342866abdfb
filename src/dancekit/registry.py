"""The one table of model families.

Each family declares, once, everything the toolkit needs to build, train, save, load and run it:

``config`` / ``module``
    the ``@dataclass`` configuration and the ``nn.Module(config)`` (``dancekit.models.<family>``)
``objective``
    ``step_fn(model, batch, ctx) -> (loss, logs)`` of the generic trainer (:mod:`dancekit.training`)
``dataset``
    ``build(data, train_config, stats) -> (train_set, val_set)``: the family's training windows
``preset``
    the music feature preset its inputs use (``None``: the family reads no music)
``train_defaults``
    :class:`~dancekit.training.TrainConfig` values of the family (under ``--set`` and ``--resume``)
``data_fields``
    model-config fields filled from the data (``music_dim``, ``pose_dim``, ``n_classes``, ``window``)
``pipeline``
    the inference pipeline class (``Pipeline.from_pretrained(name_or_folder)``), called on ``input``:
    ``"audio"`` (a song's path: dance models and the music attribute classifier) or ``"motion"`` (a
    :class:`~dancekit.motion.Motion`: the style classifier)

Entries are lazy ``"module:name"`` strings, so reading the table imports nothing (no torch);
:meth:`Family.load` imports one entry when it is needed. Adding a family means one entry here plus its
model file (``models/``) and pipeline file (``pipelines/``).

This module imports nothing of dancekit but :mod:`dancekit.errors`: every layer may read it.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from dancekit.errors import ParameterError


@dataclass(frozen=True)
class Family:
    """One model family (see the module docstring for the fields)."""

    name: str
    config: str
    module: str
    objective: str
    dataset: str
    pipeline: str
    preset: str | None = None
    kind: str = "dance"  # dance (music → motion) | classifier (→ labels) | postprocess (motion → motion)
    input: str = "audio"  # what the pipeline is called on: audio (a path) | motion (a Motion)
    description: str = ""
    train_defaults: Mapping[str, Any] = field(default_factory=dict)
    data_fields: tuple[str, ...] = ()

    def load(self, what: str) -> Any:
        """Import one entry: ``"config"``, ``"module"``, ``"objective"``, ``"dataset"`` or ``"pipeline"``."""
        if what not in ("config", "module", "objective", "dataset", "pipeline"):
            raise ParameterError(f"a family has no entry {what!r}")
        return resolve(getattr(self, what))

    @property
    def config_class(self) -> type:
        return self.load("config")

    @property
    def module_class(self) -> type:
        return self.load("module")


def resolve(spec: str) -> Any:
    """Import ``"package.module:name"`` and return ``name``."""
    module_name, sep, attr = spec.partition(":")
    if not sep:
        raise ParameterError(f"registry entry {spec!r} must read 'module:name'")
    return getattr(importlib.import_module(module_name), attr)


_FAMILIES: dict[str, Family] = {}


def register(family: Family) -> Family:
    """Add a family to the table (a second family of the same name is an error)."""
    if family.name in _FAMILIES:
        raise ParameterError(f"model family {family.name!r} is registered already")
    _FAMILIES[family.name] = family
    return family


def unregister(name: str) -> Family:
    """Remove the family ``name`` from the table (a family registered for a while, e.g. by a test or a plugin);
    :class:`ParameterError` for a name that is not registered."""
    family = get(name)
    del _FAMILIES[name]
    return family


def families(kind: str | None = None) -> tuple[str, ...]:
    """Names of the registered families (of one ``kind`` when given), sorted."""
    return tuple(sorted(n for n, f in _FAMILIES.items() if kind is None or f.kind == kind))


def get(name: str) -> Family:
    """The family called ``name``; :class:`ParameterError` naming the known ones otherwise."""
    try:
        return _FAMILIES[name]
    except KeyError:
        raise ParameterError(f"unknown model family {name!r}; known: {', '.join(families())}") from None


def family_of(model: Any) -> str:
    """The family name of a model instance (its class attribute ``family``, else a table lookup)."""
    name = getattr(model, "family", None)
    if isinstance(name, str) and name in _FAMILIES:
        return name
    for fam in _FAMILIES.values():
        if isinstance(model, fam.module_class):
            return fam.name
    raise ParameterError(f"{type(model).__name__} is not a registered model family (see dancekit.registry)")


FAMILIES = MappingProxyType(_FAMILIES)

# ---------------------------------------------------------------------------------------------- the table

register(Family(
    name="revolution",
    config="dancekit.models.revolution:RevolutionConfig",
    module="dancekit.models.revolution:RevolutionModel",
    objective="dancekit.training.objectives:revolution_step",
    dataset="dancekit.training.datasets:music_dance_windows",
    pipeline="dancekit.pipelines.revolution:RevolutionPipeline",
    preset="revolution",
    description="Dance Revolution (ICLR 2021): local self-attention music encoder + LSTM decoder, "
                "dynamic auto-condition curriculum",
    data_fields=("music_dim", "pose_dim"),
))

register(Family(
    name="music_attributes",
    config="dancekit.models.music_attributes:MusicAttributeConfig",
    module="dancekit.models.music_attributes:MusicAttributeClassifier",
    objective="dancekit.training.objectives:music_attributes_step",
    dataset="dancekit.training.datasets:music_dance_windows",
    pipeline="dancekit.pipelines.music_attributes:MusicAttributePipeline",
    preset="music2dance",
    kind="classifier",
    description="Music2Dance §4.3 music attribute classifier: temporal convolutions + BiLSTM over 30-s windows",
    # 30-s windows; 100 genre-balanced steps (chosen on the validation songs, docs/BENCHMARKS.md
    # "`--genre auto`: the genre read from the music")
    train_defaults={"seq_len": 750, "steps": 100, "balance_genres": True, "warmup_steps": 20, "val_every": 25,
                    "ckpt_every": 100, "log_every": 10},
    data_fields=("music_dim", "n_classes", "window"),
))

register(Family(
    name="style",
    config="dancekit.models.style:StyleClassifierConfig",
    module="dancekit.models.style:StyleClassifier",
    objective="dancekit.training.objectives:style_step",
    dataset="dancekit.training.datasets:style_windows",
    pipeline="dancekit.pipelines.style:StylePipeline",
    preset=None,
    kind="classifier",
    input="motion",
    description="dance style classifier (motion → genre) whose features serve the style metrics "
                "(style accuracy, style diversity, multimodality)",
    # the embedded classifier's run: 4-s windows every 0.5 s (25 fps) of the training dances and their
    # mirror images, 15 epochs of the 6384 tang2018 windows (99 steps of 64), validated every epoch
    train_defaults={"seq_len": 100, "stride": 12, "random_offset": False, "steps": 1485, "batch_size": 64,
                    "lr": 2e-3, "warmup_steps": 50, "weight_decay": 1e-4, "log_every": 99, "val_every": 99,
                    "ckpt_every": 1485, "keep_checkpoints": 1, "threads": 1},
    data_fields=("in_dim", "genres", "window", "fps", "class_weights"),
))

# One family for both generators of dual learning: joint training couples them (GW and cycle losses), so they
# share one module, one optimiser step and one checkpoint. Its pipeline is music → dance (G_M→D); the
# dance → music pipeline (G_D→M, `dancekit compose`) reads the same checkpoint: dancekit.pipelines.dual.
register(Family(
    name="dual",
    config="dancekit.models.dual:DualConfig",
    module="dancekit.models.dual:DualModel",
    objective="dancekit.training.objectives:dual_step",
    dataset="dancekit.training.datasets:dual_windows",
    pipeline="dancekit.pipelines.dual:DualPipeline",
    preset="dual",
    description="Dual learning of music and dance (MM 2021): G_M→D and G_D→M transformers trained jointly with "
                "reconstruction, cycle and Gromov-Wasserstein losses",
    # the embedded model's recipe (docs/DUAL.md): 380 steps of 16 windows of 75 frames, about 45 min with
    # 1 thread on the shared 2-core machine; beat_pos_weight=15 and decoder_noise=0.1 are DualConfig's defaults
    train_defaults={"representation": "rot6d", "seq_len": 75, "stride": 25, "batch_size": 16, "lr": 5e-4,
                    "warmup_steps": 40, "steps": 380, "val_every": 50, "ckpt_every": 50},
    data_fields=("music_dim", "pose_dim", "window", "music_raw_from", "dance_raw_from"),
))

register(Family(
    name="music2dance",
    config="dancekit.models.music2dance:Music2DanceConfig",
    module="dancekit.models.music2dance:Music2DanceModel",
    objective="dancekit.training.m2d:music2dance_step",
    dataset="dancekit.training.m2d:music2dance_windows",
    pipeline="dancekit.pipelines.music2dance:Music2DancePipeline",
    preset="music2dance",
    description="Music2Dance (§4.4): WaveNet with F_map music and dance-type conditions, GMM output, foot "
                "contacts, motion clustering (rotations_rootdelta motion)",
    # supplement §1.2: phase 1 at lr 4e-4 (phase 2: --init RUN/model --set phase=2 lr=1e-4). Sized for 2 shared
    # CPU cores (docs/MUSIC2DANCE.md): 160-frame windows (> the 125-frame receptive field), stride 20, batch 16,
    # 1600 steps (the embedded model: step 1000 of this schedule). optimizer=rmsprop is the paper's.
    train_defaults={"representation": "rotations_rootdelta", "seq_len": 160, "stride": 20, "lr": 4e-4,
                    "warmup_steps": 50, "steps": 1600, "val_every": 200, "ckpt_every": 200},
    data_fields=("music_dim", "pose_dim", "n_genres"),
))

register(Family(
    name="foot_constraint",
    config="dancekit.models.foot_constraint:FootConstraintConfig",
    module="dancekit.models.foot_constraint:FootConstraintModel",
    objective="dancekit.training.m2d:foot_constraint_step",
    dataset="dancekit.training.m2d:foot_constraint_windows",
    pipeline="dancekit.pipelines.foot_constraint:FootConstraintPipeline",
    preset="music2dance",  # the windows carry music (the CLI computes its statistics); the model ignores it
    kind="postprocess",  # motion → motion (a new kind: tests/test_registry.py checks its pipeline returns a Motion)
    input="motion",
    description="Music2Dance §4.5 Foot Constraint Model: three dilated temporal convolutions correcting the lower "
                "body of a rotations_rootdelta dance against foot sliding (arch=lstm: the FC+LSTM+FC baseline)",
    # supplement §1.3: 480-frame windows, stride 3, Adam at 5e-4 (here 240-frame windows, stride 30)
    train_defaults={"representation": "rotations_rootdelta", "seq_len": 240, "stride": 30, "lr": 5e-4,
                    "warmup_steps": 20},
    data_fields=("pose_dim", "lower_idx", "foot_idx", "contact_idx", "fps", "skeleton"),
))
