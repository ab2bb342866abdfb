"""dancekit.serve: ``dancekit serve``, a local web app and HTTP API over the pipelines and the exports.

- :mod:`~dancekit.serve.app`: the FastAPI app (pages, JSON API, token and upload guards) and :func:`serve`;
- :mod:`~dancekit.serve.jobs`: :class:`ServeConfig` and :class:`JobManager` (job folders, a bounded queue,
  worker processes, the cache bounds);
- :mod:`~dancekit.serve.worker`: the worker process (models loaded once; the library calls of
  ``dancekit dance`` and ``dancekit compose``);
- :mod:`~dancekit.serve.uploads`: file kinds read from the bytes, safe stems, capped copies.

FastAPI, uvicorn and python-multipart are the ``serve`` extra (``pip install 'dancekit[serve]'``); they are
imported only when the app is built.
"""

from dancekit.serve.jobs import JobManager, ServeConfig

__all__ = ["JobManager", "ServeConfig", "create_app", "serve"]


def __getattr__(name: str):
    if name in ("create_app", "serve"):
        from dancekit.serve import app

        return getattr(app, name)
    raise AttributeError(f"module 'dancekit.serve' has no attribute {name!r}")
