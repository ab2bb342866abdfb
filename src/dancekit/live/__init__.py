"""Live dancing: music in as it plays, poses out within half a second, on a CPU (``dancekit live``).

* :mod:`~dancekit.live.config` — :class:`LiveConfig`, the online stage settings
* :mod:`~dancekit.live.features` — :class:`OnlineFeatures`, the presets' rows as the audio arrives
* :mod:`~dancekit.live.beats` — :class:`BeatTracker`, a causal phase-locked beat and tempo tracker
* :mod:`~dancekit.live.steppers` — the models stepped frame by frame with their state kept
* :mod:`~dancekit.live.stages` — the clean-up stages in an online form
* :mod:`~dancekit.live.session` — :class:`LiveSession`: sources in, pose frames out, latency logged
* :mod:`~dancekit.live.server` — the live page and its WebSocket pose stream
"""

from dancekit.live.beats import Beat, BeatTracker
from dancekit.live.config import LiveConfig
from dancekit.live.features import OnlineFeatures

__all__ = ["Beat", "BeatTracker", "LiveConfig", "OnlineFeatures"]
