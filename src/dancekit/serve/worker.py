"""The worker process of ``dancekit serve``: models loaded once, one job at a time, events back to the server.

A worker reads job descriptions from its pipe and sends events back on it:
``("ready", worker)``, ``("started", job_id, worker)``, ``("progress", job_id, fraction, message)``, ``("playable", job_id, [names])`` (the
html player of each seed is written: the page can play the dance while the other files are written),
``("done", job_id, result)`` and ``("failed", job_id, reason)``. It writes only inside the job's ``work/``
folder and renames ``work/`` to ``files/`` when every file is complete, so a failed or killed job leaves
no finished-looking files (the server removes ``work/``). The dances and files are those of ``dancekit
dance`` / ``dancekit compose`` for the same song and options: the same library calls
(:meth:`Pipeline.dances`, :func:`dancekit.export.export_motion`, :class:`ComposePipeline`).
"""

from __future__ import annotations

import os
import shutil
import traceback
import zipfile
from pathlib import Path
from typing import Any

from dancekit.errors import AudioError, DancekitError

#: Formats written into a folder (one JSON file per frame): served zipped.
FOLDER_FORMATS = ("openpose", "coco17", "coco18")


def song_seconds(path: Path) -> float:
    """The length of the song at ``path`` in seconds, from its header (libsndfile) or ffmpeg's probe."""
    from dancekit.audio.io import duration
    from dancekit.render import audio_duration

    seconds = duration(path)
    return float(seconds) if seconds is not None else float(audio_duration(path))


def stems_for(stem: str, seeds: list[int], several: bool) -> dict[int, str]:
    """The output stem of each seed as ``dancekit dance`` names them: ``stem`` for ``--seed``, ``stem_seedK``
    for ``--seeds``."""
    return {s: (f"{stem}_seed{s}" if several else stem) for s in seeds}


class _Worker:
    def __init__(self, index: int, events: Any, threads: int):
        self.index = index
        self.events = events
        self.threads = threads
        self.pipes: dict[str, Any] = {}

    def pipeline(self, model: str):
        if model not in self.pipes:
            from dancekit.pipelines import load_pipeline

            self.pipes[model] = load_pipeline(model)
        return self.pipes[model]

    def composer(self, model: str):
        key = f"compose:{model}"
        if key not in self.pipes:
            from dancekit.pipelines import ComposePipeline

            self.pipes[key] = ComposePipeline.from_pretrained(model)
        return self.pipes[key]

    def progress(self, job: dict, fraction: float, message: str) -> None:
        self.events.put(("progress", job["id"], float(fraction), message))

    def run(self, job: dict) -> dict:
        folder = Path(job["folder"])
        work = folder / "work"
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir()
        result = self.dance(job, work) if job["kind"] == "dance" else self.compose(job, work)
        for sub in [p for p in work.iterdir() if p.is_dir() and p.name.rsplit("_", 1)[-1] in FOLDER_FORMATS]:
            _zip_folder(sub, work / f"{sub.name}.zip")
            shutil.rmtree(sub)
        os.replace(work, folder / "files")
        return result

    def dance(self, job: dict, work: Path) -> dict:
        from dancekit.export import export_motion
        from dancekit.render import AudioClip, RenderOptions

        o = job["options"]
        song = Path(job["folder"]) / "input" / job["input"]
        seconds = song_seconds(song)
        if seconds > o["max_seconds"]:
            raise AudioError(f"{job['input_name']} is {seconds / 60:.1f} min long; this server takes at most "
                             f"{o['max_seconds'] / 60:g} min of audio")
        self.progress(job, 0.02, f"loading the model {o['model']}")
        pipe = self.pipeline(o["model"])
        self.progress(job, 0.05, f"dancing {len(o['seeds'])} seed(s) to {job['input_name']}")
        results = pipe.dances(str(song), seeds=o["seeds"], start=o["start"], end=o["end"], genre=o["genre"])
        clip = AudioClip(song, o["start"], o["end"])
        options = RenderOptions(figure=o["figure"])
        stems = stems_for(job["stem"], o["seeds"], o["several"])
        self.progress(job, 0.55, "writing the 3D player")
        for r in results:
            export_motion(r.motion, work, stem=stems[r.seed], formats=["html"], audio=clip, options=options)
        self.events.put(("playable", job["id"], [f"{stems[r.seed]}.html" for r in results]))
        rest = [f for f in o["formats"] if f != "html"]
        steps = max(1, len(results) * (len(rest) + (1 if "bvh" in rest else 0)))
        done = 0
        for r in results:
            for fmt in rest:
                self.progress(job, 0.6 + 0.4 * done / steps, f"writing {fmt} (seed {r.seed})")
                export_motion(r.motion, work, stem=stems[r.seed], formats=[fmt], audio=clip, options=options)
                done += 1
                if fmt == "bvh":  # both rigs: the humanoid one as NAME_humanoid.bvh
                    export_motion(r.motion, work, stem=f"{stems[r.seed]}_humanoid", formats=["bvh"],
                                  bvh_rig="humanoid")
                    done += 1
        return {"dances": [{"seed": r.seed, "stem": stems[r.seed], "summary": r.summary(), "genre": r.genre,
                            "genre_requested": r.genre_requested,
                            "genre_probs": {k: round(float(v), 4) for k, v in r.genre_probs.items()},
                            "seconds": round(r.motion.duration, 3), "frames": r.motion.num_frames,
                            "fps": r.motion.fps} for r in results]}

    def compose(self, job: dict, work: Path) -> dict:
        from dancekit.export import export_motion
        from dancekit.motion.formats import read_motion

        o = job["options"]
        motion = read_motion(Path(job["folder"]) / "input" / job["input"])
        self.progress(job, 0.05, f"loading the model {o['model']}")
        pipe = self.composer(o["model"])
        self.progress(job, 0.1, f"composing music for {job['input_name']}")
        result = pipe(motion, seed=o["seed"], tempo=o["tempo"])
        self.progress(job, 0.5, "writing MIDI and WAV")
        music = result.write(work, stem=job["stem"])
        self.events.put(("progress", job["id"], 0.6, "writing the mp4 and the 3D player"))
        export_motion(motion, work, stem=job["stem"], formats=("html",), audio=music["wav"])
        self.events.put(("playable", job["id"], [f"{job['stem']}.html"]))
        export_motion(motion, work, stem=job["stem"], formats=("mp4",), audio=music["wav"])
        arr = result.arrangement
        return {"summary": f"composed {arr.duration:.1f} s from {result.start_chord}: {len(arr.beat_times)} beats "
                           f"at {arr.tempo:.1f} BPM",
                "tempo": round(float(arr.tempo), 2), "chords": arr.chord_names()[:16]}


def _zip_folder(folder: Path, path: Path) -> None:
    """``folder``'s files (one level, sorted) as the zip ``path`` holding ``folder.name/FILE``."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for f in sorted(folder.iterdir()):
            z.write(f, f"{folder.name}/{f.name}")


def _warm_imports() -> None:
    """Import what every job uses (the writers, the renderers, the stages) before the first job, not in it."""
    import importlib

    for name in ("dancekit.export.writer", "dancekit.render.html", "dancekit.render.video", "dancekit.motion.formats.bvh",
                 "dancekit.motion.formats.gltf", "dancekit.motion.formats.aistpp", "dancekit.motion.formats.openpose",
                 "dancekit.pipelines.stages"):
        importlib.import_module(name)


def _warm_up(w: _Worker, model: str) -> None:
    """Dance 4 s of a synthesised tune with ``model`` and write its player, in a temporary folder, so that the
    first job does not pay the one-time costs (compiled feature code, first calls into torch and ffmpeg)."""
    import tempfile

    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy
    from dancekit.export import export_motion

    old = os.environ.get("DANCEKIT_CACHE")
    try:
        pipe = w.pipeline(model)
        with tempfile.TemporaryDirectory(prefix="dancekit-serve-warm-") as tmp:
            os.environ["DANCEKIT_CACHE"] = tmp  # features computed, not read from (or left in) the user's cache
            sr = 22050
            song = save_wav(Path(tmp) / "warm.wav", ode_to_joy(sr=sr)[: 4 * sr], sr=sr)
            result = pipe.dances(str(song), seeds=[0])[0]
            export_motion(result.motion, tmp, stem="warm", formats=["html"], audio=song)
    except DancekitError:
        pass  # a model that cannot dance: the job that asks for it gets the error
    finally:
        if old is None:
            os.environ.pop("DANCEKIT_CACHE", None)
        else:
            os.environ["DANCEKIT_CACHE"] = old


class _Conn:
    """The worker's end of its pipe as an event queue (``put`` sends)."""

    def __init__(self, conn):
        self.conn = conn

    def put(self, event: tuple) -> None:
        self.conn.send(event)


def worker_main(index: int, conn: Any, preload: list[str], threads: int) -> None:
    """The worker process: load ``preload`` models, post ``ready``, then run the jobs ``conn`` brings until
    ``None`` (or the pipe closes)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the server, which stops its workers
    os.setpgid(0, 0)  # a group of its own: cancelling a job stops the worker with its ffmpeg children
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))
    import torch

    torch.set_num_threads(threads)
    events = _Conn(conn)
    w = _Worker(index, events, threads)
    for name in preload:
        try:
            w.pipeline(name)
        except DancekitError:
            pass  # the job that asks for it gets the error
    _warm_imports()
    if preload:
        _warm_up(w, preload[0])
    events.put(("ready", index))
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        events.put(("started", job["id"], index))
        try:
            result = w.run(job)
        except DancekitError as exc:
            events.put(("failed", job["id"], str(exc).splitlines()[0] if str(exc) else type(exc).__name__))
        except Exception as exc:  # a bug: the job fails with its reason, the worker goes on
            if os.environ.get("DANCEKIT_DEBUG") == "1":
                traceback.print_exc()
            events.put(("failed", job["id"], f"internal error: {type(exc).__name__}: {exc}".splitlines()[0]))
        else:
            events.put(("done", job["id"], result))
