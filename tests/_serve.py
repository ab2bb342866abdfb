"""Helpers of the ``dancekit serve`` tests: songs made here, a real server on the loopback."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dancekit.audio import save_wav
from dancekit.audio.synth import ode_to_joy

SR = 22050


def need(module: str):
    """Import ``module`` (a package of the dev extra: FastAPI, httpx, Playwright); without it skip, or fail on CI
    (``CI=true``), where the serve tests must run."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        hint = f"{module} is missing: pip install -c constraints.txt -e '.[dev]'"
        if os.environ.get("CI", "").strip().lower() == "true":
            pytest.fail(f"CI=true but {hint}", pytrace=False)
        pytest.skip(hint, allow_module_level=True)


def ode_wav(path: Path, seconds: float) -> Path:
    """Ode to Joy (dancekit's synthesiser, 120 BPM), cut to ``seconds``, as a wav at ``path``."""
    y = ode_to_joy(sr=SR, bpm=120, repeats=int(np.ceil(seconds / 32.0)))
    save_wav(path, y[: int(seconds * SR)], sr=SR)
    return path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """``dancekit serve`` in a subprocess on 127.0.0.1 (a free port), started and waited for (at most ``timeout``
    seconds). It runs in a session of its own with its output in a file (no pipe to fill or to block a read while
    a job process still holds it); :meth:`stop` ends the server with its job processes, in bounded time."""

    def __init__(self, cache: Path, *args: str, timeout: float = 120.0):
        import httpx

        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        src = str(Path(__file__).resolve().parents[1] / "src")
        env = {**os.environ, "PYTHONPATH": src + os.pathsep + os.environ.get("PYTHONPATH", "")}
        self.log = Path(cache).parent / f"serve-{self.port}.log"
        self.log.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log, "wb") as log:
            self.proc = subprocess.Popen([sys.executable, "-m", "dancekit.cli.main", "serve", "--port", str(self.port),
                                          "--cache", str(cache), *args], env=env, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + timeout
        while True:
            if self.proc.poll() is not None:
                raise RuntimeError(f"dancekit serve exited with {self.proc.returncode}: {self.output()}")
            try:
                if httpx.get(self.url + "/api/options", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"dancekit serve did not answer in {timeout:g} s: {self.output()}")
            time.sleep(0.3)

    def output(self) -> str:
        """What the server printed so far."""
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def stop(self) -> str:
        """Stop the server (SIGTERM, then after 30 s SIGKILL to its whole process group); its output."""
        from _proc import kill_group

        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
        kill_group(self.proc, grace=5.0)  # any job process left behind
        return self.output()

    def pids(self) -> list[int]:
        """The server's process and its children (the workers)."""
        out = [self.proc.pid]
        children = Path(f"/proc/{self.proc.pid}/task/{self.proc.pid}/children")
        if children.exists():
            out += [int(p) for p in children.read_text().split()]
        return out


def rss_bytes(pid: int) -> int:
    """Resident memory of ``pid`` (Linux /proc), 0 when it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def wait_job(client, job_id: str, timeout: float = 180.0, states=("done", "failed", "cancelled")) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        s = client.get(f"/api/jobs/{job_id}").json()
        if s["state"] in states or time.monotonic() > deadline:
            return s
        time.sleep(0.2)
