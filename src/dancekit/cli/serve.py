"""``dancekit serve``: the local web app and HTTP API (:mod:`dancekit.serve`)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from dancekit.errors import DancekitError, ParameterError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve",
        help="a local web app and HTTP API: upload a song, watch its dance, download every format",
        description="Serve the dance, compose and models pages and the HTTP API (/docs, /openapi.json). "
                    "Binds to 127.0.0.1; another host needs --token. Needs the serve extra: "
                    "pip install 'dancekit[serve]'.",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 2) // 2),
                   help="worker processes, each with its own models (default: one per 2 cores)")
    p.add_argument("--token", default=os.environ.get("DANCEKIT_SERVE_TOKEN"),
                   help="a secret every request must carry (?token=T or Authorization: Bearer T); required for "
                        "a host other than the loopback (default: $DANCEKIT_SERVE_TOKEN)")
    p.add_argument("--cache", default=str(Path("~/.cache/dancekit/serve")),
                   help="job folder: uploads and finished jobs (default ~/.cache/dancekit/serve)")
    p.add_argument("--cache-mb", type=float, default=2000, help="size bound of the job folder, MB (default 2000)")
    p.add_argument("--cache-days", type=float, default=7, help="finished jobs are removed after this (default 7)")
    p.add_argument("--queue", type=int, default=8, help="jobs that may wait for a worker; more get 429 (default 8)")
    p.add_argument("--max-upload-mb", type=float, default=100, help="largest upload, MB (default 100)")
    p.add_argument("--max-minutes", type=float, default=20, help="longest song, minutes (default 20)")
    p.add_argument("--threads", type=int, default=1, help="torch threads per worker (default 1)")
    p.add_argument("--live", type=int, default=1, metavar="N",
                   help="live sessions at once on /live (the browser's microphone danced as it plays; each takes "
                        "about a third of a core); 0: none (default 1)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    for name in ("workers", "queue", "threads"):
        if getattr(args, name) < 1:
            raise ParameterError(f"--{name} must be at least 1, got {getattr(args, name)}")
    if args.live < 0:
        raise ParameterError(f"--live must be at least 0, got {args.live}")
    for name in ("cache_mb", "cache_days", "max_upload_mb", "max_minutes"):
        if not getattr(args, name) > 0:
            raise ParameterError(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name):g}")
    if not 0 < args.port < 65536:
        raise ParameterError(f"--port must be in 1-65535, got {args.port}")
    try:
        import fastapi  # noqa: F401
        import python_multipart  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError as exc:
        raise DancekitError(f"dancekit serve needs the serve extra ({exc.name} is missing): "
                            "pip install 'dancekit[serve]'") from None
    from dancekit.serve import ServeConfig, serve
    from dancekit.serve.app import is_loopback

    config = ServeConfig(cache=Path(args.cache), workers=args.workers, max_queue=args.queue,
                         max_upload_bytes=int(args.max_upload_mb * 1e6), max_seconds=args.max_minutes * 60,
                         max_bytes=int(args.cache_mb * 1e6), max_age_s=args.cache_days * 86400,
                         threads=args.threads, preload=["revolution"], token=args.token or None, host=args.host,
                         max_live=args.live)
    if not is_loopback(args.host) and not config.token:
        raise ParameterError(f"--host {args.host} opens the server to other machines: give it a --token "
                             "(or $DANCEKIT_SERVE_TOKEN)")
    where = f"http://{'localhost' if is_loopback(args.host) else args.host}:{args.port}/"
    if config.token:
        print(f"dancekit serve: {where}?token=<your token>  (every request must carry the token; bound to "
              f"{args.host})", flush=True)
    else:
        print(f"dancekit serve: open {where}  (this machine only; API: {where}docs; live: {where}live)", flush=True)
    print(f"  {args.workers} worker(s), queue {args.queue}, jobs in {config.cache} (Ctrl-C stops)", flush=True)
    serve(config, port=args.port)
    return 0
