"""Live dancing: music in as it plays, poses out within half a second, on a CPU (``dancekit live``).

* :mod:`~dancekit.live.config` — :class:`LiveConfig`, the online stage settings
* :class:`OnlineFeatures` (:mod:`dancekit.features.online`) — the presets' rows as the audio arrives, and
  :class:`BeatTracker` (:mod:`dancekit.features.online_beats`), a causal phase-locked beat and tempo tracker:
  pure NumPy, in the features layer, so that a dataset can be prepared with the rows a live session computes
* :mod:`~dancekit.live.steppers` — the models stepped frame by frame with their state kept
* :mod:`~dancekit.live.stages` — the clean-up stages in an online form
* :mod:`~dancekit.live.session` — :class:`LiveSession`: sources in, pose frames out, latency logged
* :mod:`~dancekit.live.server` — the live page and its WebSocket pose stream
"""

from dancekit.features.online import OnlineFeatures
from dancekit.features.online_beats import Beat, BeatTracker
from dancekit.live.config import LiveConfig

__all__ = ["Beat", "BeatTracker", "LiveConfig", "OnlineFeatures"]
