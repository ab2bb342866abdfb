"""Models on the Hugging Face Hub: ``hf:USER/NAME[@REVISION]`` resolved to a local checkpoint folder, and a
checkpoint folder pushed to a hub repository (``dancekit models push``).

The download goes through :func:`huggingface_hub.snapshot_download` into the hub cache under the user's
dancekit models folder, ``<user models dir>/hf`` (``$DANCEKIT_MODELS/hf``, default
``~/.cache/dancekit/models/hf``; Hugging Face's own cache layout: ``models--USER--NAME/snapshots/<commit>/``),
so that ``DANCEKIT_MODELS`` alone decides where every model of dancekit lives. The endpoint is
``$HF_ENDPOINT`` (default ``https://huggingface.co``) and ``HF_HUB_OFFLINE=1`` uses the cache only; both are
read at every call. The token is Hugging Face's (``HF_TOKEN`` or ``hf auth login``).

A repository is checked before its weights are fetched: its ``config.json`` comes first, and a repository
without a dancekit ``config.json`` is refused in one line. A composite model's component folders are
part of the snapshot.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import re
import warnings
from pathlib import Path
from typing import Any

from dancekit.errors import CheckpointError, DancekitError, ParameterError

PREFIX = "hf:"
DEFAULT_ENDPOINT = "https://huggingface.co"
_REPO_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,95}/[A-Za-z0-9][A-Za-z0-9._-]{0,95}$")
_REVISION = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._/-]{0,127}$")
_RESOLVED: dict[tuple, Path] = {}  # (endpoint, repo, revision, cache, offline) -> folder, for this process


def is_hub_name(model: Any) -> bool:
    """Whether ``model`` names a hub model (a string starting with ``hf:``)."""
    return isinstance(model, str) and model.startswith(PREFIX)


def parse_hub_name(model: str) -> tuple[str, str | None]:
    """``"hf:USER/NAME@REV"`` → ``("USER/NAME", "REV")`` (``None``: the default branch).

    Raises :class:`ParameterError` for a name that is not ``hf:USER/NAME`` or ``hf:USER/NAME@REVISION``.
    """
    body = model[len(PREFIX):] if model.startswith(PREFIX) else model
    repo, _, rev = body.partition("@")
    if not _REPO_ID.match(repo) or ".." in repo or (rev and (not _REVISION.match(rev) or ".." in rev)) \
            or (_ and not rev):
        raise ParameterError(f"bad hub model name {model!r}: expected hf:USER/NAME or hf:USER/NAME@REVISION")
    return repo, rev or None


def endpoint() -> str:
    """The hub's address: ``$HF_ENDPOINT``, else ``https://huggingface.co``."""
    return (os.environ.get("HF_ENDPOINT") or DEFAULT_ENDPOINT).rstrip("/")


def offline() -> bool:
    """Whether ``HF_HUB_OFFLINE`` asks for the cache only."""
    return os.environ.get("HF_HUB_OFFLINE", "").strip().lower() in ("1", "true", "yes", "on")


def hub_cache_dir() -> Path:
    """Where hub models are cached: ``<user models dir>/hf`` (Hugging Face's cache layout)."""
    from dancekit.checkpoints.hub import user_models_dir

    return user_models_dir() / "hf"


def _hub():
    try:
        import huggingface_hub
        import huggingface_hub.constants
        import huggingface_hub.errors
    except ImportError:  # pragma: no cover - a dependency; guards a broken install
        raise DancekitError("hub models need huggingface_hub: pip install 'dancekit[hub]' (huggingface_hub)") from None
    # huggingface_hub reads HF_HUB_OFFLINE once, at its import; dancekit reads it at every call
    huggingface_hub.constants.HF_HUB_OFFLINE = offline()
    return huggingface_hub


@contextlib.contextmanager
def _quiet():
    """huggingface_hub's progress bars, log lines and warnings kept off the user's terminal."""
    from huggingface_hub.utils import are_progress_bars_disabled, disable_progress_bars, enable_progress_bars

    log = logging.getLogger("huggingface_hub")
    level = log.level
    log.setLevel(logging.ERROR)
    was_disabled = are_progress_bars_disabled()
    disable_progress_bars()
    try:
        with contextlib.redirect_stderr(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        if not was_disabled:
            enable_progress_bars()
        log.setLevel(level)


def _why(exc: BaseException) -> str:
    """The first line of an exception's message, for a one-line error."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _hub_error(exc: BaseException, name: str, where: str) -> DancekitError:
    """A one-line :class:`CheckpointError` for a failed download of ``name``."""
    hf = _hub()
    errors = hf.errors
    if isinstance(exc, errors.RevisionNotFoundError):
        return CheckpointError(f"{name}: no such revision on {where}")
    if isinstance(exc, errors.RepositoryNotFoundError | errors.GatedRepoError):
        return CheckpointError(f"{name}: no such model repository on {where} (or it is private: log in with "
                               "`hf auth login` or set HF_TOKEN)")
    if isinstance(exc, errors.RemoteEntryNotFoundError):
        return CheckpointError(f"{name} is not a dancekit model: the repository on {where} has no config.json")
    if isinstance(exc, errors.LocalEntryNotFoundError | errors.IncompleteSnapshotError):
        if offline():
            return CheckpointError(f"{name} is not in the hub cache {hub_cache_dir()} and HF_HUB_OFFLINE is set: "
                                   "download it once with network access")
        cause = exc.__cause__ or exc
        return CheckpointError(f"cannot download {name} from {where} ({_why(cause)}); no copy in the hub cache "
                               f"{hub_cache_dir()}: check the network, or HF_ENDPOINT")
    return CheckpointError(f"cannot download {name} from {where}: {_why(exc)}")


def _check_config(folder: Path, name: str) -> None:
    """Refuse a downloaded folder whose ``config.json`` is not a dancekit checkpoint's."""
    path = folder / "config.json"
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise CheckpointError(f"{name} is not a dancekit model: the repository has no config.json") from None
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise CheckpointError(f"{name} is not a dancekit model: its config.json is not JSON") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("model"), str):
        raise CheckpointError(f"{name} is not a dancekit model: its config.json has no 'model' entry "
                              "(a dancekit checkpoint folder: config.json, model.safetensors, stats.npz)")


def download_model(model: str) -> Path:
    """The local checkpoint folder of the hub model ``model`` (``hf:USER/NAME[@REVISION]``), downloaded once.

    The repository's ``config.json`` is fetched and checked first, then the whole snapshot of the same
    commit (weights, stats, card, component folders). With ``HF_HUB_OFFLINE=1`` only the cache is read.
    A folder once resolved in this process is returned again without asking the hub.

    Raises
    ------
    ParameterError
        For a malformed name.
    CheckpointError
        For a repository or revision that does not exist, a repository that is not a dancekit checkpoint,
        no network (and nothing cached), or an offline cache without the model: one line each.
    """
    repo, rev = parse_hub_name(model)
    hf = _hub()
    where, cache, off = endpoint(), hub_cache_dir(), offline()
    key = (where, repo, rev, str(cache), off)
    if key in _RESOLVED and (_RESOLVED[key] / "config.json").is_file():
        return _RESOLVED[key]
    common = dict(repo_id=repo, repo_type="model", cache_dir=str(cache), endpoint=where, local_files_only=off,
                  library_name="dancekit")
    try:
        with _quiet():
            first = Path(hf.snapshot_download(revision=rev, allow_patterns=["config.json"], **common))
            _check_config(first, model)
            commit = first.name  # snapshots/<commit>: the rest comes from the same commit
            folder = Path(hf.snapshot_download(revision=commit if not off else rev, **common))
    except DancekitError:
        raise
    except Exception as exc:  # noqa: BLE001 - huggingface_hub's and httpx's errors, turned into one line
        raise _hub_error(exc, model, where) from exc
    _check_config(folder, model)
    _RESOLVED[key] = folder
    return folder


def _card_readme(repo: str, meta: dict, card: dict) -> str:
    """A Hugging Face model card (``README.md``) from the checkpoint's ``config.json`` and ``card.json``."""
    lines = ["---", "library_name: dancekit", "tags:", "- dancekit", f"- {meta['model']}",
             "- music-to-dance", "---", "", f"# {repo}", ""]
    if card.get("description"):
        lines += [str(card["description"]), ""]
    lines += [f"A dancekit model of the `{meta['model']}` family. Dance with it:", "", "```",
              f"dancekit dance SONG.mp3 -o out --model hf:{repo}", "```", ""]
    for key in ("training_data", "training_time", "parameters"):
        if key in card:
            lines.append(f"- {key.replace('_', ' ')}: {card[key]}")
    metrics = card.get("metrics") or {}
    if metrics:
        lines += ["", "| metric | value |", "| --- | --- |"]
        lines += [f"| {k} | {v} |" for k, v in metrics.items()]
    return "\n".join(lines).rstrip() + "\n"


def push_model(folder: str | os.PathLike, repo: str, *, private: bool = False, message: str | None = None,
               token: str | None = None) -> str:
    """Upload the checkpoint folder ``folder`` (with its component folders and ``card.json``) to the hub
    model repository ``repo`` (``USER/NAME``, created if missing); returns the commit's id.

    A ``README.md`` model card is made from ``config.json`` and ``card.json`` when the folder has none
    (it is uploaded, the folder is left as it is).

    Raises
    ------
    ParameterError
        For a malformed ``repo``.
    CheckpointError
        For a folder that is not a checkpoint (no ``config.json``, a missing component or weights file),
        before anything is sent; for a failed upload (one line: no network, not logged in, no rights).
    """
    from dancekit.checkpoints.hub import components, model_card, read_meta

    folder = Path(folder)
    repo_id, rev = parse_hub_name(repo)
    if rev is not None:
        raise ParameterError(f"push to a repository, not a revision: {repo!r}")
    if not folder.is_dir():
        raise CheckpointError(f"checkpoint folder not found: {folder}")
    meta = read_meta(folder)
    components(folder, meta)
    if not (folder / "model.safetensors").is_file():
        raise CheckpointError(f"not a checkpoint folder (no model.safetensors): {folder}")
    hf = _hub()
    where = endpoint()
    api = hf.HfApi(endpoint=where, token=token, library_name="dancekit")
    ops = []
    if not (folder / "README.md").is_file():
        readme = _card_readme(repo_id, meta, model_card(folder)).encode()
        ops.append(hf.CommitOperationAdd(path_in_repo="README.md", path_or_fileobj=readme))
    skip = {".git", "__pycache__", ".cache"}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if path.is_file() and not (set(rel.parts) & skip) and not rel.name.startswith("."):
            ops.append(hf.CommitOperationAdd(path_in_repo=rel.as_posix(), path_or_fileobj=str(path)))
    try:
        with _quiet():
            api.create_repo(repo_id, repo_type="model", private=private, exist_ok=True)
            info = api.create_commit(repo_id, ops, repo_type="model",
                                     commit_message=message or f"dancekit: upload {meta['model']} model")
    except Exception as exc:  # noqa: BLE001 - huggingface_hub's and httpx's errors, turned into one line
        status = getattr(getattr(exc, "response", None), "status_code", None)
        if status in (401, 403):
            raise CheckpointError(f"cannot push to {repo_id} on {where}: not allowed (HTTP {status}); log in with "
                                  "`hf auth login` or set HF_TOKEN to a token with write access") from exc
        raise CheckpointError(f"cannot push {folder} to {repo_id} on {where}: {_why(exc)}") from exc
    return str(info.oid)
