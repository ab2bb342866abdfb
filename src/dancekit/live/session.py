"""A live session (:class:`LiveSession`): audio blocks in, pose frames out, the latency of each frame logged.

Sources (:func:`file_source`, :func:`pcm_source`, :func:`microphone_source`) deliver mono float32 blocks at the
model's feature rate (``fps · hop_length``) with the time each block *arrived* (``time.monotonic()``: for a
file fed in real time, the moment its last sample would have played). :meth:`LiveSession.run` feeds them
through the online features, the model's stepper and the online stages, and calls each sink with the frames
made.

Latency of a frame: from the arrival of the block that holds the frame's centre (sample ``f · hop_length``)
to the moment the frame is handed to the sinks. It is the sum of the **lookahead** (waiting for the block that
brings the frame's lookahead: ``lookahead_s`` rounded up to whole blocks) and the **compute** time (from that
block's arrival to the frame's sending, queueing included).

Falling behind (a block handled more than ``max_lag_s`` after its arrival) switches to the lighter path (the
chromagram held, not recomputed: it is most of the features' cost) until the session is back within half of
it; every block waiting is fed at once (one analysis for all: the fixed cost per block is paid once), so the
session never lags further and further. Both are counted and said (:attr:`LiveSession.notes`).
A block that is missing (``None``: a dropped audio block) is fed as silence and marked: the dancer calms.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from dancekit.errors import AudioError, ParameterError
from dancekit.features.online import OnlineFeatures
from dancekit.live.config import BEAT_NUDGE, LiveConfig
from dancekit.live.genre import OnlineGenreReader
from dancekit.live.stages import BeatNudge, OnlineStages
from dancekit.live.steppers import make_stepper
from dancekit.pipelines.stages import genre_jitter_cap

__all__ = ["Block", "Frame", "LiveSession", "StreamResampler", "file_source", "microphone_source", "pcm_source",
           "take_waiting"]


@dataclass
class Block:
    """Mono float32 samples at the session's rate (None: a dropped block of ``n`` samples) and when it arrived
    (``time.monotonic()``, s)."""

    samples: np.ndarray | None
    arrival: float
    n: int = 0

    def __post_init__(self):
        if self.samples is not None:
            self.n = len(self.samples)


@dataclass
class Frame:
    """One pose frame: ``index`` (frames since the start), ``time`` (s of audio), ``joints`` (J, 3) float32 in
    the skeleton's units, ``arrival`` (when its block arrived) and ``sent`` (when it was handed to the sinks,
    ``time.monotonic()``), ``ready`` (when the block that completed it arrived), ``beat`` (a beat falls on it),
    ``bpm`` (the tracker's tempo, or None), ``music`` (music was playing: sound above the silence level with a
    pulse, or in the beat tracker's first seconds, before it can tell; False: the dancer calms)."""

    index: int
    time: float
    joints: np.ndarray
    arrival: float
    ready: float
    sent: float = 0.0
    beat: bool = False
    bpm: float | None = None
    music: bool = True

    @property
    def latency(self) -> float:
        return self.sent - self.arrival

    def to_message(self, *, wall_offset: float = 0.0) -> dict:
        """The pose stream's JSON message (docs/LIVE.md): times in s, joints rounded to 0.1 unit."""
        return {"type": "pose", "frame": self.index, "t": round(self.time, 4),
                "sent": round(self.sent + wall_offset, 4), "latency": round(self.latency, 4),
                "beat": self.beat, "bpm": None if self.bpm is None else round(self.bpm, 1), "music": self.music,
                "joints": np.round(self.joints.astype(np.float64), 1).tolist()}


@dataclass
class SessionStats:
    """What a session measured: per frame the latency and its lookahead part (s); per block the compute time
    (wall s, waiting for the CPU included; and the CPU time of the session's thread, s) and its audio length
    (s); how often it took the lighter path or fed waiting blocks at once."""

    latency: list[float] = field(default_factory=list)
    lookahead: list[float] = field(default_factory=list)
    compute: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    block_audio: list[float] = field(default_factory=list)
    light_blocks: int = 0
    light_switches: int = 0
    merged_blocks: int = 0
    dropped_blocks: int = 0

    def summary(self) -> dict:
        lat = np.asarray(self.latency)
        comp, audio = float(np.sum(self.compute)), float(np.sum(self.block_audio))
        return {"frames": int(len(lat)),
                "latency_median_s": float(np.median(lat)) if len(lat) else None,
                "latency_p99_s": float(np.quantile(lat, 0.99)) if len(lat) else None,
                "lookahead_median_s": float(np.median(self.lookahead)) if self.lookahead else None,
                "compute_median_s": float(np.median(np.asarray(self.latency) - np.asarray(self.lookahead)))
                if self.lookahead else None,
                "compute_per_audio_s": comp / audio if audio else None,
                "cpu_per_audio_s": float(np.sum(self.cpu)) / audio if audio and self.cpu else None,
                "light_blocks": self.light_blocks, "light_switches": self.light_switches, "merged_blocks": self.merged_blocks,
                "dropped_blocks": self.dropped_blocks}


class LiveSession:
    """One live dance: a model, its online features and stages, the sinks its frames go to.

    Parameters
    ----------
    model : a model name or checkpoint folder (Dance Revolution or Music2Dance)
    config : the online settings (:class:`LiveConfig`)
    genre : Music2Dance's dance type (None: none)
    sinks : callables ``sink(frames: list[Frame])``
    keep_stats : keep every frame's latency (:attr:`stats`)
    """

    def __init__(self, model: str | os.PathLike = "revolution", *, config: LiveConfig | None = None,
                 genre: str | None = None, sinks: list[Callable[[list[Frame]], None]] | None = None,
                 keep_stats: bool = True, pipe=None):
        from dancekit.pipelines import load_pipeline

        self.config = config or LiveConfig()
        c = self.config
        self.pipe = pipe if pipe is not None else load_pipeline(model)
        self.fps = float(self.pipe.fps)
        self.hop = int(self.pipe.hop_length)
        self.features = OnlineFeatures(preset=self.pipe.preset, fps=self.fps, hop_length=self.hop,
                                       lookahead_s=c.lookahead_s, context_s=c.context_s,
                                       beat_window_s=c.beat_window_s, tempogram_future=c.tempogram_future)
        self.sr = self.features.sr
        la_frames = int(np.ceil(c.model_lookahead_s * self.fps - 1e-9))
        #: the model stepped: the checkpoint's live component where it has one (trained on the online features)
        self.live_pipe = self.pipe.live_pipeline() if hasattr(self.pipe, "live_pipeline") else self.pipe
        encoder = getattr(self.live_pipe.model, "encoder", None)
        exact = getattr(encoder, "bounded_lookahead", None)
        if exact is not None:  # an encoder that looks no further: waiting longer changes nothing
            la_frames = min(la_frames, exact)
        self.stepper = make_stepper(self.live_pipe, lookahead=la_frames, context=int(round(c.encoder_context_s * self.fps)),
                                    seed=c.seed, genre=genre, smoothing=c.sample_smoothing,
                                    hold_back=None if c.smoothing_hold_s is None
                                    else int(round(c.smoothing_hold_s * self.fps)))
        if hasattr(self.stepper, "raw"):
            self.stepper.raw = True  # the online stages set the bone lengths
        self.skeleton = self.pipe.skeleton
        self.genre_reader, self._cap, self._genre = None, None, genre
        cap = _live_jitter_cap(self.pipe, c, genre)
        if cap is not None:
            self._cap, self.genre_reader = cap
        self.stages = OnlineStages(self.skeleton, fps=self.fps, config=c, cap=self._cap is not None)
        if self._cap is not None and self.genre_reader is None:  # a genre asked for by name: its own cap now
            self.stages.max_jitter = genre_jitter_cap(*self._cap, probs={}, genre=genre)
        self.notes: list[str] = []
        if c.jitter_cap and self._cap is None:
            self.notes.append("no jitter cap: the model has none, or no genre reader of its live features")
        #: the beat nudge's rate bound: the config's, or the offline warp's of the model
        self.rate_bound = c.rate_bound if c.rate_bound is not None else offline_rate_bound(self.pipe)
        #: the beat nudge's way: the config's, or the model family's (``BEAT_NUDGE``)
        self.beat_nudge = c.beat_nudge or BEAT_NUDGE.get(getattr(self.pipe, "family", None), "target")
        self.nudge = BeatNudge(fps=self.fps, rate_bound=self.rate_bound, mode=self.beat_nudge,
                               root=self.pipe.skeleton.root, unit_scale=float(self.pipe.skeleton.unit_scale)) \
            if self.rate_bound > 0 else None
        self.sinks = list(sinks or [])
        self.stats = SessionStats()
        self.keep_stats = keep_stats
        self.model_name = str(model)
        # per block: (first sample, arrival), to find the block that holds a frame's centre
        self._blocks: list[tuple[int, float, bool]] = []
        self._samples = 0
        self._frames = 0
        self._light = False
        self._silent_db = c.silence_db

    # ------------------------------------------------------------------ one step
    def feed(self, blocks: list[Block], *, now: Callable[[], float] = time.monotonic) -> list[Frame]:
        """Feed waiting blocks (one analysis for all of them); returns the frames made."""
        c = self.config
        lag = now() - blocks[0].arrival
        if lag > c.max_lag_s and not self._light:
            self._light = True
            self.stats.light_switches += 1
            if self.stats.light_switches <= 3:  # the first few said; all counted
                self.notes.append(f"fell {lag:.2f} s behind at {self._samples / self.sr:.1f} s: chromagram held")
        elif self._light and lag < 0.5 * c.max_lag_s:
            self._light = False
        self.features.hold_chroma = self._light
        if self._light:
            self.stats.light_blocks += len(blocks)
        if len(blocks) > 1:
            self.stats.merged_blocks += len(blocks) - 1
        parts = []
        for b in blocks:
            music = b.samples is not None
            y = b.samples if music else np.zeros(b.n, np.float32)
            if music:
                rms = float(np.sqrt(np.mean(np.square(y, dtype=np.float64)))) if len(y) else 0.0
                music = 20 * np.log10(max(rms, 1e-12)) > self._silent_db
            else:
                self.stats.dropped_blocks += 1
            self._blocks.append((self._samples, b.arrival, music))
            self._samples += len(y)
            parts.append(y)
        rows = self.features.feed(np.concatenate(parts) if len(parts) > 1 else parts[0])
        self._read_genre(rows)
        return self._emit(rows, ready=blocks[-1].arrival, now=now)

    def _read_genre(self, rows: np.ndarray) -> None:
        """The genre reader fed the new rows; a new reading sets the stages' jitter cap."""
        if self.genre_reader is not None and self.genre_reader.push(rows):
            self.stages.max_jitter = genre_jitter_cap(*self._cap, probs=self.genre_reader.probs, genre=self._genre)

    def finish(self, *, now: Callable[[], float] = time.monotonic) -> list[Frame]:
        """The frames still waiting for their lookahead (the stream ended); none when no audio came at all."""
        if not self._samples:
            return []
        rows = self.features.finish()
        self._read_genre(rows)
        return self._emit(rows, ready=now(), now=now, final=True)

    def _emit(self, rows: np.ndarray, *, ready: float, now, final: bool = False) -> list[Frame]:
        poses = self.stepper.push(rows) if not final else np.concatenate([self.stepper.push(rows),
                                                                          self.stepper.finish()])
        k = len(poses)
        idx = np.arange(self._frames, self._frames + k)
        centre = idx * self.hop
        starts = np.array([b[0] for b in self._blocks])
        which = np.clip(np.searchsorted(starts, centre, side="right") - 1, 0, max(0, len(starts) - 1))
        clear = self.features.tracker.pulse  # a pulse, or not known yet (the tracker's warm-up)
        music = np.array([self._blocks[w][2] for w in which], bool) if k else np.zeros(0, bool)
        music &= clear  # sound above the silence level with a pulse: dance; else calm
        if self.nudge is not None and k:
            tracker = self.features.tracker
            period = None if tracker.bpm is None else 60.0 / tracker.bpm
            poses = self.nudge.process(poses, tracker.next_time if clear else None, period)
        poses = self.stages.process(poses, music)
        bpm = self.features.tracker.bpm
        beats = {int(round(b.time * self.fps)) for b in self.features.tracker.beats[-8:]}
        frames = [Frame(index=int(i), time=float(i / self.fps), joints=poses[j], arrival=self._blocks[which[j]][1],
                        ready=ready, beat=int(i) in beats, bpm=bpm, music=bool(music[j]))
                  for j, i in enumerate(idx)]
        self._frames += k
        keep = np.searchsorted(starts, self._frames * self.hop, side="right") - 1
        if keep > 0:
            del self._blocks[:keep]
        sent = now()
        for f in frames:
            f.sent = sent
        for sink in self.sinks:
            sink(frames)
        if self.keep_stats:
            self.stats.latency.extend(f.latency for f in frames)
            self.stats.lookahead.extend(f.ready - f.arrival for f in frames)
        return frames

    # ------------------------------------------------------------------ the loop
    def run(self, source: Iterator[Block], *, duration_s: float | None = None,
            stop: threading.Event | None = None) -> SessionStats:
        """Feed ``source``'s blocks as they come (a reader thread queues them) until it ends, ``duration_s`` of
        audio has been fed or ``stop`` is set; then the frames still waiting are made."""
        q: queue.Queue = queue.Queue()
        stop = stop or threading.Event()
        error: list[BaseException] = []

        def reader():
            try:
                for block in source:
                    q.put(block)
                    if stop.is_set():
                        break
            except BaseException as exc:  # handed to the main thread
                error.append(exc)
            finally:
                q.put(None)

        thread = threading.Thread(target=reader, name="dancekit-live-source", daemon=True)
        thread.start()
        fed = 0.0
        ended = False
        try:
            while not ended and not stop.is_set():
                item = q.get()
                if item is None:
                    break
                blocks, ended = take_waiting(item, q.get_nowait, queue.Empty)
                t0, c0 = time.monotonic(), time.thread_time()
                self.feed(blocks)
                self.stats.compute.append(time.monotonic() - t0)
                self.stats.cpu.append(time.thread_time() - c0)
                self.stats.block_audio.append(sum(b.n for b in blocks) / self.sr)
                fed += sum(b.n for b in blocks) / self.sr
                if duration_s is not None and fed >= duration_s:
                    break
        finally:
            stop.set()
        if error:
            raise error[0]
        self.finish()
        if self.stats.light_switches > 3:
            self.notes.append(f"took the lighter path {self.stats.light_switches} times in all")
        if self.stats.merged_blocks:
            self.notes.append(f"{self.stats.merged_blocks} blocks fed together with the one before (behind the clock)")
        return self.stats


def _live_jitter_cap(pipe, config: LiveConfig, genre: str | None):
    """``((jitter_cap settings, genre statistics), OnlineGenreReader or None)`` of a session with
    ``config.jitter_cap`` whose checkpoint has a jitter cap (its ``stages.jitter_cap``); the reader when the cap
    follows the genres read from the music (the checkpoint's ``genre_reader``, of the session's preset, fps and
    hop) and no genre is asked for by name; None: no cap."""
    settings = getattr(pipe, "settings", None)
    stages = getattr(settings, "stages", None)
    if not config.jitter_cap or stages is None or stages.jitter_cap is None:
        return None
    cap = (stages.jitter_cap, stages.genre_stats)
    if genre not in (None, "none", "auto"):
        return cap, None
    reader = getattr(pipe, "genre_reader", None)
    if reader is None or not getattr(pipe, "genres", ()) or reader.preset != pipe.preset \
            or reader.fps != float(pipe.fps) or reader.hop_length != int(pipe.hop_length):
        return None
    return cap, OnlineGenreReader(reader, genres=tuple(pipe.genres))


def take_waiting(first: Block, get_nowait: Callable[[], Block | None],
                 empty: type[Exception]) -> tuple[list[Block], bool]:
    """``first`` and every block already waiting in a queue (``get_nowait()`` until it raises ``empty``), fed to
    :meth:`LiveSession.feed` together (one analysis: a session behind the clock catches up); ``ended`` is True
    when the queue's end mark (None) was among them. Used over a thread's queue (:meth:`LiveSession.run`) and an
    asyncio queue (``dancekit serve``'s live socket) alike."""
    blocks, ended = [first], False
    while True:
        try:
            nxt = get_nowait()
        except empty:
            break
        if nxt is None:
            ended = True
            break
        blocks.append(nxt)
    return blocks, ended


class StreamResampler:
    """Mono float32 audio at ``rate`` Hz → float32 at ``sr`` Hz, piece by piece as it comes (soxr's stream keeps its
    state between pieces, so the pieces give the resampling of the whole); :meth:`flush` returns what soxr still
    holds when the stream ends (a few milliseconds). ``rate == sr``: the pieces as they are."""

    def __init__(self, rate: int, sr: int):
        import soxr

        self.stream = None if rate == sr else soxr.ResampleStream(rate, sr, 1, dtype="float32")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, np.float32)
        return x if self.stream is None else self.stream.resample_chunk(x)

    def flush(self) -> np.ndarray:
        if self.stream is None:
            return np.zeros(0, np.float32)
        return self.stream.resample_chunk(np.zeros(0, np.float32), last=True)


def offline_rate_bound(pipe) -> float:
    """The bound of the offline beat warp of a loaded pipeline (``1 ± bound``): its checkpoint's
    ``stages.beat_sync.max_rate_change``, else the warp's default."""
    from dancekit.motion.timewarp import DEFAULT_MAX_RATE_CHANGE

    bound = pipe.stage_options().beat_sync.max_rate_change
    return float(DEFAULT_MAX_RATE_CHANGE if bound is None else bound)


# ---------------------------------------------------------------------- sources
def file_source(path: str | os.PathLike | list, *, sr: int, block_s: float = 0.04, realtime: bool = True,
                loop: bool = False, start_at: float | None = None) -> Iterator[Block]:
    """An audio file (or a list of files, one after the other) as blocks of ``block_s`` at ``sr`` Hz;
    ``realtime``: each block arrives when its last sample would play (the clock starts at the first block),
    else as fast as they are asked for (arrival: when asked). ``loop``: the file(s) again and again."""
    from dancekit.audio import load

    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    songs = [load(p, sr=sr)[0] for p in paths]  # decoded first: no decoding pause on the clock
    n = max(1, int(round(block_s * sr)))
    t0 = time.monotonic() if start_at is None else start_at
    played = 0
    while True:
        for y in songs:
            for a in range(0, len(y), n):
                block = y[a : a + n]
                played += len(block)
                if realtime:
                    due = t0 + played / sr
                    wait = due - time.monotonic()
                    if wait > 0:
                        time.sleep(wait)
                    yield Block(np.ascontiguousarray(block, np.float32), due)
                else:
                    yield Block(np.ascontiguousarray(block, np.float32), time.monotonic())
        if not loop:
            return


def pcm_source(stream, *, rate: int, sr: int, block_s: float = 0.08, channels: int = 1) -> Iterator[Block]:
    """Raw signed 16-bit little-endian PCM (``channels`` interleaved, ``rate`` Hz) read from a binary
    ``stream`` (stdin) as blocks at ``sr`` Hz (mixed to mono, resampled block by block: soxr keeps its state)."""
    if rate <= 0 or channels <= 0:
        raise ParameterError(f"PCM input needs a positive rate and channel count, got {rate} Hz, {channels}")
    n = max(1, int(round(block_s * rate)))
    resample = StreamResampler(rate, sr)
    while True:
        data = stream.read(2 * channels * n)
        arrival = time.monotonic()
        if not data:
            break
        usable = len(data) - len(data) % (2 * channels)
        x = np.frombuffer(data[:usable], "<i2").astype(np.float32).reshape(-1, channels).mean(axis=1) / 32768.0
        y = resample(x)
        if len(y):
            yield Block(np.ascontiguousarray(y, np.float32), arrival)
    tail = resample.flush()
    if len(tail):
        yield Block(np.ascontiguousarray(tail, np.float32), time.monotonic())


def microphone_source(*, sr: int, block_s: float = 0.08, device: str | int | None = None) -> Iterator[Block]:
    """The microphone or line-in (PortAudio through the optional ``sounddevice`` package) as blocks at ``sr``
    Hz; an overflowed input block is a dropped block (None)."""
    try:
        import sounddevice as sd
    except (ImportError, OSError) as exc:
        raise AudioError("dancekit live --mic needs the optional sounddevice package and PortAudio "
                         f"(pip install 'dancekit[live]'; Debian: apt install libportaudio2): {exc}") from None
    n = max(1, int(round(block_s * sr)))
    q: queue.Queue = queue.Queue()

    def callback(indata, frames, t, status):
        arrival = time.monotonic()
        q.put(Block(None, arrival, n=frames) if status.input_overflow else Block(indata[:, 0].copy(), arrival))

    try:
        with sd.InputStream(samplerate=sr, blocksize=n, channels=1, dtype="float32", device=device,
                            callback=callback):
            while True:
                yield q.get()
    except sd.PortAudioError as exc:
        raise AudioError(f"cannot open the audio input {device if device is not None else '(default)'}: {exc}") from None
