"""Child processes of the tests that can never outlive their bound: a process started in a session of its own, so
that a timeout kills it with everything it started (a launcher's workers, a server's job processes)."""

from __future__ import annotations

import os
import signal
import subprocess


def kill_group(proc: subprocess.Popen, *, grace: float = 30.0) -> None:
    """Stop ``proc`` (started with ``start_new_session=True``) and its process group: SIGTERM, then after
    ``grace`` seconds SIGKILL; reaped either way."""
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 30.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:  # the group is gone
            pass
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def run(cmd: list[str], *, timeout: float, capture_output: bool = False, text: bool = False,
        **kwargs) -> subprocess.CompletedProcess:
    """:func:`subprocess.run` with a timeout that also ends the command's children: on ``timeout`` (seconds) the
    whole process group is killed and :class:`subprocess.TimeoutExpired` raised."""
    pipe = subprocess.PIPE if capture_output else None
    with subprocess.Popen(cmd, stdout=pipe, stderr=pipe, text=text, start_new_session=True, **kwargs) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            kill_group(proc, grace=0.0)
            raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)
