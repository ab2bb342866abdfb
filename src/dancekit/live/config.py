"""The online stage settings of ``dancekit live`` (:class:`LiveConfig`): one frozen dataclass, units in the names.

Every time below is seconds of audio (the clock of the music), every rate a fraction. The offline stage
settings live beside the pipelines; these are their online counterparts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from dancekit.errors import ParameterError
from dancekit.features.online import TEMPOGRAM_FUTURES

__all__ = ["BEAT_NUDGE", "LIVE_FAMILIES", "NUDGES", "SMOOTHING", "LiveConfig"]

#: the model families that can dance live (:func:`dancekit.live.steppers.make_stepper` has a stepper for each)
LIVE_FAMILIES = ("revolution", "music2dance")

#: the beat nudge of each model family when ``LiveConfig.beat_nudge`` is None (another family: ``"target"``):
#: music2dance's pulse (within its ±40 % warp bound) raised its validation BAS from 0.197 to 0.425 with its FIDs
#: within 3.3 %; revolution's (±15 %) from 0.160 to 0.249 but put a song over the stillness bound twice
#: (docs/research/live.md, rounds 14-15)
BEAT_NUDGE = {"revolution": "target", "music2dance": "pulse"}

#: the beat nudge's ways of following the beat (``LiveConfig.beat_nudge``, :class:`dancekit.live.stages.BeatNudge`)
NUDGES = ("target", "pulse", "pulse_moving")

#: how Music2Dance's sampled features may be smoothed live (``LiveConfig.sample_smoothing``)
SMOOTHING = ("delay", "causal")


@dataclass(frozen=True)
class LiveConfig:
    """Settings of a live session (:class:`dancekit.live.LiveSession`).

    Attributes
    ----------
    block_s : length of the audio blocks a file or stdin source delivers (s, > 0); a microphone delivers
        blocks of this length too
    lookahead_s : audio after a frame that its features may see before the row is made (s, ≥ 0). The
        offline extractor's support is about 0.9 s (the lowest constant-Q filter, the MFCC delta's ±4 frames):
        with ``lookahead_s ≥ EXACT_LOOKAHEAD_S`` the online features equal the offline ones
        (``tests/live/test_live.py``); less trades that for latency (0.08 s: the mel spectrogram's own window)
    model_lookahead_s : feature rows after a frame that the model's music encoder may see (s, ≥ 0; whole
        frames, rounded up). With ``lookahead_s`` it is the latency floor: ``lookahead_s + model_lookahead_s``
        plus up to one block
    context_s : audio history the online features are recomputed over at each block (s, ≥ 5: the constant-Q
        chromagram's 4 s margin fits)
    encoder_context_s : music history the Dance Revolution encoder sees for each new latent (s, ≥ 0); its
        receptive field (4 s for the embedded model) makes the history exact
    beat_window_s : onset history the beat tracker's tempo and phase are estimated over (s, ≥ 2)
    tempogram_future : how Dance Revolution's tempogram (a window of ±7.7 s at 25 fps) fills its future half:
        ``"bar"``, the onset envelope's last bar repeated (the row up to date), or ``"none"``, the rows delayed by
        half the window (:class:`dancekit.features.online.OnlineFeatures`). Chosen on the validation songs
        (docs/research/live.md)
    smooth_hz : cut-off of the causal one-pole smoothing of the joints (Hz, > 0; ``inf``: off)
    floor_window_s : the floor is the lowest joint's lowest height over this past window (s, > 0)
    silence_db : a block whose RMS is below this level (dB full scale) is silence (the dancer calms)
    calm : how much of the movement is left while the music is silent or not music (0 … 1; offline: 0.4)
    calm_glide_s : time constant of the glide between dancing and calm (s, > 0)
    rate_bound : the beat alignment nudges the playback rate of the dance within ``1 ± rate_bound`` (0: no
        nudge); None: the offline warp's bound of the model (its checkpoint's ``stages.beat_sync.max_rate_change``:
        ±40 % for the embedded music2dance; else ±15 %)
    max_lag_s : behind the clock by more than this (s, > 0), the session drops to its lighter path (the
        chromagram held, not recomputed) and says so; behind by more than ``3 × max_lag_s`` it drops blocks
    seed : the seed of the model's draws
    sample_smoothing : Music2Dance's Gaussian smoothing of the sampled features (the checkpoint's
        ``smooth_sigma`` σ, per genre where it has one; offline a centred kernel of radius ``r = round(3σ)``
        frames): ``"delay"``, the centred kernel with each frame held back ``r`` frames (the offline smoothing
        exactly; ``r / fps`` s more lookahead: 0.24 s for the embedded model), or ``"causal"``, the kernel's
        past half (no frame held back; a weaker low-pass that lags the movement by about 0.65 σ frames).
        Chosen on the validation songs (docs/research/live.md)
    smoothing_hold_s : with ``"delay"``, hold each frame back at most this long (s, ≥ 0; the kernel's lags
        beyond it dropped, the rest renormalised); None: the kernel's radius (the offline smoothing exactly,
        0.24 s for the embedded model). 0.08 s keeps music2dance's latency within 0.3 s; chosen on the validation
        songs (docs/research/live.md)
    beat_nudge : how the beat alignment moves the dance's clock (:class:`dancekit.live.stages.BeatNudge`):
        ``"target"``, the model's next kinematic beat nudged onto the tracker's next beat, or ``"pulse"``, the
        rate slowest on each beat and fastest between two (the speed dips on the beats), or ``"pulse_moving"``,
        the pulse only while the dancer moves (shallower under 0.2 m/s, none at 0.1), all within ``rate_bound``;
        None: the model family's (:data:`BEAT_NUDGE`). Chosen per family on the validation
        songs (docs/research/live.md, rounds 14-15)
    jitter_cap : the checkpoint's jitter cap online (its ``stages.jitter_cap`` and ``genre_stats.jitter``): the
        smoothing's cut-off lowered until the dance's recent jitter is under the cap, the genres it follows read
        from the music heard so far by the checkpoint's ``genre_reader`` (a reader of the session's feature
        preset; a genre asked for by name: its own). A model without them is not capped.
    foot_lock : hold every planted foot where it was planted, causally (:class:`dancekit.live.stages.OnlineFootLock`:
        the offline lock's contact thresholds, no lookahead; the legs only change). Chosen on the validation
        songs for both models: foot skating 0.71 → 0.42 (revolution) and 0.84 → 0.57 (music2dance), their FIDs
        and BAS as good or better (docs/research/live.md, round 17)
    """

    block_s: float = 0.04
    lookahead_s: float = 0.08
    model_lookahead_s: float = 0.08
    context_s: float = 6.0
    encoder_context_s: float = 4.0
    beat_window_s: float = 6.0
    tempogram_future: str = "bar"
    smooth_hz: float = 6.0
    floor_window_s: float = 2.0
    silence_db: float = -50.0
    calm: float = 0.4
    calm_glide_s: float = 0.5
    rate_bound: float | None = None
    max_lag_s: float = 0.25
    seed: int = 0
    sample_smoothing: str = "delay"
    smoothing_hold_s: float | None = 0.08
    beat_nudge: str | None = None
    jitter_cap: bool = False
    foot_lock: bool = True

    #: lookahead (s) at which the online features equal the offline extractor's (the constant-Q support)
    EXACT_LOOKAHEAD_S = 1.0

    def __post_init__(self) -> None:
        def number(name: str) -> float:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v):
                raise ParameterError(f"LiveConfig.{name} must be a number, got {v!r}")
            return float(v)

        checks = {
            "block_s": lambda v: 0 < v <= 2.0, "lookahead_s": lambda v: 0 <= v <= 10.0, "model_lookahead_s": lambda v: 0 <= v <= 10.0,
            "context_s": lambda v: 5.0 <= v <= 60.0, "encoder_context_s": lambda v: 0 <= v <= 60.0,
            "beat_window_s": lambda v: 2.0 <= v <= 30.0, "smooth_hz": lambda v: v > 0,
            "floor_window_s": lambda v: 0 < v <= 60.0, "silence_db": lambda v: -120 <= v <= 0,
            "calm": lambda v: 0 <= v <= 1, "calm_glide_s": lambda v: 0 < v <= 10,
            "rate_bound": lambda v: 0 <= v < 0.5, "max_lag_s": lambda v: 0 < v <= 10,
            "smoothing_hold_s": lambda v: 0 <= v <= 10,
        }
        ranges = {"block_s": "(0, 2] s", "lookahead_s": "[0, 10] s", "model_lookahead_s": "[0, 10] s", "context_s": "[5, 60] s",
                  "encoder_context_s": "[0, 60] s", "beat_window_s": "[2, 30] s", "smooth_hz": "> 0 Hz",
                  "floor_window_s": "(0, 60] s", "silence_db": "[-120, 0] dB", "calm": "[0, 1]",
                  "calm_glide_s": "(0, 10] s", "rate_bound": "[0, 0.5)", "max_lag_s": "(0, 10] s",
                  "smoothing_hold_s": "[0, 10] s"}
        for name, ok in checks.items():
            if name in ("rate_bound", "smoothing_hold_s") and getattr(self, name) is None:
                continue
            if not ok(number(name)):
                raise ParameterError(f"LiveConfig.{name} must be in {ranges[name]}, got {getattr(self, name)!r}")
        for flag in ("jitter_cap", "foot_lock"):
            if not isinstance(getattr(self, flag), bool):
                raise ParameterError(f"LiveConfig.{flag} must be true or false, got {getattr(self, flag)!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ParameterError(f"LiveConfig.seed must be an integer, got {self.seed!r}")
        if self.tempogram_future not in TEMPOGRAM_FUTURES:
            raise ParameterError(f"LiveConfig.tempogram_future must be one of {TEMPOGRAM_FUTURES}, "
                                 f"got {self.tempogram_future!r}")
        if self.beat_nudge is not None and self.beat_nudge not in NUDGES:
            raise ParameterError(f"LiveConfig.beat_nudge must be one of {NUDGES} or None, got {self.beat_nudge!r}")
        if self.sample_smoothing not in SMOOTHING:
            raise ParameterError(f"LiveConfig.sample_smoothing must be 'delay' or 'causal', got {self.sample_smoothing!r}")

    @classmethod
    def from_dict(cls, spec: dict) -> LiveConfig:
        """A config from a mapping of field names (an unknown key is an error that names it)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(spec) - known)
        if unknown:
            raise ParameterError(f"unknown live setting(s) {unknown}; known: {sorted(known)}")
        return cls(**spec)
