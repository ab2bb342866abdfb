"""The FastAPI app of ``dancekit serve``: three pages and a JSON API over :class:`~dancekit.serve.jobs.JobManager`.

Routes (every one behind the token when the server has one: ``Authorization: Bearer T`` or ``?token=T``):

- ``GET /``, ``/compose``, ``/models``: the dance, compose and models pages (static html + js); ``GET /live``: the
  live page (the browser's microphone danced as it plays) and its WebSocket ``/api/live``
  (:mod:`dancekit.serve.live`; the token as ``?token=T``);
- ``GET /api/options``: dance models with their genres, the output formats, the limits;
- ``GET /api/models``: every model's card (as ``dancekit models --json``);
- ``POST /api/jobs/dance`` (multipart: ``file`` or ``demo=true``, ``model``, ``genre``, ``seeds``,
  ``start``, ``end``, ``figure``, ``formats``) and ``POST /api/jobs/compose`` (``file``, ``model``,
  ``seed``, ``tempo``): 202 with the job's status; 429 with ``Retry-After`` when the queue is full;
- ``GET /api/jobs``, ``GET /api/jobs/{id}``: status (``state``, ``progress`` 0…1, ``message``,
  ``playable``, ``files``, ``result``, ``error``); ``GET /api/jobs/{id}/files`` and
  ``GET /api/jobs/{id}/files/{name}``; ``POST /api/jobs/{id}/cancel``; ``DELETE /api/jobs/{id}``;
- ``GET /openapi.json``, ``GET /docs``: the schema and its browser.

Every error is a 4xx whose JSON ``detail`` is one line. This module needs the ``serve`` extra (FastAPI,
uvicorn, python-multipart); ``dancekit.serve`` imports it only when the app is built.
"""

from __future__ import annotations

import contextlib
import hmac
import ipaddress
import shutil
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import FastAPI, HTTPException, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from dancekit.errors import ParameterError
from dancekit.live.config import LIVE_FAMILIES
from dancekit.serve.jobs import JobConflict, JobManager, QueueFull, ServeConfig, UnknownJob
from dancekit.serve.live import LiveRooms, live_socket
from dancekit.serve.uploads import AUDIO_KINDS, DANCE_KINDS, copy_capped, safe_stem, sniff

#: Outputs of a dance job on the web (``coco18`` and the rest of :data:`dancekit.export.FORMATS` by request).
WEB_FORMATS = ("html", "mp4", "glb", "bvh", "pkl", "npz", "openpose", "coco17")
_MULTIPART_SLACK = 64 * 1024  # the form fields and part headers around the file


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _options_table() -> dict[str, Any]:
    """The dance and compose models the server offers (no paths: only names it found)."""
    from dancekit.checkpoints import DEFAULT_MODEL, model_cards

    dance, compose = {}, []
    for name, card in model_cards().items():
        if card["kind"] != "dance":
            continue
        genres = ["auto", "none", *card["genre_models"]]
        dance[name] = {"genres": genres, "reads_genre_from_music": card["reads_genre_from_music"],
                       "description": card.get("description", ""),
                       "live": card["family"] in LIVE_FAMILIES}
        if card["family"] == "dual":
            compose.append(name)
    return {"dance_models": dance, "default_model": DEFAULT_MODEL if DEFAULT_MODEL in dance else next(iter(dance), None),
            "compose_models": compose, "formats": list(WEB_FORMATS)}


class _CapBody:
    """ASGI middleware: a job upload over ``limit`` bytes is refused (413) from its ``Content-Length``, or, sent
    without one, cut off once ``limit`` bytes have arrived (the form parser then fails and the route answers
    413), so no more than ``limit`` bytes of it are ever stored."""

    def __init__(self, app, *, limit: int, message: str):
        self.app, self.limit, self.message = app, limit, message

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "POST" or not scope["path"].startswith("/api/jobs/"):
            return await self.app(scope, receive, send)
        length = dict(scope["headers"]).get(b"content-length", b"")
        if length.isdigit() and int(length) > self.limit:
            return await JSONResponse({"detail": self.message}, status_code=413)(scope, receive, send)
        state = scope.setdefault("dancekit.body", {"too_large": False})
        seen = 0

        async def capped():
            nonlocal seen
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.limit:
                state["too_large"] = True
                return {"type": "http.disconnect"}
            return message

        return await self.app(scope, capped, send)


def create_app(config: ServeConfig, *, manager: JobManager | None = None):
    """The ASGI app; its lifespan starts and stops the job manager (and so the workers)."""
    manager = manager or JobManager(config)
    table = _options_table()

    @contextlib.asynccontextmanager
    async def lifespan(app):
        manager.start()
        try:
            yield
        finally:
            manager.stop()

    app = FastAPI(title="dancekit serve", version=_version(), lifespan=lifespan,
                  description="Upload a song, get its dance (mp4, html player, glb, bvh, SMPL pkl, npz, "
                              "keypoints); upload a dance, get its music.")
    app.state.manager = manager
    static = resources.files("dancekit.serve").joinpath("static")

    def fail(code: int, reason: str, headers: dict | None = None):
        raise HTTPException(status_code=code, detail=" ".join(str(reason).split()), headers=headers)

    @app.exception_handler(RequestValidationError)
    async def _validation(request, exc):
        first = exc.errors()[0] if exc.errors() else {}
        where = ".".join(str(x) for x in first.get("loc", ()) if x != "body")
        return JSONResponse({"detail": f"bad request: {where}: {first.get('msg', 'invalid')}"}, status_code=400)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request, exc):
        detail = exc.detail if isinstance(exc.detail, str) else str(exc.detail)
        return JSONResponse({"detail": detail.splitlines()[0] if detail else ""}, status_code=exc.status_code,
                            headers=getattr(exc, "headers", None))

    def refusal(connection) -> tuple[int, str] | None:
        """Why a request or WebSocket is refused: (HTTP status, reason) without the server's token, or from a
        Host other than the loopback on a server without one (a web page of another site: DNS rebinding)."""
        if config.token is not None:
            given = connection.headers.get("authorization", "").removeprefix("Bearer ").strip() \
                or connection.query_params.get("token", "")
            if not hmac.compare_digest(given.encode(), config.token.encode()):
                return 401, "this server needs its token (?token=... or Authorization: Bearer)"
        elif not _host_ok(connection.headers.get("host", "")):
            return 421, "unexpected Host header; open the server as 127.0.0.1 or localhost"
        return None

    @app.middleware("http")
    async def _guard(request: Request, call_next):
        refused = refusal(request)
        if refused is not None:
            return JSONResponse({"detail": refused[1]}, status_code=refused[0])
        return await call_next(request)

    app.add_middleware(_CapBody, limit=config.max_upload_bytes + _MULTIPART_SLACK,
                       message=f"the upload is larger than the limit of {config.max_upload_bytes / 1e6:g} MB")

    # ---- pages -------------------------------------------------------------------------------------------
    def page(name: str) -> HTMLResponse:
        return HTMLResponse(static.joinpath(name).read_text(encoding="utf-8"),
                            headers={"Cache-Control": "no-store"})

    @app.get("/", include_in_schema=False)
    def dance_page():
        return page("dance.html")

    @app.get("/compose", include_in_schema=False)
    def compose_page():
        return page("compose.html")

    @app.get("/models", include_in_schema=False)
    def models_page():
        return page("models.html")

    @app.get("/live", include_in_schema=False)
    def live_page():
        from dancekit.live.server import page_html

        html = page_html().decode("utf-8").replace("<body>", '<body data-source="mic">', 1)
        return HTMLResponse(html, headers={"Cache-Control": "no-store"})

    rooms = LiveRooms(config.max_live)

    @app.websocket("/api/live")
    async def live(ws: WebSocket):
        refused = refusal(ws)  # the checks of every HTTP route (the middleware does not see WebSockets)
        if refused is not None:
            await ws.close(code=1008, reason=refused[1])
            return
        await live_socket(ws, rooms=rooms, models=table["dance_models"], default=table["default_model"],
                          threads=config.threads)

    app.mount("/static", StaticFiles(directory=str(static)), name="static")

    # ---- API -----------------------------------------------------------------------------------------------
    @app.get("/api/options", summary="the dance and compose models, their genres, the formats and the limits")
    def options():
        return {**table, "max_upload_mb": config.max_upload_bytes / 1e6, "max_minutes": config.max_seconds / 60,
                "max_seeds": config.max_seeds, "workers": config.workers, "workers_ready": manager.ready_workers(),
                "max_queue": config.max_queue}

    @app.get("/api/models", summary="every model's card, as `dancekit models --json`")
    def models():
        from dancekit.checkpoints import model_cards

        return {name: {k: v for k, v in card.items() if k != "folder"} for name, card in model_cards().items()}

    async def read_form(request: Request):
        try:
            return await request.form(max_files=1, max_fields=16, max_part_size=64 * 1024)
        except Exception as exc:  # malformed multipart, or a body cut off by _CapBody
            if request.scope.get("dancekit.body", {}).get("too_large"):
                fail(413, f"the upload is larger than the limit of {config.max_upload_bytes / 1e6:g} MB")
            fail(400, f"bad multipart form: {exc}")

    def field(form, name: str, default: str | None = None) -> str | None:
        value = form.get(name)
        if value is None or (isinstance(value, str) and value.strip() == ""):
            return default
        if not isinstance(value, str):
            fail(400, f"form field {name!r} must be text, not a file")
        return value.strip()

    def number(form, name: str) -> float | None:
        text = field(form, name)
        if text is None:
            return None
        try:
            value = float(text)
        except ValueError:
            fail(400, f"{name} must be a number of seconds, got {text!r}")
        if not value >= 0 or value == float("inf"):
            fail(400, f"{name} must be a non-negative number of seconds, got {text!r}")
        return value

    def store_upload(form, stage: Path, kinds: dict[str, str], *, what: str, default_stem: str):
        upload = form.get("file")
        if upload is None or isinstance(upload, str):
            fail(400, f"no file: send the {what} as the multipart field 'file'")
        name = _display_name(upload.filename)
        upload.file.seek(0)
        head = upload.file.read(64)
        upload.file.seek(0)
        if not head:
            fail(400, f"{name or 'the upload'} is empty")
        kind = sniff(head)
        if kind not in kinds:
            seen = f"a {kind} file" if kind else "not a format dancekit reads"
            fail(415, f"{name or 'the upload'} is not {what} ({seen}); the page takes "
                      f"{', '.join(sorted(set(kinds) | ({'m4a'} if 'mp4' in kinds else set())))}")
        stored = f"upload{kinds[kind]}"
        try:
            with open(stage / "input" / stored, "wb") as out:
                copy_capped(upload.file, out, limit=config.max_upload_bytes, what=name or "the upload")
        except ParameterError as exc:
            fail(413, str(exc))
        return stored, name, safe_stem(name, default_stem)

    def create(kind: str, build):
        try:
            manager.reserve()
        except QueueFull as exc:
            fail(429, str(exc), headers={"Retry-After": "10"})
        stage = None
        try:
            job_id, stage = manager.new_folder()
            stored, name, stem, options = build(stage)
            status = manager.submit(job_id, stage, kind=kind, input_file=stored, input_name=name or stored,
                                    stem=stem, options=options)
        except BaseException:
            manager.release()
            if stage is not None:
                shutil.rmtree(stage, ignore_errors=True)
            raise
        return JSONResponse(status, status_code=202)

    @app.post("/api/jobs/dance", status_code=202,
              summary="a dance for a song: multipart file (or demo=true), model, genre, seeds, start, end, "
                      "figure, formats")
    async def create_dance(request: Request):
        return await submit(request, "dance", _dance_job)

    async def submit(request: Request, kind: str, job) -> JSONResponse:
        """A job of ``kind`` from the multipart form: 429 when the queue is full (before the upload is read), then
        ``job(form, stage)`` checks the options and stores the upload in the job's staging folder."""
        manager_full = _full(manager)
        if manager_full:
            fail(429, manager_full, headers={"Retry-After": "10"})
        form = await read_form(request)
        try:
            return await _in_thread(create, kind, lambda stage: job(form, stage))
        finally:
            await form.close()

    def _dance_job(form, stage: Path):
        model = field(form, "model", table["default_model"])
        if model not in table["dance_models"]:
            fail(400, f"unknown model {model!r}; this server has {', '.join(table['dance_models'])}")
        genre = field(form, "genre", "auto")
        if genre not in table["dance_models"][model]["genres"]:
            fail(400, f"model {model!r} has no genre {genre!r}; choose from "
                      f"{', '.join(table['dance_models'][model]['genres'])}")
        seeds_text = field(form, "seeds", "0")
        from dancekit.pipelines.base import parse_seeds

        try:
            seeds = parse_seeds(seeds_text)
        except ParameterError as exc:
            fail(400, str(exc))
        if len(seeds) > config.max_seeds:
            fail(400, f"{len(seeds)} seeds; this server dances at most {config.max_seeds} in one job")
        start, end = number(form, "start"), number(form, "end")
        if start is not None and end is not None and end <= start:
            fail(400, f"end ({end:g} s) must be after start ({start:g} s)")
        figure = field(form, "figure", "stick")
        if figure not in ("stick", "body"):
            fail(400, f"figure must be stick or body, got {figure!r}")
        from dancekit.export import check_formats

        try:
            formats = check_formats(field(form, "formats", ",".join(WEB_FORMATS)))
        except ParameterError as exc:
            fail(400, str(exc))
        if "html" not in formats:
            formats = ["html", *formats]  # the page plays the html player
        if field(form, "demo", "false").lower() in ("1", "true", "yes", "on"):
            from dancekit.audio import save_wav
            from dancekit.audio.synth import ode_to_joy

            sr = 22050
            save_wav(stage / "input" / "upload.wav", ode_to_joy(sr=sr, bpm=120, repeats=1), sr=sr)
            stored, name, stem = "upload.wav", "ode_to_joy.wav", "ode_to_joy"
        else:
            stored, name, stem = store_upload(form, stage, AUDIO_KINDS, what="audio", default_stem="song")
        options = {"model": model, "genre": genre, "seeds": seeds, "several": len(seeds) > 1 or "," in seeds_text
                   or "-" in seeds_text, "start": start, "end": end, "figure": figure, "formats": formats,
                   "max_seconds": config.max_seconds}
        return stored, name, stem, options

    @app.post("/api/jobs/compose", status_code=202,
              summary="music for a dance: multipart file (npz, bvh, glb, AIST++ pkl), model, seed, tempo")
    async def create_compose(request: Request):
        return await submit(request, "compose", _compose_job)

    def _compose_job(form, stage: Path):
        model = field(form, "model", table["compose_models"][0] if table["compose_models"] else "dual")
        if model not in table["compose_models"]:
            fail(400, f"unknown compose model {model!r}; this server has {', '.join(table['compose_models'])}")
        seed_text = field(form, "seed", "0")
        try:
            seed = int(seed_text)
        except ValueError:
            fail(400, f"seed must be an integer, got {seed_text!r}")
        tempo: str | float | None = field(form, "tempo", None)
        if tempo not in (None, "dance", "auto", "periodic"):
            try:
                tempo = float(tempo)
            except ValueError:
                fail(400, f"tempo must be dance, auto, periodic or a number of BPM, got {tempo!r}")
            if not 20 <= tempo <= 400:
                fail(400, f"tempo must be between 20 and 400 BPM, got {tempo:g}")
        stored, name, stem = store_upload(form, stage, DANCE_KINDS, what="a dance", default_stem="dance")
        return stored, name, stem, {"model": model, "seed": seed, "tempo": tempo}

    @app.get("/api/jobs", summary="every job, newest first")
    def jobs():
        return manager.list()

    def lookup(call, *args):
        try:
            return call(*args)
        except UnknownJob as exc:
            fail(404, str(exc))
        except JobConflict as exc:
            fail(409, str(exc))

    @app.get("/api/jobs/{job_id}", summary="a job's status and progress")
    def job(job_id: str):
        return lookup(manager.status, job_id)

    @app.get("/api/jobs/{job_id}/files", summary="a job's files (done), or its players so far (running)")
    def job_files(job_id: str):
        status = lookup(manager.status, job_id)
        if status["state"] == "done":
            return status["files"]
        if status["state"] in ("failed", "cancelled"):
            fail(409, f"job {job_id} {status['state']}: it has no files")
        return [{"name": n} for n in status["playable"]]

    @app.get("/api/jobs/{job_id}/files/{name}", summary="one file of a job")
    def job_file(job_id: str, name: str):
        path = lookup(manager.file_path, job_id, name)
        media = {".html": "text/html", ".mp4": "video/mp4", ".glb": "model/gltf-binary", ".zip": "application/zip",
                 ".mid": "audio/midi", ".wav": "audio/wav", ".bvh": "text/plain"}.get(path.suffix,
                                                                                      "application/octet-stream")
        inline = path.suffix in (".html", ".mp4", ".wav")
        return FileResponse(path, media_type=media, filename=name,
                            content_disposition_type="inline" if inline else "attachment")

    @app.post("/api/jobs/{job_id}/cancel", summary="cancel a queued or running job (its files are removed)")
    def cancel(job_id: str):
        return lookup(manager.cancel, job_id)

    @app.delete("/api/jobs/{job_id}", summary="remove a job and its files (cancelling it first)")
    def delete(job_id: str):
        lookup(manager.status, job_id)
        manager.delete(job_id)
        return {"deleted": job_id}

    return app


def _display_name(name: str | None) -> str:
    """The client's file name for messages only: its last component, printable, at most 100 characters."""
    import re

    last = re.split(r"[/\\]", str(name or ""))[-1]
    return "".join(c for c in last if c.isprintable())[:100]


def _full(manager: JobManager) -> str | None:
    """Why a new job cannot wait now (the queue is full), before its upload is read."""
    with manager.lock:
        if len(manager.pending) + manager.reserved >= manager.config.max_queue:
            return f"the queue is full ({manager.config.max_queue} jobs waiting); try again later"
    return None


async def _in_thread(fn, *args):
    from starlette.concurrency import run_in_threadpool

    return await run_in_threadpool(fn, *args)


def _host_ok(host: str) -> bool:
    name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
    return name in ("localhost", "[::1]") or name.startswith("127.")


def _version() -> str:
    from dancekit import __version__

    return __version__


def serve(config: ServeConfig, *, port: int = 8000, log_level: str = "warning") -> None:
    """Run the app with uvicorn on ``config.host:port`` until Ctrl-C or SIGTERM (blocks).

    Raises
    ------
    ParameterError
        For a host other than the loopback without a token.
    """
    import uvicorn

    if not is_loopback(config.host) and not config.token:
        raise ParameterError(f"--host {config.host} opens the server to other machines: give it a --token")
    app = create_app(config)
    uvicorn.run(app, host=config.host, port=port, log_level=log_level, access_log=False,
                timeout_graceful_shutdown=5)
