"""``dancekit live``: dance to music as it plays (a file fed at the clock's pace, raw PCM on stdin, or the
microphone), poses streamed to the live page and to any WebSocket client, the performance recorded on stop."""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path

from dancekit.errors import ParameterError


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "live", help="dance to music as it plays (file, stdin PCM or microphone), poses streamed over a WebSocket",
        description="Dance to music as it plays: the features, the beat tracker, the model and the clean-up all run "
                    "online, and each pose frame is sent within a fraction of a second of its audio "
                    "(docs/LIVE.md). Open the printed address for the live page; the pose stream is "
                    "ws://HOST:PORT/poses.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--input", "-i", metavar="FILE", help="an audio file (with --realtime: fed at the clock's pace)")
    src.add_argument("--stdin", action="store_true", help="raw signed 16-bit little-endian PCM on stdin")
    src.add_argument("--mic", action="store_true", help="the microphone or line-in (needs the sounddevice extra)")
    p.add_argument("--realtime", action="store_true",
                   help="feed --input at the pace of the clock (without it: as fast as it is danced, for tests)")
    p.add_argument("--rate", type=int, default=44100, help="--stdin: sample rate in Hz (default 44100)")
    p.add_argument("--channels", type=int, default=1, help="--stdin: interleaved channels (default 1)")
    p.add_argument("--device", default=None, help="--mic: the PortAudio input device (name or index)")
    p.add_argument("--model", "-m", default="revolution", help="revolution (default), music2dance, or a folder")
    p.add_argument("--genre", default=None, help="music2dance: the dance type (default: none)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--lookahead", type=float, default=None, help="feature lookahead in s (default 0.08)")
    p.add_argument("--jitter-cap", action="store_true",
                   help="music2dance: hold the tremor under its checkpoint's jitter cap, the genre read from the music "
                        "as it comes (a calmer dancer; on the validation songs FID_k +22 %%, docs/LIVE.md)")
    p.add_argument("--foot-lock", choices=("on", "off"), default="on",
                   help="hold the planted feet (default on: less foot skating, chosen on the validation songs; "
                        "docs/LIVE.md)")
    p.add_argument("--host", default="127.0.0.1", help="where the live page listens (default loopback)")
    p.add_argument("--port", type=int, default=8765, help="port of the live page and pose stream (0: any free)")
    p.add_argument("--no-serve", action="store_true", help="no page and no stream (record or log only)")
    p.add_argument("--osc", metavar="HOST:PORT", default=None,
                   help="also send the poses over OSC (UDP) to HOST:PORT (needs the osc extra; docs/LIVE.md)")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds of audio")
    p.add_argument("--record", type=Path, default=None, metavar="OUT",
                   help="write the performance when it stops: OUT.npz, OUT.bvh or OUT.glb (with OUT.wav, the audio)")
    p.add_argument("--log", type=Path, default=None, metavar="JSONL",
                   help="one JSON line per frame: index, audio time, arrival, sent, latency (s)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    import numpy as np
    import torch
    from threadpoolctl import threadpool_limits

    from dancekit._io import atomic_path
    from dancekit.live import LiveConfig
    from dancekit.live.session import LiveSession, file_source, microphone_source, pcm_source

    if args.record is not None and args.record.suffix.lower() not in (".npz", ".bvh", ".glb"):
        raise ParameterError(f"--record {args.record}: the file must end in .npz, .bvh or .glb")
    if args.realtime and not args.input:
        raise ParameterError("--realtime paces a file: use it with --input")
    if args.osc is not None:
        from dancekit.live.osc import parse_address

        parse_address(args.osc)
    if args.duration is not None and not args.duration > 0:
        raise ParameterError(f"--duration must be > 0 s, got {args.duration}")
    if args.input and not Path(args.input).is_file():
        from dancekit.errors import AudioError

        raise AudioError(f"no such audio file: {args.input}")
    config = LiveConfig(seed=args.seed, jitter_cap=args.jitter_cap,
                        foot_lock=args.foot_lock == "on",
                        **({} if args.lookahead is None else {"lookahead_s": args.lookahead}))
    torch.set_num_threads(1)  # one core for the model, the other for the features and the stream
    recorded: list[np.ndarray] = []
    heard: list[np.ndarray] = []
    log = None
    with threadpool_limits(1):
        session = LiveSession(args.model, config=config, genre=args.genre)
        if args.input:
            source = file_source(args.input, sr=session.sr, block_s=config.block_s, realtime=args.realtime)
        elif args.stdin:
            source = pcm_source(sys.stdin.buffer, rate=args.rate, sr=session.sr, block_s=config.block_s,
                                channels=args.channels)
        else:
            source = microphone_source(sr=session.sr, block_s=config.block_s, device=args.device)
        if args.osc is not None:
            from dancekit.live.osc import OscSink

            session.sinks.append(OscSink(args.osc, skeleton=session.skeleton))
        if args.record is not None:
            session.sinks.append(lambda frames: recorded.extend(f.joints for f in frames))
            source = _tee(source, heard)
        server = None
        if not args.no_serve:
            from dancekit.live.server import PoseServer, hello_message

            server = PoseServer(hello_message(session.skeleton, fps=session.fps, model=args.model),
                                host=args.host, port=args.port).start()
            session.sinks.append(server.send)
            print(f"dancekit live: the live page is {server.url} (pose stream ws://{args.host}:{server.port}/poses)",
                  file=sys.stderr, flush=True)
        if args.log is not None:
            log_cm = atomic_path(args.log)
            log_path = log_cm.__enter__()
            log = open(log_path, "w")
            session.sinks.append(lambda frames: log.writelines(
                json.dumps({"frame": f.index, "t": f.time, "arrival": f.arrival, "ready": f.ready, "sent": f.sent,
                            "latency": f.latency}) + "\n" for f in frames))
        stop = threading.Event()
        try:
            stats = session.run(source, duration_s=args.duration, stop=stop)
        finally:
            if server is not None:
                server.stop()
            if log is not None:
                log.close()
                log_cm.__exit__(*sys.exc_info())
    summary = stats.summary()
    for note in session.notes:
        print(f"dancekit live: {note}", file=sys.stderr)
    if summary["frames"]:
        print(f"dancekit live: {summary['frames']} frames, latency median {summary['latency_median_s']:.3f} s, "
              f"99th percentile {summary['latency_p99_s']:.3f} s (lookahead {summary['lookahead_median_s']:.3f} s), "
              f"compute {summary['compute_per_audio_s']:.3f} s per s of audio", file=sys.stderr)
    if args.record is not None:
        _record(args.record, recorded, heard, session)
        print(f"dancekit live: recorded {args.record}", file=sys.stderr)
    return 0


def _tee(source, heard):
    for block in source:
        if block.samples is not None:
            heard.append(block.samples)
        yield block


def _record(out: Path, poses, heard, session) -> None:
    """Write the performance (OUT.npz / .bvh / .glb) and the audio it heard (OUT.wav), all or nothing."""
    import numpy as np

    from dancekit.errors import DancekitError
    from dancekit.export import export_motion
    from dancekit.motion import Motion

    if not poses:
        raise DancekitError(f"nothing to record in {out}: no frame was danced")
    motion = Motion(skeleton=session.skeleton, fps=session.fps, positions=np.stack(poses).astype(np.float32))
    fmt = out.suffix.lower().lstrip(".")
    folder = out.parent if str(out.parent) else Path(".")
    y = np.concatenate(heard) if heard else np.zeros(0, np.float32)
    from dancekit.audio import save_wav

    written = export_motion(motion, folder, stem=out.stem, formats=[fmt])
    try:
        save_wav(out.with_suffix(".wav"), y, sr=session.sr)
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        raise
