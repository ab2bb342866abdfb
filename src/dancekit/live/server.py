"""The live page and its WebSocket pose stream (:class:`PoseServer`), self-contained (``websockets``).

``GET /`` is the live page (a canvas figure fed by the stream); ``/poses`` is the pose stream: on connecting a
client receives one ``hello`` message, then one ``pose`` message per frame as the frames are made, and ``end``
when the session stops. The messages are JSON text (docs/LIVE.md)::

    {"type": "hello", "model": "revolution", "fps": 25.0, "units": "cm", "up_axis": 1, "root": 2,
     "joint_names": [...], "parents": [...], "height": 170.0}
    {"type": "pose", "frame": 412, "t": 16.48, "sent": 1764283012.31, "latency": 0.21, "beat": false,
     "bpm": 128.9, "music": true, "joints": [[x, y, z], ...]}
    {"type": "end"}

``t`` is the frame's time in the audio (s from the stream's start), ``sent`` the wall clock (Unix s) when it
was sent, ``latency`` the time from its audio block's arrival to sending. Loopback by default.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time
from importlib import resources

from dancekit.errors import ParameterError

__all__ = ["PoseServer", "hello_message", "page_html"]


def page_html() -> bytes:
    """The live page (UTF-8 HTML)."""
    return resources.files("dancekit.live").joinpath("assets/live.html").read_bytes()


def hello_message(skeleton, *, fps: float, model: str) -> dict:
    """The stream's first message: the skeleton (joint names, parents, root, up axis, units), fps, model."""
    import numpy as np

    offsets = np.asarray(skeleton.offsets, np.float64)
    rest = np.zeros_like(offsets)
    for j in skeleton.topological_order:  # the rest pose: offsets summed along the chain
        p = skeleton.parents[j]
        rest[j] = offsets[j] + (rest[p] if p >= 0 else 0.0)
    span = float(np.ptp(rest[:, skeleton.up_index])) if len(rest) else 0.0
    height = span if span > 0 else 170.0
    return {"type": "hello", "model": str(model), "fps": float(fps), "units": str(getattr(skeleton, "units", "cm")),
            "up_axis": int(skeleton.up_index), "root": int(skeleton.root), "joint_names": list(skeleton.joint_names),
            "parents": [int(p) for p in skeleton.parents], "height": height}


class PoseServer:
    """Serve the live page and broadcast pose frames to every connected client (a thread of its own).

    Parameters
    ----------
    hello : the stream's first message (:func:`hello_message`)
    host, port : where to listen (port 0: a free port, see :attr:`port` after :meth:`start`)
    """

    def __init__(self, hello: dict, *, host: str = "127.0.0.1", port: int = 8765):
        if not 0 <= int(port) < 65536:
            raise ParameterError(f"port must be in 0..65535, got {port!r}")
        self.hello = json.dumps(hello)
        self.host, self.port = host, int(port)
        self.clients: set = set()
        self.loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None
        self.sent = 0

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def start(self) -> PoseServer:
        """Start listening (returns once the socket is bound)."""
        self._thread = threading.Thread(target=self._run, name="dancekit-live-server", daemon=True)
        self._thread.start()
        self._ready.wait(10)
        if self._error is not None:
            raise ParameterError(f"cannot serve the live page on {self.host}:{self.port}: {self._error}")
        return self

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # reported by start()
            self._error = exc
            self._ready.set()

    async def _main(self) -> None:
        from websockets.asyncio.server import serve
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        page = page_html()

        def process_request(connection, request):
            path = request.path.split("?", 1)[0]
            if path == "/poses":
                return None  # the WebSocket handshake
            if path in ("/", "/index.html"):
                return Response(200, "OK", Headers([("Content-Type", "text/html; charset=utf-8"),
                                                    ("Content-Length", str(len(page))),
                                                    ("Cache-Control", "no-store")]), page)
            return connection.respond(404, "not found\n")

        async def handler(ws):
            await ws.send(self.hello)
            self.clients.add(ws)
            try:
                await ws.wait_closed()
            finally:
                self.clients.discard(ws)

        self.loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(handler, self.host, self.port, process_request=process_request,
                         max_queue=4, ping_interval=None) as server:
            self.port = server.sockets[0].getsockname()[1] if self.port == 0 else self.port
            self._ready.set()
            await self._stop.wait()
            from websockets.asyncio.server import broadcast

            broadcast(self.clients, json.dumps({"type": "end"}))
            await asyncio.sleep(0.05)

    def send(self, frames) -> None:
        """Broadcast frames (:class:`~dancekit.live.session.Frame`) to the clients (from any thread)."""
        if self.loop is None or not frames:
            return
        offset = time.time() - time.monotonic()
        messages = [json.dumps(f.to_message(wall_offset=offset)) for f in frames]
        self.loop.call_soon_threadsafe(self._broadcast, messages)

    def _broadcast(self, messages) -> None:
        from websockets.asyncio.server import broadcast

        for m in messages:
            broadcast(self.clients, m)
        self.sent += len(messages)

    def stop(self) -> None:
        """Send ``end`` to the clients and stop listening."""
        if self.loop is not None and self._stop is not None:
            self.loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(5)
