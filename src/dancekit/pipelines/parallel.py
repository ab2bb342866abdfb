"""Work split over forked processes: :func:`fork_map` runs a function on parts of a list, one process per part.

A dance's frames are decoded one after another and its stages run in NumPy, so the seeds of
``dancekit dance --seeds`` share one core in one process (threads gain nothing: each frame's small products hold
the interpreter). Forked after the model is loaded and the song's features are read, each process decodes its own
seeds with the same weights and the same arithmetic, so every dance is bit for bit the dance made alone.
"""

from __future__ import annotations

import os
import pickle
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = ["can_fork", "fork_map", "usable_cores"]

T = TypeVar("T")


def usable_cores() -> int:
    """The CPU cores this process may run on (its affinity where the system says, else ``os.cpu_count()``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def can_fork() -> bool:
    """Whether :func:`fork_map` forks here: Linux only (elsewhere, or where ``DANCEKIT_NO_FORK`` is set, one process)."""
    return sys.platform.startswith("linux") and hasattr(os, "fork") and not os.environ.get("DANCEKIT_NO_FORK")


def fork_map(fn: Callable[[T], Any], parts: Sequence[T]) -> list[Any]:
    """``[fn(p) for p in parts]``, the first part in this process and each other part in a forked child (its
    result pickled back through a pipe). An exception in a child is raised here (the first in part order); a child
    that dies without a result raises :class:`RuntimeError`. Without fork (:func:`can_fork`) the parts run here,
    one after another."""
    if len(parts) <= 1 or not can_fork():
        return [fn(p) for p in parts]
    children = []  # (pid, read end)
    try:
        for part in parts[1:]:
            r, w = os.pipe()
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
            if pid == 0:  # the child: compute, send, leave without running the parent's exit handlers
                os.close(r)
                code = 0
                try:
                    try:
                        payload = pickle.dumps((True, fn(part)), protocol=pickle.HIGHEST_PROTOCOL)
                    except BaseException as exc:  # noqa: BLE001 - sent to the parent, raised there
                        payload = pickle.dumps((False, exc), protocol=pickle.HIGHEST_PROTOCOL)
                    with os.fdopen(w, "wb") as fh:
                        fh.write(payload)
                except BaseException:  # noqa: BLE001 - nothing can be reported: the parent sees no result
                    code = 1
                finally:
                    os._exit(code)
            os.close(w)
            children.append((pid, r))
        first = fn(parts[0])
        results = [first]
        errors = []
        for pid, r in children:
            with os.fdopen(r, "rb") as fh:
                data = fh.read()
            os.waitpid(pid, 0)
            if not data:
                errors.append(RuntimeError("a worker process ended without a result"))
                results.append(None)
                continue
            ok, value = pickle.loads(data)
            if not ok:
                errors.append(value)
            results.append(value if ok else None)
        children = []
        if errors:
            raise errors[0]
        return results
    finally:  # an exception in this process: the children are not left running or as zombies
        for pid, r in children:
            try:
                os.kill(pid, 9)
                os.waitpid(pid, 0)
            except OSError:
                pass
            try:
                os.close(r)
            except OSError:
                pass
