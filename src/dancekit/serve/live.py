"""The browser's microphone danced live by ``dancekit serve``: the ``/live`` page and its WebSocket ``/api/live``.

The page captures the microphone (``getUserMedia``, an AudioWorklet) and sends it to the server; the server feeds
it to a :class:`~dancekit.live.LiveSession` as it comes and sends the poses back on the same socket, in the pose
stream's messages (docs/LIVE.md). The protocol:

- client → server: first one JSON text message ``{"type": "start", "sample_rate": 48000, "model": "revolution",
  "seed": 0}`` (``model`` and ``seed`` optional: the server's default model, seed 0); then binary messages, each
  mono little-endian float32 PCM at ``sample_rate`` (at most :data:`MAX_BLOCK_S` seconds each); ``{"type":
  "stop"}`` ends the session;
- server → client: ``hello`` (the skeleton, once the model is loaded), then one ``pose`` message per frame, and
  ``end`` when the session stops; a bad request or a busy server is one ``{"type": "error", "detail": "..."}``
  message (one line), then the socket is closed (code 1008, or 1013 when the server is busy: try again later).

The audio is resampled on the server to the model's feature rate (soxr, streamed:
:class:`~dancekit.live.session.StreamResampler`) and fed in blocks of the
session's ``LiveConfig.block_s`` whatever the length of the client's messages (a live dance depends on the block
length: the same audio sent in other pieces dances the same). When the client stops, the resampler's last
milliseconds and the frames still waiting for their lookahead are danced and sent before ``end``. At most
``ServeConfig.max_live`` sessions run at once; each runs on the server's own process, one thread for its model.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time

import numpy as np

__all__ = ["MAX_BLOCK_S", "LiveRooms", "Rebuffer", "live_socket", "start_message"]

#: the longest audio message accepted (s)
MAX_BLOCK_S = 2.0
#: how long the server waits for the start message (s)
START_TIMEOUT_S = 30.0
#: the sample rates a client may send (Hz)
RATES = (8000, 192000)


class LiveRooms:
    """How many live sessions run, at most ``limit`` (thread-safe)."""

    def __init__(self, limit: int):
        self.limit, self.running = int(limit), 0
        self.lock = threading.Lock()

    def enter(self) -> bool:
        with self.lock:
            if self.running >= self.limit:
                return False
            self.running += 1
            return True

    def leave(self) -> None:
        with self.lock:
            self.running -= 1


def start_message(text: str, *, models: dict, default: str | None) -> tuple[str, int, int]:
    """The client's first message → (model, sample rate, seed); :class:`~dancekit.errors.ParameterError` (one line)
    for anything else. ``models``: the server's dance models (name → its options entry, ``live`` True where the model
    can dance live)."""
    from dancekit.errors import ParameterError

    try:
        m = json.loads(text)
    except (TypeError, ValueError):
        raise ParameterError("the first message must be JSON: {\"type\": \"start\", \"sample_rate\": …}") from None
    if not isinstance(m, dict) or m.get("type") != "start":
        raise ParameterError("the first message must be {\"type\": \"start\", \"sample_rate\": …}")
    rate = m.get("sample_rate")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not RATES[0] <= rate <= RATES[1] \
            or rate != int(rate):
        raise ParameterError(f"sample_rate must be a whole number of Hz in [{RATES[0]}, {RATES[1]}], got {rate!r}")
    model = m.get("model") or default
    if model not in models:
        raise ParameterError(f"unknown model {model!r}; this server has {', '.join(models) or 'none'}")
    if not models[model].get("live"):
        from dancekit.live.config import LIVE_FAMILIES

        raise ParameterError(f"the model {model!r} cannot dance live (live: {' and '.join(LIVE_FAMILIES)} models)")
    seed = m.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
        raise ParameterError(f"seed must be an integer in [0, 2^31), got {seed!r}")
    return str(model), int(rate), int(seed)


class Rebuffer:
    """Audio in pieces of any length → :class:`~dancekit.live.session.Block` of ``size`` samples each (the session's
    block), each arriving when the piece that completed it did."""

    def __init__(self, size: int):
        self.size = int(size)
        self.held = np.zeros(0, np.float32)

    def push(self, y: np.ndarray, arrival: float) -> list:
        from dancekit.live.session import Block

        y = np.concatenate([self.held, np.asarray(y, np.float32)])
        cut = len(y) - len(y) % self.size
        self.held = y[cut:]
        return [Block(y[a : a + self.size], arrival) for a in range(0, cut, self.size)]

    def rest(self, arrival: float):
        """What is held, as a last shorter block (None: nothing)."""
        from dancekit.live.session import Block

        if not len(self.held):
            return None
        block, self.held = Block(self.held, arrival), np.zeros(0, np.float32)
        return block


async def live_socket(ws, *, rooms: LiveRooms, models: dict, default: str | None, threads: int = 1) -> None:
    """Serve one client of ``/api/live`` (a Starlette ``WebSocket``, accepted here) until it stops or leaves."""
    from starlette.websockets import WebSocketDisconnect

    from dancekit.errors import DancekitError

    await ws.accept()

    async def refuse(detail: str, code: int = 1008) -> None:
        await ws.send_text(json.dumps({"type": "error", "detail": " ".join(str(detail).split())}))
        await ws.close(code=code)

    try:
        first = await asyncio.wait_for(ws.receive(), timeout=START_TIMEOUT_S)
    except TimeoutError:
        await refuse(f"no start message in {START_TIMEOUT_S:g} s")
        return
    except (WebSocketDisconnect, RuntimeError):
        return
    if first["type"] == "websocket.disconnect":
        return
    try:
        model, rate, seed = start_message(first.get("text"), models=models, default=default)
    except DancekitError as exc:
        await refuse(str(exc))
        return
    if not rooms.enter():
        await refuse(f"{rooms.limit} live session(s) already running on this server; try again later", code=1013)
        return
    try:
        await _run(ws, model=model, rate=rate, seed=seed, threads=threads, refuse=refuse)
    finally:
        rooms.leave()


def _open(model: str, seed: int, threads: int):
    import torch
    from threadpoolctl import threadpool_limits

    from dancekit.live import LiveConfig
    from dancekit.live.session import LiveSession

    torch.set_num_threads(max(1, int(threads)))
    threadpool_limits(1)  # the features' BLAS on one thread (process-wide: the server's own process)
    return LiveSession(model, config=LiveConfig(seed=seed))


async def _run(ws, *, model: str, rate: int, seed: int, threads: int, refuse) -> None:
    from starlette.concurrency import run_in_threadpool
    from starlette.websockets import WebSocketDisconnect

    from dancekit.errors import DancekitError
    from dancekit.live.server import hello_message
    from dancekit.live.session import StreamResampler, take_waiting

    try:
        session = await run_in_threadpool(_open, model, seed, threads)
    except DancekitError as exc:
        await refuse(str(exc))
        return
    resample = StreamResampler(rate, session.sr)
    await ws.send_text(json.dumps(hello_message(session.skeleton, fps=session.fps, model=model)))
    blocks: asyncio.Queue = asyncio.Queue()
    offset = time.time() - time.monotonic()
    most = int(MAX_BLOCK_S * rate) * 4
    rebuffer = Rebuffer(max(1, int(round(session.config.block_s * session.sr))))
    refused = asyncio.Event()  # a bad audio message: the socket is closed, nothing more is danced

    async def receive() -> None:
        try:
            while True:
                msg = await ws.receive()
                if msg["type"] == "websocket.disconnect":
                    break
                data = msg.get("bytes")
                if data is None:  # text: only {"type": "stop"} means something now
                    try:
                        stop = json.loads(msg.get("text") or "").get("type") == "stop"
                    except (ValueError, AttributeError):
                        stop = False
                    if stop:
                        break
                    continue
                arrival = time.monotonic()
                if len(data) % 4 or len(data) > most:
                    refused.set()
                    await refuse(f"an audio message must be whole float32 samples, at most {MAX_BLOCK_S:g} s; "
                                 f"got {len(data)} bytes")
                    break
                # non-finite samples zeroed before the resampler, whose filter would spread each over ~70 ms
                x = np.nan_to_num(np.frombuffer(data, "<f4").astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)
                for block in rebuffer.push(resample(x), arrival):
                    await blocks.put(block)
        except WebSocketDisconnect:
            pass
        finally:  # what soxr still holds, then the last shorter block (none after a refusal)
            if not refused.is_set():
                for block in rebuffer.push(resample.flush(), time.monotonic()):
                    await blocks.put(block)
                rest = rebuffer.rest(time.monotonic())
                if rest is not None:
                    await blocks.put(rest)
            await blocks.put(None)

    reader = asyncio.create_task(receive())
    try:
        ended = False
        while not ended:
            item = await blocks.get()
            if item is None or refused.is_set():
                break
            waiting, ended = take_waiting(item, blocks.get_nowait, asyncio.QueueEmpty)
            for f in await run_in_threadpool(session.feed, waiting):
                await ws.send_text(json.dumps(f.to_message(wall_offset=offset)))
        if refused.is_set():
            return
        for f in await run_in_threadpool(session.finish):  # the frames still waiting for their lookahead
            await ws.send_text(json.dumps(f.to_message(wall_offset=offset)))
        await ws.send_text(json.dumps({"type": "end"}))
        await ws.close()
    except (WebSocketDisconnect, RuntimeError):  # the client left
        pass
    finally:
        reader.cancel()
