"""A song's music features computed in a second process while the first one loads its model.

A cold ``dancekit dance`` spends about two seconds importing torch and loading the model before it needs the
song's features, which take about one second more (60 s of music). :func:`prefetch_features` forks a child
process that computes them into the feature cache (:func:`~dancekit.features.extract_file`, whose entries are
written atomically) meanwhile, on another CPU core; the parent calls :meth:`Prefetch.wait` before it asks
for the features, which it then reads from the cache. The child's work is the parent's own: the same
function on the same arguments, so the dance is the same; if the child fails (an unreadable song, no cache
folder), the parent computes (and reports) as it would have without it.

Only where it can help and is safe: POSIX ``fork``, torch not imported yet in this process (a process that
has it loaded has nothing left to overlap, and may run threads), ``DANCEKIT_PREFETCH`` not ``0``, and a
clip of at most :data:`MAX_SECONDS` whose length the file's header gives: for a long song the second or
two of overlap is small against the whole run, and two processes would hold memory at once (issue 18 bounds
a 60-minute song's peak). The child writes nothing to stdout or stderr.
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

#: The longest clip (seconds) whose features are prefetched.
MAX_SECONDS = 600.0


class Prefetch:
    """The handle of a prefetching child process (``pid`` None: none was started)."""

    def __init__(self, pid: int | None = None):
        self.pid = pid

    @property
    def started(self) -> bool:
        return self.pid is not None

    def wait(self) -> bool:
        """Wait for the child; True when it computed the features (now in the cache)."""
        if self.pid is None:
            return False
        try:
            _, status = os.waitpid(self.pid, 0)
        except ChildProcessError:
            status = 1
        self.pid = None
        return os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0

    def cancel(self) -> None:
        """Stop the child if it still runs (its cache entry is then not written) and reap it."""
        if self.pid is None:
            return
        try:
            os.kill(self.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        self.wait()


def _child(path: Path, kwargs: dict) -> None:
    code = 1
    try:
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # unwinds: atomic writes remove their temp file
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle (it cancels the child)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        import warnings

        warnings.simplefilter("ignore")
        from dancekit.features.cache import extract_file

        extract_file(path, **kwargs)
        code = 0
    except BaseException:  # noqa: BLE001 - the parent recomputes and reports
        code = 1
    finally:
        os._exit(code)


def _short_enough(path: str | os.PathLike, start: float | None, end: float | None) -> bool:
    """Whether the clip ``[start, end)`` of ``path`` is known to last at most :data:`MAX_SECONDS`."""
    from dancekit.audio.io import duration

    try:
        total = duration(path)
    except Exception:  # noqa: BLE001 - the parent's own read reports a bad file
        return False
    if total is None:
        return False
    span = (total if end is None else min(float(end), total)) - (0.0 if start is None else float(start))
    return span <= MAX_SECONDS


def prefetch_features(path: str | os.PathLike, *, fps: float, preset: str, hop_length: int = 512,
                      start: float | None = None, end: float | None = None) -> Prefetch:
    """Start computing ``extract_file(path, fps=..., preset=..., hop_length=..., start=..., end=...)`` into the
    feature cache in a forked child process; a :class:`Prefetch` with no child where that cannot help (see
    the module docstring)."""
    if not hasattr(os, "fork") or "torch" in sys.modules or os.environ.get("DANCEKIT_PREFETCH", "1") == "0":
        return Prefetch()
    if not _short_enough(path, start, end):
        return Prefetch()
    kwargs = {"fps": float(fps), "preset": str(preset), "hop_length": int(hop_length), "start": start, "end": end}
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        pid = os.fork()
    except OSError:
        return Prefetch()
    if pid == 0:  # pragma: no cover - the child never returns
        _child(Path(path), kwargs)
    return Prefetch(pid)
