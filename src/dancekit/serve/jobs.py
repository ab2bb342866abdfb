"""Jobs of ``dancekit serve``: a folder per job, a bounded queue, a pool of worker processes.

A job is the folder ``CACHE/<id>/`` (``id``: a random uuid4, 32 hex digits) holding ``status.json`` (written
atomically, by the server process alone), ``input/`` (the upload), ``work/`` (what a worker is writing) and,
once the job is done, ``files/`` (every output, complete). A job is ``queued`` → ``running`` → ``done``, or
``failed`` / ``cancelled``; a failed or cancelled job keeps only its ``status.json`` (the reason), no input
and no partial files. A server that starts on a cache folder keeps its finished jobs and marks the jobs
an earlier server left queued or running as failed.

The cache is bounded: finished jobs older than ``max_age_s`` are removed, then the oldest finished jobs
until the folder holds at most ``max_bytes`` (:meth:`JobManager.clean`, at start, after every job and
every few minutes). Queued and running jobs are never removed.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing as mp
import os
import re
import shutil
import threading
import time
import uuid
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dancekit._io import atomic_path
from dancekit.errors import DancekitError

JOB_ID = re.compile(r"^[0-9a-f]{32}$")
FINISHED = ("done", "failed", "cancelled")


class QueueFull(DancekitError):
    """The queue holds as many waiting jobs as it may (the API answers 429)."""


class UnknownJob(DancekitError):
    """No job has this id (the API answers 404)."""


class JobConflict(DancekitError):
    """The job is not in a state that allows the request (the API answers 409)."""


@dataclass
class ServeConfig:
    """Settings of ``dancekit serve``.

    ``workers``: worker processes (0: jobs wait in the queue; for tests); ``max_queue``: jobs that may wait
    for a worker; ``max_upload_bytes``: the largest upload; ``max_seconds``: the longest song (seconds);
    ``max_bytes`` / ``max_age_s``: the cache folder's bounds; ``threads``: torch threads per worker;
    ``preload``: models each worker loads before it takes jobs; ``token``: when set, every request must
    carry it; ``max_seeds``: seeds in one dance job; ``max_live``: live sessions (the browser's microphone, ``/live``)
    at once, each on the server's own process (0: none).
    """

    cache: Path
    workers: int = 1
    max_queue: int = 8
    max_upload_bytes: int = 100_000_000
    max_seconds: float = 20 * 60.0
    max_bytes: int = 2_000_000_000
    max_age_s: float = 7 * 24 * 3600.0
    threads: int = 1
    preload: list[str] = field(default_factory=list)
    token: str | None = None
    max_seeds: int = 8
    host: str = "127.0.0.1"
    max_live: int = 1

    def __post_init__(self):
        self.cache = Path(self.cache).expanduser()


def folder_size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


class JobManager:
    """The queue, the workers and the job folders. Thread-safe: the API calls it from its thread pool."""

    def __init__(self, config: ServeConfig):
        self.config = config
        self.root = config.cache
        self.lock = threading.RLock()
        self.jobs: dict[str, dict] = {}  # id -> status (the status.json contents)
        self.pending: deque[str] = deque()
        self.running: dict[str, int] = {}  # id -> worker index
        self.reserved = 0
        self.ctx = mp.get_context("spawn")  # no fork of a process with threads and torch
        self.workers: list[dict] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_clean = 0.0

    # ---- life cycle -------------------------------------------------------------------------------
    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        self.recover()
        self.clean()
        for i in range(self.config.workers):
            self.workers.append(self._spawn(i))
        self._thread = threading.Thread(target=self._loop, name="dancekit-serve-dispatch", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        for w in self.workers:
            with contextlib.suppress(Exception):
                w["conn"].send(None)
        for w in self.workers:
            w["proc"].join(timeout=3)
            if w["proc"].is_alive():
                _kill(w["proc"])
        with self.lock:
            for job_id in list(self.running) + list(self.pending):
                self._finish(job_id, "failed", error="the server stopped before the job finished")
            self.running.clear()
            self.pending.clear()

    def _spawn(self, index: int) -> dict:
        from dancekit.serve.worker import worker_main

        # one pipe per worker: a worker killed while it writes spoils only its own pipe, replaced with it
        ours, theirs = self.ctx.Pipe()
        proc = self.ctx.Process(target=worker_main, name=f"dancekit-serve-worker-{index}",
                                args=(index, theirs, list(self.config.preload), self.config.threads), daemon=True)
        proc.start()
        theirs.close()
        return {"index": index, "proc": proc, "conn": ours, "ready": False, "job": None}

    def ready_workers(self) -> int:
        """Workers that have loaded their models and warmed up (and so take jobs at once)."""
        with self.lock:
            return sum(1 for w in self.workers if w["ready"])

    def worker_pids(self) -> list[int]:
        return [w["proc"].pid for w in self.workers if w["proc"].pid is not None]

    # ---- job folders ------------------------------------------------------------------------------
    def folder(self, job_id: str) -> Path:
        if not JOB_ID.match(job_id):
            raise UnknownJob(f"no job {job_id!r}")
        return self.root / job_id

    def _write_status(self, status: dict) -> None:
        status["updated"] = time.time()
        path = self.root / status["id"] / "status.json"
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(status, indent=1))

    def recover(self) -> None:
        """Read the job folders an earlier server left: finished jobs are kept; queued or running ones are
        marked failed and their input and partial files removed; anything else is removed."""
        for path in sorted(self.root.iterdir()):
            status = None
            if path.is_dir() and JOB_ID.match(path.name):
                with contextlib.suppress(OSError, ValueError):
                    status = json.loads((path / "status.json").read_text())
            if not isinstance(status, dict) or status.get("id") != path.name:
                _remove(path)
                continue
            self.jobs[path.name] = status
            if status.get("state") not in FINISHED:
                self._finish(path.name, "failed", error="the server stopped before the job finished")

    def clean(self) -> list[str]:
        """Remove finished jobs past the age bound, then the oldest finished jobs over the size bound."""
        removed = []
        now = time.time()
        with self.lock:
            finished = sorted((s for s in self.jobs.values() if s["state"] in FINISHED), key=lambda s: s["updated"])
            for s in finished:
                if now - s["updated"] > self.config.max_age_s:
                    removed.append(s["id"])
            total = folder_size(self.root)
            for s in finished:
                if total <= self.config.max_bytes:
                    break
                if s["id"] not in removed:
                    removed.append(s["id"])
                    total -= folder_size(self.root / s["id"])
            for job_id in removed:
                self.jobs.pop(job_id, None)
                _remove(self.root / job_id)
        self._last_clean = now
        return removed

    # ---- the API's calls ----------------------------------------------------------------------------
    def reserve(self) -> None:
        """Hold a place in the queue for a job about to be created; raises :class:`QueueFull`."""
        with self.lock:
            if len(self.pending) + self.reserved >= self.config.max_queue:
                raise QueueFull(f"the queue is full ({self.config.max_queue} jobs waiting); try again later")
            self.reserved += 1

    def release(self) -> None:
        with self.lock:
            self.reserved -= 1

    def new_folder(self) -> tuple[str, Path]:
        """A fresh job id and its (hidden, not yet listed) staging folder ``CACHE/.new-<id>/input/``."""
        job_id = uuid.uuid4().hex
        stage = self.root / f".new-{job_id}"
        (stage / "input").mkdir(parents=True)
        return job_id, stage

    def submit(self, job_id: str, stage: Path, *, kind: str, input_file: str, input_name: str, stem: str,
               options: dict) -> dict:
        """Turn a staged folder (with its upload) into a queued job; uses the place :meth:`reserve` held."""
        status = {"id": job_id, "kind": kind, "state": "queued", "progress": 0.0, "message": "waiting for a worker",
                  "created": time.time(), "updated": time.time(), "input": input_file, "input_name": input_name,
                  "stem": stem, "options": options, "error": None, "result": None, "playable": [], "files": []}
        with atomic_path(stage / "status.json") as tmp:
            tmp.write_text(json.dumps(status, indent=1))
        with self.lock:
            os.replace(stage, self.root / job_id)
            self.reserved -= 1
            self.jobs[job_id] = status
            self.pending.append(job_id)
        return dict(status)

    def status(self, job_id: str) -> dict:
        self.folder(job_id)
        with self.lock:
            if job_id not in self.jobs:
                raise UnknownJob(f"no job {job_id!r}")
            status = dict(self.jobs[job_id])
        if status["state"] == "queued":
            with self.lock:
                status["queue_position"] = list(self.pending).index(job_id) + 1 if job_id in self.pending else 0
        return status

    def list(self) -> list[dict]:
        with self.lock:
            return [dict(s) for s in sorted(self.jobs.values(), key=lambda s: s["created"], reverse=True)]

    def file_path(self, job_id: str, name: str) -> Path:
        """The path of the job's file ``name``: only a name the job lists (done: its files; running: the
        players written so far), never a path the client made up."""
        status = self.status(job_id)
        if status["state"] == "done" and name in {f["name"] for f in status["files"]}:
            return self.root / job_id / "files" / name
        if status["state"] == "running" and name in status["playable"]:
            return self.root / job_id / "work" / name
        if status["state"] in ("failed", "cancelled"):
            raise JobConflict(f"job {job_id} {status['state']}: it has no files")
        raise UnknownJob(f"job {job_id} has no file {name!r}")

    def cancel(self, job_id: str) -> dict:
        """Cancel a queued job, or a running one (its worker is stopped and replaced)."""
        self.folder(job_id)
        with self.lock:
            status = self.jobs.get(job_id)
            if status is None:
                raise UnknownJob(f"no job {job_id!r}")
            if status["state"] in FINISHED:
                raise JobConflict(f"job {job_id} is already {status['state']}")
            if job_id in self.pending:
                self.pending.remove(job_id)
            elif job_id in self.running:
                index = self.running.pop(job_id)
                w = self.workers[index]
                _kill(w["proc"])
                w["conn"].close()
                self.workers[index] = self._spawn(index)
            self._finish(job_id, "cancelled", error="cancelled")
            return dict(self.jobs[job_id])

    def delete(self, job_id: str) -> None:
        """Remove a finished job and its files (a queued or running one is cancelled first)."""
        with contextlib.suppress(JobConflict):
            self.cancel(job_id)
        with self.lock:
            self.jobs.pop(job_id, None)
            _remove(self.root / job_id)

    # ---- the dispatcher thread -----------------------------------------------------------------------
    def _finish(self, job_id: str, state: str, *, error: str | None = None, result: Any = None) -> None:
        """Record a finished job (under the lock): a failed or cancelled one loses its input and files."""
        status = self.jobs[job_id]
        folder = self.root / job_id
        if state != "done":
            for sub in ("work", "files", "input"):
                _remove(folder / sub)
            status.update(state=state, error=error, playable=[], files=[], message=error or state)
        else:
            _remove(folder / "input")
            files = folder / "files"
            status.update(state="done", progress=1.0, message="done", result=result,
                          files=[{"name": p.name, "bytes": p.stat().st_size}
                                 for p in sorted(files.iterdir()) if p.is_file()])
        status["finished"] = time.time()
        self._write_status(status)

    def _handle(self, event: tuple) -> None:
        kind, *rest = event
        with self.lock:
            if kind == "ready":
                self.workers[rest[0]]["ready"] = True
                return
            job_id = rest[0]
            status = self.jobs.get(job_id)
            if status is None or status["state"] in FINISHED or job_id not in self.running:
                return  # a cancelled job's last words
            if kind == "started":
                return
            if kind == "progress":
                status.update(progress=round(rest[1], 4), message=rest[2])
            elif kind == "playable":
                status.update(playable=list(rest[1]), playable_at=time.time())
            elif kind in ("done", "failed"):
                index = self.running.pop(job_id)
                self.workers[index]["job"] = None
                if kind == "done":
                    self._finish(job_id, "done", result=rest[1])
                else:
                    self._finish(job_id, "failed", error=rest[1])
                return
            self._write_status(status)

    def _dispatch(self) -> None:
        with self.lock:
            for w in self.workers:
                if not w["proc"].is_alive():  # died (killed by the system): its job failed, a new worker
                    job_id = w["job"]
                    if job_id is not None and job_id in self.running:
                        self.running.pop(job_id)
                        self._finish(job_id, "failed", error=f"the worker stopped (exit code {w['proc'].exitcode})")
                    w["conn"].close()
                    self.workers[w["index"]] = w = self._spawn(w["index"])
                if w["ready"] and w["job"] is None and self.pending:
                    job_id = self.pending.popleft()
                    status = self.jobs[job_id]
                    w["job"] = job_id
                    self.running[job_id] = w["index"]
                    status.update(state="running", message="starting", started=time.time())
                    self._write_status(status)
                    w["conn"].send({"id": job_id, "folder": str(self.root / job_id), "kind": status["kind"],
                                    "input": status["input"], "input_name": status["input_name"],
                                    "stem": status["stem"], "options": status["options"]})

    def _events(self, timeout: float) -> list[tuple]:
        """The events the workers have sent (waiting up to ``timeout`` seconds for the first)."""
        from multiprocessing.connection import wait

        with self.lock:
            conns = [w["conn"] for w in self.workers if not w["conn"].closed]
        out = []
        try:
            ready = wait(conns, timeout=timeout) if conns else []
        except (OSError, ValueError):  # a pipe closed by cancel() meanwhile
            ready = []
        for conn in ready:
            with contextlib.suppress(EOFError, OSError):  # a worker that died (handled by _dispatch)
                while not conn.closed and conn.poll():
                    out.append(conn.recv())
        if not conns:
            time.sleep(timeout)
        return out

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                for event in self._events(0.1):
                    self._handle(event)
                self._dispatch()
                if time.time() - self._last_clean > 300:
                    self.clean()
            except Exception:  # the dispatcher must not die: the server would hang every job
                import traceback

                traceback.print_exc()
                time.sleep(0.5)


def _kill(proc) -> None:
    """Stop a worker and the programs it runs (its process group: ffmpeg encoders), and wait for it."""
    import signal

    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()  # not yet in its own group
    proc.join(timeout=10)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
