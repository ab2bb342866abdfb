"""Finding model folders: one resolver from a model name to a checkpoint folder, and composite models.

``resolve_model(name_or_path)`` looks, in order, at

1. an explicit path (a folder holding ``config.json``);
2. the user's models folder: ``$DANCEKIT_MODELS`` when set, else ``<user cache>/dancekit/models``
   (``$XDG_CACHE_HOME`` or ``~/.cache``), one sub-folder per model name;
3. the models embedded in the package (``dancekit/assets/models/<name>/``), so the default model needs
   no download.

A name ``hf:USER/NAME`` (or ``hf:USER/NAME@REVISION``: a branch, tag or commit) is a model on the Hugging
Face Hub, downloaded once into ``<user models folder>/hf`` (:mod:`dancekit.checkpoints.hf`;
``HF_ENDPOINT`` and ``HF_HUB_OFFLINE=1`` are honoured).

A **composite model** declares its parts in its own ``config.json`` (as diffusers' ``model_index.json``
does), never by the presence of folders::

    "components": {"genre_reader": "music_attributes",
                   "genres": {"waltz": "genres/waltz", "rumba": "genres/rumba"}}

Each value is a folder relative to the parent (a checkpoint folder of its own), or a mapping of such
folders. :func:`components` reads and checks the index; the pipelines interpret the names.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from dancekit.errors import CheckpointError, ParameterError

MODELS_DIR = Path(__file__).resolve().parents[1] / "assets" / "models"
DEFAULT_MODEL = "revolution"
CONFIG_FILE = "config.json"


def user_models_dir() -> Path:
    """The user's models folder: ``$DANCEKIT_MODELS``, else ``<user cache dir>/dancekit/models``."""
    env = os.environ.get("DANCEKIT_MODELS")
    if env:
        return Path(env).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "dancekit" / "models"


def _model_folders(root: Path) -> dict[str, Path]:
    if not root.is_dir():
        return {}
    return {p.name: p for p in sorted(root.iterdir()) if p.is_dir() and (p / CONFIG_FILE).is_file()}


def embedded_models() -> dict[str, Path]:
    """Name → folder of every model embedded in the package (dance models and classifiers)."""
    return _model_folders(MODELS_DIR)


def available_models() -> dict[str, Path]:
    """Name → folder of every model found by name: the user's models folder first, then the embedded ones."""
    return {**embedded_models(), **_model_folders(user_models_dir())}


def resolve_model(model: str | os.PathLike | None = None) -> Path:
    """The checkpoint folder of ``model``: an explicit folder, else a name in the user's models folder,
    else an embedded model (``None``: the default model); ``hf:USER/NAME[@REVISION]``: a hub model,
    downloaded into the hub cache on first use (:func:`dancekit.checkpoints.hf.download_model`).

    Raises
    ------
    CheckpointError
        For a path (anything with a separator) that does not exist or holds no ``config.json``; for a hub
        model that cannot be downloaded or is not a dancekit checkpoint.
    ParameterError
        For a name found nowhere (the message lists the names that exist).
    """
    name = DEFAULT_MODEL if model is None else model
    if isinstance(name, str) and name.startswith("hf:"):
        from dancekit.checkpoints.hf import download_model

        return download_model(name)
    path = Path(name)
    if path.is_dir():
        if not (path / CONFIG_FILE).is_file():
            raise CheckpointError(f"not a checkpoint folder (no {CONFIG_FILE}): {path}")
        return path
    if not isinstance(name, str) or os.sep in name or "/" in name:  # a path, not a name
        raise CheckpointError(f"checkpoint folder not found: {path}")
    user = user_models_dir() / name
    if (user / CONFIG_FILE).is_file():
        return user
    if (MODELS_DIR / name / CONFIG_FILE).is_file():
        return MODELS_DIR / name
    known = ", ".join(available_models()) or "none"
    raise ParameterError(f"unknown model {str(name)!r}: not a checkpoint folder, and no model of that name in "
                         f"{user_models_dir()} or the embedded models ({known})")


def read_meta(folder: str | os.PathLike) -> dict[str, Any]:
    """The parsed ``config.json`` of a model folder (:class:`CheckpointError` when missing or corrupt)."""
    path = Path(folder) / CONFIG_FILE
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise CheckpointError(f"not a checkpoint: {path} is missing") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CheckpointError(f"corrupt checkpoint file {path}: {exc}") from exc
    if not isinstance(doc, dict) or "model" not in doc:
        raise CheckpointError(f"corrupt checkpoint file {path}: no 'model' entry")
    return doc


def components(folder: str | os.PathLike, meta: dict[str, Any] | None = None) -> dict[str, Any]:
    """The component index of a composite model folder: name → folder, or name → {key → folder}.

    Every listed folder must exist and hold a ``config.json``; an empty dict when the model declares none.
    """
    folder = Path(folder)
    meta = read_meta(folder) if meta is None else meta
    index = meta.get("components") or {}
    if not isinstance(index, dict):
        raise CheckpointError(f"{folder / CONFIG_FILE}: 'components' must be a mapping")

    def check(rel: Any, where: str) -> Path:
        if not isinstance(rel, str) or Path(rel).is_absolute() or ".." in Path(rel).parts:
            raise CheckpointError(f"{folder / CONFIG_FILE}: component {where} must be a relative folder, got {rel!r}")
        path = folder / rel
        if not (path / CONFIG_FILE).is_file():
            raise CheckpointError(f"{folder / CONFIG_FILE}: component {where} ({path}) is not a checkpoint folder")
        return path

    out: dict[str, Any] = {}
    for name, value in index.items():
        if isinstance(value, dict):
            out[name] = {k: check(v, f"{name}.{k}") for k, v in value.items()}
        else:
            out[name] = check(value, name)
    return out


def model_card(folder: str | os.PathLike) -> dict:
    """The ``card.json`` of a model folder (empty when there is none)."""
    card = Path(folder) / "card.json"
    return json.loads(card.read_text()) if card.is_file() else {}


def model_cards() -> dict[str, dict]:
    """Name → card of every model :func:`available_models` finds (what ``dancekit models`` prints): ``name``,
    ``family``, ``kind`` (the registry's: dance, classifier, postprocess; ``unknown`` for an unregistered
    family), ``folder``, ``default``, ``size_mb``, ``genre_models`` (names), ``reads_genre_from_music``, ``live_model`` (a ``live`` component: the model
    ``dancekit live`` steps), ``genre_condition`` (the genres a model takes as
    an input, e.g. music2dance's dance type) and the
    fields of its ``card.json`` (``description``, ``training_data``, ``metrics``, ...)."""
    from dancekit import registry

    cards = {}
    for name, folder in available_models().items():
        meta = read_meta(folder)
        family = meta["model"]
        kind = registry.get(family).kind if family in registry.families() else "unknown"
        parts = components(folder, meta)
        size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())
        card = {"name": name, "family": family, "kind": kind, "folder": str(folder),
                "default": name == DEFAULT_MODEL, "size_mb": round(size / 1e6, 2),
                "genre_models": list(parts.get("genres", {})),
                "reads_genre_from_music": "genre_reader" in parts,
                "live_model": "live" in parts,
                "genre_condition": list(meta.get("genres", [])) if meta.get("config", {}).get("n_genres") else [],
                **model_card(folder)}
        if not card.get("description"):  # a model without a card.json still says what it is
            genres = meta.get("genres") or meta.get("config", {}).get("genres") or []
            card["description"] = f"a {family} model ({kind}, no model card)" + (
                f"; genres: {', '.join(genres)}" if genres else "")
        cards[name] = card
    return cards


def declare_components(folder: str | os.PathLike, index: dict[str, Any]) -> dict[str, Any]:
    """Add ``index`` (name → relative folder, or name → {key → relative folder}) to the component index of
    the model in ``folder`` (its ``config.json``, rewritten atomically); a mapping merges into an existing one.

    Returns the resolved index (:func:`components`). Raises :class:`CheckpointError` for a folder that
    is not a checkpoint, before anything is written.
    """
    from dancekit._io import atomic_path

    folder = Path(folder)
    meta = read_meta(folder)
    merged = dict(meta.get("components") or {})
    for name, value in index.items():
        if isinstance(value, dict) and isinstance(merged.get(name), dict):
            merged[name] = {**merged[name], **value}
        else:
            merged[name] = value
    meta["components"] = merged
    resolved = components(folder, meta)
    with atomic_path(folder / CONFIG_FILE) as tmp:
        tmp.write_text(json.dumps(meta, indent=1))
    return resolved
