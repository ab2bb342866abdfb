"""The typed settings of a dance checkpoint: its stages, its sampling and its per-genre statistics.

A dance checkpoint's ``config.json`` carries three entries for inference (beside the model's own ``"config"``):

* ``"stages"``: one object per stage of :func:`dancekit.pipelines.stages.finish`, each parsed into its frozen
  dataclass below (:class:`SmoothConfig`, :class:`EnergyConfig`, :class:`JitterCapConfig`,
  :class:`FootLockConfig`, :class:`SettleConfig`, :class:`RegroundConfig`, :class:`BeatSyncConfig`); a stage
  without an entry keeps its defaults (the energy lift, the jitter cap and the regrounding are then off);
* ``"sampling"``: the family's generation settings (its pipeline's ``sampling_config`` dataclass, e.g.
  :class:`Music2DanceSampling`);
* ``"genre_stats"``: the per-genre tables of the real training dances the stages compare a dance with
  (:class:`GenreStats`: jitter, energy, planted share, jitter-to-energy ratio).

:func:`checkpoint_settings` parses them once, when a pipeline loads (the stages never read ``config.json``).
Every value is checked in its dataclass's ``__post_init__``; a bad one is a :class:`~dancekit.errors.CheckpointError`
naming the key, the value, the allowed range and the checkpoint folder, and so is an unknown key anywhere in
these entries or at the top level of ``config.json``. A checkpoint written by an earlier release (the stage
settings as loose top-level entries: ``"smoothing"``, ``"energy"``, ``"jitter_cap"``, ``"plant"``, ...) is
converted on reading, with one warning line per folder (:func:`convert_old_layout`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from typing import Any

from dancekit.errors import CheckpointError, ParameterError

__all__ = ["BeatSyncConfig", "CheckpointSettings", "CleanUpConfig", "DualSampling", "EditConfig", "EnergyConfig",
           "FootLockConfig", "GenreStats", "JitterCapConfig", "Music2DanceSampling", "NoSampling",
           "RegroundConfig", "RevolutionSampling", "STAGE_NAMES", "SettleConfig", "SmoothConfig", "StageConfig",
           "SAMPLING_CONFIGS", "TOP_LEVEL_KEYS", "checkpoint_settings", "convert_old_layout", "parse_entry",
           "read_checkpoint_settings", "read_stage_config"]

#: The stages of :func:`dancekit.pipelines.stages.finish`, in the order it runs them (the jitter cap runs after
#: the settle instead with :attr:`JitterCapConfig.after_lock`).
STAGE_NAMES = ("clean_up", "smooth", "lift_energy", "jitter_cap", "foot_lock", "settle", "reground", "beat_sync")

#: The top-level keys a checkpoint's ``config.json`` may hold (written by ``dancekit train`` and
#: :func:`dancekit.checkpoints.save_pretrained`, plus the three entries of this module).
TOP_LEVEL_KEYS = frozenset({"model", "config", "representation", "preset", "fps", "hop_length", "skeleton", "genres",
                            "data", "init", "step", "val_loss", "train", "components", "stages", "sampling",
                            "genre_stats", "soup"})


#: The jitter-to-energy ratio (:func:`dancekit.motion.footlock.smoothing_window`) the smoothing stage brings a
#: jittery dance down to: about the 80th percentile of the real training dances' (0.055-0.28, median 0.065);
#: a dance beyond :data:`NOISY_RATIO` (more than nearly every real dance: frame-to-frame noise, the dual
#: model's 0.31-0.33) is brought to :data:`SMOOTH_TARGET_NOISY`, the real median. Chosen on the validation
#: songs (``benchmarks/bench_feet.py --grid``, docs/STAGES.md). :class:`SmoothConfig`'s defaults.
SMOOTH_TARGET = 0.09
SMOOTH_TARGET_NOISY = 0.065
NOISY_RATIO = 0.2
#: The smoothing stage's default filter: ``"lowpass"`` or ``"savgol"``.
SMOOTH_FILTER = "savgol"


#: the logger of the one line said when an old-layout checkpoint is converted (:func:`convert_old_layout`)
log = logging.getLogger("dancekit.checkpoints")


# --- value checks (each raises ParameterError naming the key, the value and the allowed range) -------------------

def _number(key: str, v: Any, *, lo: float | None = None, hi: float | None = None, lo_open: bool = False,
            hi_open: bool = False, unit: str = "") -> float:
    """``v`` as a float when it is a finite int / float (not a bool) within the range, else ParameterError."""
    lo_s = "" if lo is None else ("(" if lo_open else "[") + f"{lo:g}"
    hi_s = "" if hi is None else f"{hi:g}" + (")" if hi_open else "]")
    what = (f"a number in {lo_s or '(-inf'}, {hi_s or 'inf)'}" if lo is not None or hi is not None
            else "a finite number") + (f" ({unit})" if unit else "")
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v < hi if hi_open else v <= hi
    if not ok:
        raise ParameterError(f"{key} must be {what}, got {v!r}")
    return float(v)


def _flag(key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise ParameterError(f"{key} must be true or false, got {v!r}")
    return v


def _table(key: str, v: Any, *, lo: float = 0.0, hi: float | None = None, hi_open: bool = False,
           unit: str = "") -> tuple[tuple[str, float], ...]:
    """A genre table ``{genre: number}`` (or its tuple of pairs) as a tuple of ``(genre, float)`` pairs, values > lo."""
    pairs = list(v.items()) if isinstance(v, dict) else v
    try:
        pairs = [(g, x) for g, x in pairs]
    except (TypeError, ValueError):
        raise ParameterError(f"{key} must map genres to numbers, got {v!r}") from None
    out = []
    for g, x in pairs:
        if not isinstance(g, str):
            raise ParameterError(f"{key} must map genre names to numbers, got the key {g!r}")
        out.append((g, _number(f"{key}.{g}", x, lo=lo, lo_open=True, hi=hi, hi_open=hi_open, unit=unit)))
    return tuple(out)


def _names(key: str, v: Any) -> tuple[str, ...]:
    if isinstance(v, str) or not all(isinstance(g, str) for g in (v if isinstance(v, (list, tuple)) else [None])):
        raise ParameterError(f"{key} must be a list of genre names, got {v!r}")
    return tuple(v)


def _optional(check, key: str, v: Any, **kw):
    return None if v is None else check(key, v, **kw)


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


# --- the per-genre statistics ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GenreStats:
    """Per genre, the median (the planted share: the mean) of one measure over the real training dances
    (``genre_stats`` of a checkpoint, :func:`dancekit.training.genre_stats.genre_stats`); each a tuple of
    ``(genre, value)`` pairs in the checkpoint's order (``{}`` in JSON), empty when the checkpoint has none.

    * ``jitter``: the speed (m/s) a 5-frame average removes (:func:`dancekit.metrics.stability.jitter`);
    * ``energy``: the smoothed energy (m/s, :func:`dancekit.metrics.smoothed_energy`);
    * ``planted_share``: the share of frames with a planted foot (:func:`dancekit.motion.floor.planted_share`),
      in (0, 1];
    * ``smoothing``: the jitter-to-energy ratio (:func:`dancekit.motion.jitter.smoothing_window`), in (0, 10).
    """

    jitter: tuple[tuple[str, float], ...] = ()
    energy: tuple[tuple[str, float], ...] = ()
    planted_share: tuple[tuple[str, float], ...] = ()
    smoothing: tuple[tuple[str, float], ...] = ()

    def __post_init__(self):
        _set(self, "jitter", _table("genre_stats.jitter", self.jitter, unit="m/s"))
        _set(self, "energy", _table("genre_stats.energy", self.energy, unit="m/s"))
        _set(self, "planted_share", _table("genre_stats.planted_share", self.planted_share, hi=1.0))
        _set(self, "smoothing", _table("genre_stats.smoothing", self.smoothing, hi=10.0, hi_open=True))

    def table(self, name: str) -> dict[str, float]:
        """One table as a dict (genre → value)."""
        return dict(getattr(self, name))


# --- one dataclass per stage -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CleanUpConfig:
    """The clean-up (:func:`dancekit.pipelines.stages.clean_up`): no settings yet (the floor and the 4-m dance
    floor are :mod:`dancekit.motion.cleanup`'s)."""


@dataclass(frozen=True)
class SmoothConfig:
    """The smoothing stage (:func:`dancekit.pipelines.stages.smooth`).

    ``filter``: ``"savgol"`` (a Savitzky-Golay filter, the window chosen per dance) or ``"lowpass"``;
    ``target``: the jitter-to-energy ratio a jittery dance is brought to; ``noisy_ratio``: a dance beyond it is
    brought to ``target_noisy`` instead; ``genre_targets``: the genres whose real ratio (``genre_stats.smoothing``)
    × ``scale`` is the target of a dance of that genre asked for by name (or, with ``drawn``, also read from the
    music or drawn by the seed)."""

    filter: str = SMOOTH_FILTER
    target: float = SMOOTH_TARGET
    target_noisy: float = SMOOTH_TARGET_NOISY
    noisy_ratio: float = NOISY_RATIO
    genre_targets: tuple[str, ...] = ()
    drawn: bool = False
    scale: float = 1.0

    def __post_init__(self):
        if self.filter not in ("savgol", "lowpass"):
            raise ParameterError(f"stages.smooth.filter must be 'savgol' or 'lowpass', got {self.filter!r}")
        for k in ("target", "target_noisy", "noisy_ratio"):
            _set(self, k, _number(f"stages.smooth.{k}", getattr(self, k), lo=0, lo_open=True, hi=10, hi_open=True))
        _set(self, "genre_targets", _names("stages.smooth.genre_targets", self.genre_targets))
        _flag("stages.smooth.drawn", self.drawn)
        _set(self, "scale", _number("stages.smooth.scale", self.scale, lo=0, lo_open=True, hi=10))


@dataclass(frozen=True)
class EnergyConfig:
    """The energy lift (:func:`dancekit.pipelines.stages.lift_energy`, :mod:`dancekit.motion.energy`): a dance
    whose smoothed energy is under a floor (m/s) has the ``band_hz`` low band of its deviation from its
    ``mean_s`` moving mean scaled up by one gain in ``[1, max_gain]`` (the band above by ``gain ** -damp``).
    The floor: ``fraction`` × the real energy of the genres read from the music (``genre_stats.energy``), else
    the fixed ``floor``. ``root`` / ``legs`` false: the root's orientation / the legs are not lifted."""

    floor: float | None = None
    fraction: float | None = None
    max_gain: float = 2.0
    mean_s: float = 1.5
    band_hz: float = 2.5
    damp: float = 0.0
    root: bool = True
    legs: bool = True

    def __post_init__(self):
        _set(self, "floor", _optional(_number, "stages.lift_energy.floor", self.floor, lo=0, lo_open=True, unit="m/s"))
        _set(self, "fraction", _optional(_number, "stages.lift_energy.fraction", self.fraction, lo=0, lo_open=True))
        _set(self, "max_gain", _number("stages.lift_energy.max_gain", self.max_gain, lo=1))
        _set(self, "mean_s", _number("stages.lift_energy.mean_s", self.mean_s, lo=0, lo_open=True, unit="s"))
        _set(self, "band_hz", _number("stages.lift_energy.band_hz", self.band_hz, lo=0, lo_open=True, unit="Hz"))
        _set(self, "damp", _number("stages.lift_energy.damp", self.damp, lo=0, hi=1))
        _flag("stages.lift_energy.root", self.root)
        _flag("stages.lift_energy.legs", self.legs)
        if self.floor is None and self.fraction is None:
            raise ParameterError("stages.lift_energy needs a floor (m/s) or a fraction (of genre_stats.energy)")


@dataclass(frozen=True)
class JitterCapConfig:
    """The per-dance jitter cap (:func:`dancekit.pipelines.stages.jitter_cap`): a low-pass whose cut-off is the
    highest that brings the dance's jitter under ``scale`` × the smallest real jitter (``genre_stats.jitter``)
    among the song's plausible genres (``p_g ≥ min_ratio · max(p)``). ``all``: the most likely genre's dance is
    capped too (else only a genre drawn by the seed or the model alone); ``named``: a genre asked for by name
    is capped at its own real jitter; ``after_lock``: the low-pass runs after the foot lock and its settle
    (default: before the lock); ``to_end``: the cap holds for the finished dance (the stages after it run again
    with the next lower cut-off while the jitter is over the cap). ``max_jitter`` (m/s): a fixed cap instead of
    the genres' (for every dance of a song that looks like music)."""

    scale: float = 1.0
    min_ratio: float = 0.5
    max_jitter: float | None = None
    all: bool = False
    named: bool = False
    after_lock: bool = False
    to_end: bool = False

    def __post_init__(self):
        _set(self, "scale", _number("stages.jitter_cap.scale", self.scale, lo=0, lo_open=True))
        _set(self, "min_ratio", _number("stages.jitter_cap.min_ratio", self.min_ratio, lo=0, hi=1))
        _set(self, "max_jitter", _optional(_number, "stages.jitter_cap.max_jitter", self.max_jitter, lo=0,
                                           lo_open=True, unit="m/s"))
        for k in ("all", "named", "after_lock", "to_end"):
            _flag(f"stages.jitter_cap.{k}", getattr(self, k))


@dataclass(frozen=True)
class FootLockConfig:
    """The foot lock (:func:`dancekit.pipelines.stages.foot_lock`, :func:`dancekit.motion.footlock.lock_feet`):
    the shortest hold (``min_hold_s``, s), how far the original ankle may move from a held foot before it is
    re-planted (``max_drift_m``, m), the hand-over to and from a hold (``blend_s``, s) and the contact
    thresholds (m above the local floor, m/s; ``*_on`` ≤ ``*_off``). None: :mod:`dancekit.motion.footlock`'s
    default. ``plant``: the feet held no longer than the genre's real planted share (``genre_stats.planted_share``)."""

    min_hold_s: float | None = None
    max_drift_m: float | None = None
    blend_s: float | None = None
    height_on: float | None = None
    height_off: float | None = None
    speed_on: float | None = None
    speed_off: float | None = None
    plant: bool = False

    def __post_init__(self):
        from dancekit.motion import footlock as fl

        units = {"min_hold_s": "s", "max_drift_m": "m", "blend_s": "s", "height_on": "m", "height_off": "m",
                 "speed_on": "m/s", "speed_off": "m/s"}
        for k, unit in units.items():
            _set(self, k, _optional(_number, f"stages.foot_lock.{k}", getattr(self, k), lo=0, lo_open=True, unit=unit))
        _flag("stages.foot_lock.plant", self.plant)
        default = {"height_on": fl.CONTACT_HEIGHT_ON_M, "height_off": fl.CONTACT_HEIGHT_OFF_M,
                   "speed_on": fl.CONTACT_SPEED_ON, "speed_off": fl.CONTACT_SPEED_OFF}
        full = {k: default[k] if getattr(self, k) is None else getattr(self, k) for k in default}
        for q in ("height", "speed"):
            if full[f"{q}_on"] > full[f"{q}_off"]:
                raise ParameterError(f"stages.foot_lock.{q}_on must be <= {q}_off ({full[f'{q}_off']:g}), "
                                     f"got {full[f'{q}_on']!r}")

    def lock_options(self) -> dict[str, float]:
        """The :func:`~dancekit.motion.footlock.lock_feet` keyword arguments that are set."""
        return {k: v for k, v in dataclasses.asdict(self).items() if k != "plant" and v is not None}


@dataclass(frozen=True)
class SettleConfig:
    """The light low-pass after the foot lock (:func:`dancekit.pipelines.stages.settle`): ``cutoff_hz`` (Hz,
    0 or None: none) or ``ratio_target`` (the cut-off chosen per dance to bring its jitter-to-energy ratio to it),
    not both."""

    cutoff_hz: float | None = None
    ratio_target: float | None = None

    def __post_init__(self):
        _set(self, "cutoff_hz", _optional(_number, "stages.settle.cutoff_hz", self.cutoff_hz, lo=0, unit="Hz"))
        _set(self, "ratio_target", _optional(_number, "stages.settle.ratio_target", self.ratio_target, lo=0,
                                             lo_open=True))
        if self.cutoff_hz is not None and self.ratio_target is not None:
            raise ParameterError("stages.settle takes cutoff_hz or ratio_target, not both")

    def settle_options(self) -> dict[str, float]:
        """The :func:`~dancekit.pipelines.stages.settle` keyword arguments that are set."""
        out = {} if self.cutoff_hz is None else {"cutoff": self.cutoff_hz}
        return out if self.ratio_target is None else {**out, "ratio_target": self.ratio_target}


@dataclass(frozen=True)
class RegroundConfig:
    """The second grounding after the foot lock (:func:`dancekit.pipelines.stages.reground`): the lowest joint
    put on the floor at least once in every ``window_s`` (s) window; ``max_float_cm``: shorter windows are tried
    while the dance still floats higher than this (cm)."""

    window_s: float = 1.0
    max_float_cm: float | None = None

    def __post_init__(self):
        _set(self, "window_s", _number("stages.reground.window_s", self.window_s, lo=0, lo_open=True, unit="s"))
        _set(self, "max_float_cm", _optional(_number, "stages.reground.max_float_cm", self.max_float_cm, lo=0,
                                             lo_open=True, unit="cm"))

    def reground_options(self) -> dict[str, float]:
        out = {"window_s": self.window_s}
        return out if self.max_float_cm is None else {**out, "max_float_cm": self.max_float_cm}


@dataclass(frozen=True)
class BeatSyncConfig:
    """The beat-synchronous warp (:func:`dancekit.pipelines.stages.beat_sync`,
    :func:`dancekit.motion.timewarp.beat_warp`; None: its default): the bound on the local speed change
    (``max_rate_change``, the rate within ``1 ± it``), the bound between two matched beats (``pair_rate_change``
    ≤ ``max_rate_change``), the farthest a kinematic beat moves (``max_shift``, s), the landing tolerance of
    unpaired kinematic beats (``between_tolerance``, s; 0: off), the rate's smoothness time scale (``smooth_s``,
    s), the bound on the rate's change per frame (``max_rate_step``) and whether the pairing skips steps that
    bound cannot follow (``step_pairing``)."""

    max_rate_change: float | None = None
    pair_rate_change: float | None = None
    max_shift: float | None = None
    between_tolerance: float | None = None
    smooth_s: float | None = None
    max_rate_step: float | None = None
    step_pairing: bool | None = None

    def __post_init__(self):
        from dancekit.motion import timewarp as tw

        for k in ("max_rate_change", "pair_rate_change"):
            _set(self, k, _optional(_number, f"stages.beat_sync.{k}", getattr(self, k), lo=0, lo_open=True, hi=1,
                                    hi_open=True))
        for k in ("max_shift", "smooth_s", "max_rate_step"):
            _set(self, k, _optional(_number, f"stages.beat_sync.{k}", getattr(self, k), lo=0, lo_open=True))
        _set(self, "between_tolerance", _optional(_number, "stages.beat_sync.between_tolerance",
                                                  self.between_tolerance, lo=0, unit="s"))
        _optional(_flag, "stages.beat_sync.step_pairing", self.step_pairing)
        top = tw.DEFAULT_MAX_RATE_CHANGE if self.max_rate_change is None else self.max_rate_change
        pair = tw.DEFAULT_PAIR_RATE_CHANGE if self.pair_rate_change is None else self.pair_rate_change
        if pair > top:
            raise ParameterError(f"stages.beat_sync.pair_rate_change must be <= max_rate_change ({top:g}), got {pair!r}")

    def warp_options(self) -> dict[str, float | bool]:
        """The :func:`~dancekit.motion.timewarp.beat_warp` keyword arguments that are set."""
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


#: stage name → its settings dataclass (the keys of a checkpoint's ``"stages"`` entry)
STAGE_CONFIGS: dict[str, type] = {"clean_up": CleanUpConfig, "smooth": SmoothConfig, "lift_energy": EnergyConfig,
                                  "jitter_cap": JitterCapConfig, "foot_lock": FootLockConfig, "settle": SettleConfig,
                                  "reground": RegroundConfig, "beat_sync": BeatSyncConfig}


@dataclass(frozen=True)
class EditConfig:
    """The edit stage (:func:`dancekit.pipelines.stages.stage_edit`, :mod:`dancekit.motion.edit`): the user's
    constraints on one run, applied to the finished dance after every other stage, but for a path, which
    :func:`~dancekit.pipelines.stages.finish` applies before the foot lock too (not a checkpoint setting).

    ``prefix``: a motion file kept exactly for its length, the dance continuing from it; ``keyframes``: a
    ``keys.json``; ``path``: a ``path.json``; ``keep``: ``"upper"``, ``"lower"`` or joint names (a tuple, or a
    comma-separated string) taken from the motion file ``take``; ``support_s`` (s): half-width of a key's
    correction; ``crossfade_s`` (s): the fade after the prefix; ``max_speed`` (m/s): keys needing a faster
    joint are refused. A contradictory request (``keep`` without ``take``, a prefix with a path) is a
    ParameterError; so is a file that does not exist."""

    prefix: str | None = None
    keyframes: str | None = None
    path: str | None = None
    keep: str | tuple[str, ...] | None = None
    take: str | None = None
    support_s: float = 1.0
    crossfade_s: float = 0.5
    max_speed: float = 5.0

    def __post_init__(self):
        for k in ("prefix", "keyframes", "path", "take"):
            v = getattr(self, k)
            if v is not None:
                if not os.path.isfile(v):
                    raise ParameterError(f"edit: {k} file not found: {v}")
                _set(self, k, str(v))
        if (self.keep is None) != (self.take is None):
            raise ParameterError("edit: keep (--keep) and take (--from) go together")
        if self.prefix is not None and self.path is not None:
            raise ParameterError(f"edit: a prefix ({self.prefix}) fixes the root's path for its length; "
                                 "it cannot be given with a path")
        if self.prefix is not None and self.keep is not None:
            raise ParameterError(f"edit: a prefix ({self.prefix}) fixes every joint for its length; "
                                 "it cannot be given with kept body parts")
        if isinstance(self.keep, list):
            _set(self, "keep", tuple(self.keep))
        _set(self, "support_s", _number("edit.support_s", self.support_s, lo=0, lo_open=True, unit="s"))
        _set(self, "crossfade_s", _number("edit.crossfade_s", self.crossfade_s, lo=0, lo_open=True, unit="s"))
        _set(self, "max_speed", _number("edit.max_speed", self.max_speed, lo=0, lo_open=True, unit="m/s"))

    @property
    def active(self) -> bool:
        """Whether any constraint is given."""
        return any(v is not None for v in (self.prefix, self.keyframes, self.path, self.keep))


@dataclass(frozen=True)
class StageConfig:
    """The offline stages of a checkpoint: one settings dataclass per stage (None: the stage is off for this
    checkpoint: no energy lift, jitter cap or regrounding), the per-genre statistics they compare a dance
    with, and ``enabled``, the stages switched on for a run (:meth:`switched`). ``StageConfig()``: every
    stage at its defaults, as for a checkpoint without a ``"stages"`` entry."""

    clean_up: CleanUpConfig = field(default_factory=CleanUpConfig)
    smooth: SmoothConfig = field(default_factory=SmoothConfig)
    lift_energy: EnergyConfig | None = None
    jitter_cap: JitterCapConfig | None = None
    foot_lock: FootLockConfig = field(default_factory=FootLockConfig)
    settle: SettleConfig = field(default_factory=SettleConfig)
    reground: RegroundConfig | None = None
    beat_sync: BeatSyncConfig = field(default_factory=BeatSyncConfig)
    genre_stats: GenreStats = field(default_factory=GenreStats)
    enabled: frozenset[str] = frozenset(STAGE_NAMES)
    #: the user's edit of this run (:class:`EditConfig`), run after every other stage (a path also before the
    #: foot lock); None: no edit
    edit: EditConfig | None = None

    def __post_init__(self):
        unknown = set(self.enabled) - set(STAGE_NAMES)
        if unknown:
            raise ParameterError(f"unknown stages {sorted(unknown)}; the stages are {', '.join(STAGE_NAMES)}")
        _set(self, "enabled", frozenset(self.enabled))
        if self.lift_energy is not None and self.lift_energy.fraction is not None and not self.genre_stats.energy:
            raise ParameterError("stages.lift_energy.fraction needs a genre_stats.energy table")
        if self.jitter_cap is not None and self.jitter_cap.max_jitter is None and not self.genre_stats.jitter:
            raise ParameterError("stages.jitter_cap needs a genre_stats.jitter table")
        if self.foot_lock.plant and not self.genre_stats.planted_share:
            raise ParameterError("stages.foot_lock.plant needs a genre_stats.planted_share table")
        missing = sorted(set(self.smooth.genre_targets) - set(self.genre_stats.table("smoothing")))
        if missing:
            raise ParameterError(f"stages.smooth.genre_targets {missing} have no genre_stats.smoothing value")

    def switched(self, *, beat_sync: bool = True, cleanup: bool = True, foot_lock: bool | None = None,
                 smooth: bool | None = None, energy: bool | None = None) -> StageConfig:
        """This configuration with the stages switched as ``dancekit dance`` does: ``cleanup`` the clean-up and,
        unless given, the smoothing, the energy lift and the foot lock (with the jitter cap, the settle and the
        regrounding, which belong to the lock); ``beat_sync`` the warp."""
        on = {"clean_up": cleanup, "smooth": cleanup if smooth is None else smooth,
              "lift_energy": cleanup if energy is None else energy, "beat_sync": beat_sync}
        lock = cleanup if foot_lock is None else foot_lock
        on.update({k: lock for k in ("jitter_cap", "foot_lock", "settle", "reground")})
        return dataclasses.replace(self, enabled=frozenset(k for k, v in on.items() if v))

    def order(self) -> tuple[str, ...]:
        """The stages that run, in order: the configured ones that are enabled (the energy lift runs, as a
        no-op, without settings; the jitter cap and the regrounding only with theirs)."""
        cap_after = self.jitter_cap is not None and self.jitter_cap.after_lock
        names = ["clean_up", "smooth", "lift_energy"] + ([] if cap_after else ["jitter_cap"]) \
            + ["foot_lock", "settle"] + (["jitter_cap"] if cap_after else []) + ["reground", "beat_sync"]
        configured = {"jitter_cap": self.jitter_cap is not None, "reground": self.reground is not None}
        return tuple(n for n in names if n in self.enabled and configured.get(n, True))


# --- the sampling settings of each family ------------------------------------------------------------------------

@dataclass(frozen=True)
class NoSampling:
    """A family without sampling settings (its ``"sampling"`` entry must be empty)."""


@dataclass(frozen=True)
class RevolutionSampling:
    """Dance Revolution's sampling (:class:`~dancekit.models.revolution.SeedVariety` and the genre draw,
    :class:`~dancekit.pipelines.revolution.GenreDraw`): ``phrase_s`` (s), ``state_noise``, ``latent_noise``,
    ``dance_latent``, ``style``, ``style_share`` (the seed variety, 0: off); ``genre_temperature`` τ ≥ 0,
    ``genre_alone`` w ∈ [0, 1), ``genre_draw_seed0``, ``genre_min_ratio`` ρ ∈ [0, 1], ``genre_max_jitter`` k ≥ 0
    (with ``genre_stats.jitter``) and ``genre_draw_spread`` (the genre draw)."""

    phrase_s: float = 0.0
    state_noise: float = 0.0
    latent_noise: float = 0.0
    dance_latent: float = 0.0
    style: float = 0.0
    style_share: float = 0.0
    genre_temperature: float = 0.0
    genre_alone: float = 0.0
    genre_draw_seed0: bool = False
    genre_min_ratio: float = 0.0
    genre_max_jitter: float = 0.0
    genre_draw_spread: bool = False

    def __post_init__(self):
        for k in ("phrase_s", "state_noise", "latent_noise", "dance_latent", "style", "style_share",
                  "genre_temperature", "genre_max_jitter"):
            _set(self, k, _number(f"sampling.{k}", getattr(self, k), lo=0))
        _set(self, "genre_alone", _number("sampling.genre_alone", self.genre_alone, lo=0, hi=1, hi_open=True))
        _set(self, "genre_min_ratio", _number("sampling.genre_min_ratio", self.genre_min_ratio, lo=0, hi=1))
        _flag("sampling.genre_draw_seed0", self.genre_draw_seed0)
        _flag("sampling.genre_draw_spread", self.genre_draw_spread)


@dataclass(frozen=True)
class Music2DanceGenreSampling:
    """Music2Dance's sampling for one genre asked for by name (None: the plain setting)."""

    temperature: float | None = None
    noise_correlation: float | None = None
    smooth_sigma: float | None = None
    genre_scale: float | None = None

    def __post_init__(self):
        for k in ("temperature", "smooth_sigma", "genre_scale"):
            _set(self, k, _optional(_number, f"sampling.genres.{k}", getattr(self, k), lo=0))
        _set(self, "noise_correlation", _optional(_number, "sampling.genres.noise_correlation",
                                                  self.noise_correlation, lo=0, hi=1, hi_open=True))

    def settings(self) -> dict[str, float]:
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


@dataclass(frozen=True)
class Music2DanceSampling:
    """Music2Dance's sampling (:meth:`~dancekit.models.music2dance.Music2DanceModel.generate`): the variance
    ``temperature`` (0: the means), the frame-to-frame ``noise_correlation`` ρ ∈ [0, 1), a Gaussian
    ``smooth_sigma`` (frames) of the sampled features and the dance-type guidance ``genre_scale`` α; ``genres``:
    genre → :class:`Music2DanceGenreSampling` for a genre asked for by name."""

    temperature: float = 1.0
    noise_correlation: float = 0.0
    smooth_sigma: float = 0.0
    genre_scale: float = 1.0
    genres: tuple[tuple[str, Music2DanceGenreSampling], ...] = ()

    def __post_init__(self):
        for k in ("temperature", "smooth_sigma", "genre_scale"):
            _set(self, k, _number(f"sampling.{k}", getattr(self, k), lo=0))
        _set(self, "noise_correlation", _number("sampling.noise_correlation", self.noise_correlation, lo=0, hi=1,
                                                hi_open=True))
        items = self.genres.items() if isinstance(self.genres, dict) else self.genres
        out = []
        for g, spec in items:
            if isinstance(spec, dict):
                try:
                    spec = parse_entry(Music2DanceGenreSampling, spec, f"sampling.genres.{g}")
                except ParameterError as exc:  # the genre named in the key
                    raise ParameterError(str(exc).replace("sampling.genres.", f"sampling.genres.{g}.", 1)
                                         if not str(exc).startswith("unknown") else str(exc)) from None
            elif not isinstance(spec, Music2DanceGenreSampling):
                raise ParameterError(f"sampling.genres.{g} must be an object, got {spec!r}")
            out.append((str(g), spec))
        _set(self, "genres", tuple(out))


@dataclass(frozen=True)
class DualSampling:
    """Dual learning's settings: G_M→D's output filtered by a centred moving average of ``smooth_frames`` frames
    or a ``lowpass_hz`` Butterworth low-pass (Hz), the root's 6D decoded by ``root_6d_decode``
    (``"gram_schmidt"`` or ``"procrustes"``); composing: ``beat_threshold``, ``beat_min_gap`` (s) and
    ``beat_tempo`` (``"dance"``: the arranger that follows the dance, :mod:`dancekit.pipelines.compose`; or
    G_D→M's own beats, ``"auto"`` (thresholded peaks) or ``"periodic"``)."""

    smooth_frames: int = 1
    lowpass_hz: float | None = None
    root_6d_decode: str = "gram_schmidt"
    beat_threshold: float = 0.5
    beat_min_gap: float = 0.25
    beat_tempo: str = "dance"

    def __post_init__(self):
        if isinstance(self.smooth_frames, bool) or not isinstance(self.smooth_frames, int) or self.smooth_frames < 1:
            raise ParameterError(f"sampling.smooth_frames must be an integer >= 1, got {self.smooth_frames!r}")
        _set(self, "lowpass_hz", _optional(_number, "sampling.lowpass_hz", self.lowpass_hz, lo=0, lo_open=True,
                                           unit="Hz"))
        if self.root_6d_decode not in ("gram_schmidt", "procrustes"):
            raise ParameterError(f"sampling.root_6d_decode must be 'gram_schmidt' or 'procrustes', "
                                 f"got {self.root_6d_decode!r}")
        _set(self, "beat_threshold", _number("sampling.beat_threshold", self.beat_threshold, lo=0, hi=1))
        _set(self, "beat_min_gap", _number("sampling.beat_min_gap", self.beat_min_gap, lo=0, unit="s"))
        if self.beat_tempo not in ("dance", "auto", "periodic"):
            raise ParameterError(f"sampling.beat_tempo must be 'dance', 'auto' or 'periodic', got {self.beat_tempo!r}")


# --- parsing -----------------------------------------------------------------------------------------------------

def parse_entry(cls: type, spec: Any, where: str):
    """``spec`` (a JSON object) as ``cls`` (a settings dataclass): ParameterError for a non-object or an
    unknown key (naming ``where`` and the key), else whatever ``cls``'s checks raise."""
    if spec is None:
        spec = {}
    if not isinstance(spec, dict):
        raise ParameterError(f"{where} must be an object, got {spec!r}")
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = [k for k in spec if k not in names]
    if unknown:
        raise ParameterError(f"unknown key {where}.{unknown[0]}" + (f" (it takes {', '.join(names)})" if names
                                                                   else " (it takes none)"))
    return cls(**spec)


@dataclass(frozen=True)
class CheckpointSettings:
    """What a dance pipeline reads of its checkpoint's ``config.json`` for inference, parsed once
    (:func:`checkpoint_settings`): the offline stages (:class:`StageConfig`, with the genre statistics) and
    the family's sampling settings."""

    stages: StageConfig
    sampling: Any


def checkpoint_settings(meta: dict[str, Any], *, folder: str | os.PathLike = "?",
                        sampling: type = NoSampling) -> CheckpointSettings:
    """The parsed ``"stages"``, ``"genre_stats"`` and ``"sampling"`` entries of a checkpoint's ``config.json``
    (``meta``, as read by :func:`dancekit.checkpoints.load_pretrained`), ``sampling`` the family's sampling
    dataclass. An old-layout checkpoint is converted first (:func:`convert_old_layout`, one warning).

    Raises
    ------
    CheckpointError
        Naming the folder and the key, for an unknown top-level key, an unknown key in these entries, or a
        value of the wrong type or outside its range (the message gives the allowed range)."""
    meta = convert_old_layout(meta, folder=folder, family=str(meta.get("model", "")))
    try:
        unknown = [k for k in meta if k not in TOP_LEVEL_KEYS]
        if unknown:
            raise ParameterError(f"unknown key {unknown[0]!r} (a checkpoint's config.json takes "
                                 f"{', '.join(sorted(TOP_LEVEL_KEYS))})")
        stats = parse_entry(GenreStats, meta.get("genre_stats"), "genre_stats")
        spec = meta.get("stages") or {}
        if not isinstance(spec, dict):
            raise ParameterError(f"stages must be an object, got {spec!r}")
        bad = [k for k in spec if k not in STAGE_CONFIGS]
        if bad:
            raise ParameterError(f"unknown key stages.{bad[0]} (the stages are {', '.join(STAGE_NAMES)})")
        parts = {k: parse_entry(STAGE_CONFIGS[k], v, f"stages.{k}") for k, v in spec.items()}
        energy = parts.get("lift_energy")
        fps = meta.get("fps")
        if energy is not None and isinstance(fps, (int, float)) and not energy.band_hz < fps / 2:
            raise ParameterError(f"stages.lift_energy.band_hz must be below {fps / 2:g} Hz (half the {fps:g}-fps "
                                 f"frame rate), got {energy.band_hz!r}")
        config = StageConfig(genre_stats=stats, **parts)
        samp = parse_entry(sampling, meta.get("sampling"), "sampling")
    except (ParameterError, TypeError) as exc:
        raise CheckpointError(f"checkpoint {folder}: config.json: {exc}") from None
    return CheckpointSettings(stages=config, sampling=samp)


#: old top-level entry → where it goes (the stage entries of releases before the typed configuration)
_OLD_STAGE_KEYS = ("smoothing", "energy", "jitter_cap", "plant", "settle", "foot_lock", "ground", "beat_sync",
                   "genre_sampling", "smooth_frames", "lowpass_hz", "root_6d_decode", "beat_threshold",
                   "beat_min_gap", "beat_tempo")
_warned: set[str] = set()


def _put_table(stats: dict, name: str, table: Any, where: str) -> None:
    if table is None:
        return
    if name in stats and stats[name] != table:
        raise ParameterError(f"{where} differs from another genre_stats.{name} table of the same checkpoint")
    stats[name] = table


def convert_old_layout(meta: dict[str, Any], *, folder: str | os.PathLike = "?", family: str = "") -> dict[str, Any]:
    """``meta`` in the current layout: a ``config.json`` of an earlier release (stage settings as loose top-level
    entries, the per-genre tables inside them, revolution's jitter cap in its ``"sampling"``) converted to the
    ``"stages"`` / ``"sampling"`` / ``"genre_stats"`` entries, with one warning line per folder (logger
    ``dancekit.checkpoints``);
    a current one is returned as it is. A malformed old entry is a CheckpointError naming the folder."""
    old = [k for k in _OLD_STAGE_KEYS if k in meta]
    samp = meta.get("sampling")
    rev_cap = isinstance(samp, dict) and any(k in samp for k in ("genre_jitter", "jitter_cap", "jitter_cap_min_ratio",
                                                                 "jitter_cap_all", "jitter_cap_to_end"))
    if not old and not rev_cap:
        return meta
    if "stages" in meta or "genre_stats" in meta:
        raise CheckpointError(f"checkpoint {folder}: config.json mixes the old stage entries {old} with 'stages'")
    key = str(folder)
    if key not in _warned:
        _warned.add(key)
        log.warning(f"dancekit: checkpoint {folder}: converting the stage settings of an earlier release "
                    f"({', '.join(old + (['sampling'] if rev_cap else []))}) to 'stages' / 'sampling' / "
                    f"'genre_stats' on reading")
    out = {k: v for k, v in meta.items() if k not in old}
    stages: dict[str, Any] = {}
    stats: dict[str, Any] = {}
    sampling = dict(samp) if isinstance(samp, dict) else samp

    def obj(name: str) -> dict:
        v = meta[name]
        if not isinstance(v, dict):
            raise CheckpointError(f"checkpoint {folder}: config.json: {name} must be an object, got {v!r}")
        return dict(v)

    try:
        if rev_cap:
            _put_table(stats, "jitter", sampling.pop("genre_jitter", None), "sampling.genre_jitter")
            cap = {"scale": sampling.pop("jitter_cap", None), "min_ratio": sampling.pop("jitter_cap_min_ratio", None),
                   "all": sampling.pop("jitter_cap_all", None), "to_end": sampling.pop("jitter_cap_to_end", None)}
            if cap["scale"] not in (None, 0, 0.0):
                stages["jitter_cap"] = {k: v for k, v in cap.items() if v is not None}
        if "smoothing" in meta:
            spec = obj("smoothing")
            table = spec.pop("genre_targets", None)
            _put_table(stats, "smoothing", table, "smoothing.genre_targets")
            stages["smooth"] = {**spec, **({"genre_targets": list(table)} if table else {})}
        if "energy" in meta:
            spec = obj("energy")
            _put_table(stats, "energy", spec.pop("genre_energy", None), "energy.genre_energy")
            for k in ("root", "legs"):
                if k in spec and spec[k] in (0, 1) and not isinstance(spec[k], bool):
                    spec[k] = bool(spec[k])
            if spec:
                stages["lift_energy"] = spec
        if "jitter_cap" in meta:
            spec = obj("jitter_cap")
            _put_table(stats, "jitter", spec.pop("genre_jitter", None), "jitter_cap.genre_jitter")
            cap = {"scale": spec.pop("jitter_cap", None), "min_ratio": spec.pop("jitter_cap_min_ratio", None)}
            stages["jitter_cap"] = {**{k: v for k, v in cap.items() if v is not None}, "all": True, "named": True,
                                    **spec}
        if "plant" in meta:
            spec = obj("plant")
            _put_table(stats, "planted_share", spec.pop("genre_share", None), "plant.genre_share")
            if spec:
                raise ParameterError(f"unknown key plant.{next(iter(spec))}")
            stages.setdefault("foot_lock", {})["plant"] = True
        if "foot_lock" in meta:
            stages["foot_lock"] = {**obj("foot_lock"), **stages.get("foot_lock", {})}
        if "settle" in meta:
            stages["settle"] = obj("settle")
        if "ground" in meta:
            spec = obj("ground")
            if "after_lock_s" in spec:
                spec["window_s"] = spec.pop("after_lock_s")
                stages["reground"] = spec
            elif spec:
                raise ParameterError("ground.max_float_cm needs an after_lock_s window")
        if "beat_sync" in meta:
            stages["beat_sync"] = obj("beat_sync")
        if "genre_sampling" in meta:
            sampling = dict(sampling or {})
            sampling["genres"] = obj("genre_sampling")
        loose = {k: meta[k] for k in ("smooth_frames", "lowpass_hz", "root_6d_decode", "beat_threshold",
                                      "beat_min_gap", "beat_tempo") if k in meta}
        if loose:
            sampling = {**(sampling or {}), **loose}
    except ParameterError as exc:
        raise CheckpointError(f"checkpoint {folder}: config.json: {exc}") from None
    if stages:
        out["stages"] = stages
    if stats:
        out["genre_stats"] = stats
    if sampling is not None:
        out["sampling"] = sampling
    return out


def read_checkpoint_settings(folder: str | os.PathLike, *, sampling: type | None = None) -> CheckpointSettings:
    """:func:`checkpoint_settings` of the checkpoint folder ``folder`` (its ``config.json`` read here); ``sampling``
    default: the family's (its pipeline's ``sampling_config``, :class:`NoSampling` for a family without one).
    A folder that is not a checkpoint is a :class:`~dancekit.errors.CheckpointError`."""
    from dancekit.checkpoints.hub import read_meta

    meta = read_meta(folder)
    if sampling is None:
        sampling = SAMPLING_CONFIGS.get(str(meta["model"]), NoSampling)
    return checkpoint_settings(meta, folder=folder, sampling=sampling)


def read_stage_config(folder: str | os.PathLike) -> StageConfig:
    """The :class:`StageConfig` of the checkpoint folder ``folder`` (:func:`read_checkpoint_settings`)."""
    return read_checkpoint_settings(folder).stages


#: family → its sampling settings dataclass (a family not listed has none)
SAMPLING_CONFIGS: dict[str, type] = {"revolution": RevolutionSampling, "music2dance": Music2DanceSampling,
                                     "dual": DualSampling}
