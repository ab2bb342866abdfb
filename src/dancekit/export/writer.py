"""One motion to every output format, written through a staging folder (:func:`export_motion`)."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from dancekit.errors import DancekitError, ParameterError

if TYPE_CHECKING:
    from dancekit.motion import Motion
    from dancekit.render import AudioClip, RenderOptions

FORMATS = ("mp4", "html", "npz", "bvh", "openpose", "glb", "pkl", "coco17", "coco18", "fbx")
DEFAULT_FORMATS = ("mp4", "html", "npz", "bvh")
_STAGE_PREFIX = ".dancekit-"


def check_formats(formats: str | Iterable[str]) -> list[str]:
    """``formats`` (names, or one comma-separated string) as a list of :data:`FORMATS`, duplicates dropped.

    Raises
    ------
    ParameterError
        If a name is not in :data:`FORMATS` (the message names it), or none is given.
    ExternalToolError
        For ``fbx`` without Blender (one line naming what to install), before any work is done.
    """
    items = formats.split(",") if isinstance(formats, str) else list(formats)
    names = [str(f).strip().lower() for f in items if str(f).strip()]
    bad = [f for f in names if f not in FORMATS]
    if bad or not names:
        raise ParameterError(
            f"unknown output format {', '.join(bad) or repr(formats)}; choose from {', '.join(FORMATS)}"
        )
    if "fbx" in names:
        from dancekit.export.fbx import require_blender

        require_blender()
    return list(dict.fromkeys(names))


def check_output_folder(folder: str | os.PathLike) -> Path:
    """Check that :func:`export_motion` can write into ``folder``, leaving nothing behind.

    ``folder`` may be missing if it can be created. The check makes and removes an empty
    folder in ``folder`` (or in its nearest existing parent). :func:`export_motion` checks
    again; this lets a caller fail before spending time on a dance.

    Raises
    ------
    DancekitError
        If ``folder`` is a file, or is (or would be created in) a folder that is not writable.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DancekitError(f"output path exists and is not a folder: {folder}")
    where = folder if folder.is_dir() else _first_missing(folder).parent
    try:
        os.rmdir(tempfile.mkdtemp(prefix=_STAGE_PREFIX, dir=where))
    except OSError as exc:
        if folder.is_dir():
            raise DancekitError(f"output folder is not writable: {folder} ({exc.strerror})") from exc
        raise DancekitError(
            f"cannot create output folder {folder}: cannot write in {where} ({exc.strerror})"
        ) from exc
    return folder


def export_motion(
    motion: Motion,
    folder: str | os.PathLike,
    *,
    stem: str,
    formats: str | Iterable[str] = DEFAULT_FORMATS,
    audio: AudioClip | str | os.PathLike | None = None,
    options: RenderOptions | None = None,
    progress: bool = False,
    bvh_rig: str = "exact",
) -> list[Path]:
    """Write ``motion`` into ``folder`` in every requested format, all or nothing.

    Every file is first written into a staging folder inside ``folder`` and moved into
    place once all are complete; files of the same names already in ``folder`` are
    replaced. On any error, or Ctrl-C, the staging folder is removed, replaced files are
    put back, and a ``folder`` this call created is removed: the folder is left as it was.

    Parameters
    ----------
    motion : Motion
        The dance.
    folder : path-like
        Output folder, created (with its parents) if missing.
    stem : str
        File name stem of the outputs (a name, not a path).
    formats : str or iterable of str
        From :data:`FORMATS`: ``mp4`` (video with the song), ``html`` (self-contained
        player), ``npz`` (the motion), ``bvh``, ``openpose`` (a folder of BODY_25 JSON, one
        file per frame; a 3D motion is projected), ``glb`` (glTF 2.0: the rig, the animation
        and a skinned body, :mod:`dancekit.motion.formats.gltf`), ``pkl`` (AIST++ SMPL at 60 fps,
        retargeted onto SMPL, :func:`dancekit.motion.formats.aistpp.write_aistpp`), ``coco17`` /
        ``coco18`` (folders of COCO keypoint JSON, like ``openpose``), ``fbx`` (the armature, the skinned
        mannequin and the baked dance through Blender's exporter, :mod:`dancekit.export.fbx`; needs
        ``blender``). Default :data:`DEFAULT_FORMATS`.
    audio : AudioClip, path-like or None
        The song slice that plays with the dance in the mp4 and html (a plain path: the
        song from 0 s); None: silent.
    options : RenderOptions or None
        Size, camera, quality and page title of the mp4 and html (None: the defaults;
        the html title defaults to ``stem``).
    progress : bool
        Show a progress bar while the mp4 renders.
    bvh_rig : {"exact", "humanoid"}
        The rig of the BVH and the FBX: the skeleton's own joints (default) or the standard humanoid rig
        (Mixamo-like names, :func:`dancekit.motion.formats.bvh.humanoid_motion`).

    Returns
    -------
    list of Path
        The written paths in ``folder``, in the order of ``formats``: ``{stem}.mp4``,
        ``{stem}.html``, ``{stem}.npz``, ``{stem}.bvh``, ``{stem}_openpose/``, ``{stem}.glb``, ``{stem}.pkl``, ``{stem}_coco17/``, ``{stem}_coco18/``, ``{stem}.fbx``.

    Raises
    ------
    ParameterError
        On an unknown format, a bad ``stem``, ``audio`` or ``options``.
    DancekitError
        If ``folder`` cannot be created or written, and every error of the writers
        (:class:`~dancekit.errors.AudioError`, :class:`~dancekit.errors.ExternalToolError`,
        :class:`~dancekit.errors.MotionFormatError`, ...).

    Examples
    --------
    >>> from dancekit.render import AudioClip, RenderOptions
    >>> export_motion(result.motion, "out", stem="song", formats=["mp4", "npz"],
    ...               audio=AudioClip("song.mp3", start=10.0),
    ...               options=RenderOptions(width=320, height=240))  # doctest: +SKIP
    [PosixPath('out/song.mp4'), PosixPath('out/song.npz')]
    """
    from dancekit.render import AudioClip, RenderOptions

    formats = check_formats(formats)
    if not isinstance(stem, str) or stem in ("", ".", "..") or any(c in stem for c in ("/", os.sep, "\0")):
        raise ParameterError(f"stem must be a file name without a folder, got {stem!r}")
    audio = AudioClip.of(audio)
    if bvh_rig not in ("exact", "humanoid"):
        raise ParameterError(f"bvh_rig must be 'exact' or 'humanoid', got {bvh_rig!r}")
    if options is None:
        options = RenderOptions()
    elif not isinstance(options, RenderOptions):
        raise ParameterError(f"options must be a RenderOptions or None, got {type(options).__name__}")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DancekitError(f"output path exists and is not a folder: {folder}")
    created = None if folder.exists() else _first_missing(folder)  # removed again on failure
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DancekitError(f"cannot create output folder {folder}: {exc.strerror}") from exc
    placed: list[tuple[Path, Path | None]] = []  # (target, where the file it replaced waits)
    stage = None
    try:
        try:
            stage = Path(tempfile.mkdtemp(prefix=_STAGE_PREFIX, dir=folder))
        except OSError as exc:
            raise DancekitError(f"output folder is not writable: {folder} ({exc.strerror})") from exc
        new, old = stage / "new", stage / "old"
        new.mkdir()
        old.mkdir()
        written = [_write(fmt, motion, new, stem, audio, options, progress, bvh_rig) for fmt in formats]
        final = []
        for path in written:
            target = folder / path.name
            backup = old / path.name if _exists(target) else None
            placed.append((target, backup))
            if backup is not None:
                os.replace(target, backup)
            os.replace(path, target)
            final.append(target)
    except BaseException:
        _roll_back(placed)
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        if created is not None:
            shutil.rmtree(created, ignore_errors=True)
        raise
    shutil.rmtree(stage, ignore_errors=True)  # the replaced files
    return final


def _write(fmt: str, motion, folder: Path, stem: str, audio, options, progress: bool, bvh_rig: str) -> Path:
    """Write ``motion`` as ``fmt`` into ``folder``; returns the path."""
    from dancekit import render  # looked up per call (tests replace the writers)
    from dancekit.motion.formats import write_motion

    if fmt in ("npz", "glb", "pkl"):
        path = folder / f"{stem}.{fmt}"
        write_motion(path, motion)
    elif fmt == "bvh":
        path = folder / f"{stem}.bvh"
        write_motion(path, motion, rig=bvh_rig)
    elif fmt == "fbx":
        from dancekit.export.fbx import write_fbx

        path = folder / f"{stem}.fbx"
        write_fbx(path, motion, rig=bvh_rig)
    elif fmt in ("openpose", "coco17", "coco18"):
        from dancekit.motion.formats.openpose import write_openpose

        path = folder / f"{stem}_{fmt}"
        write_openpose(path, motion, keypoints="body25" if fmt == "openpose" else fmt)
    elif fmt == "mp4":
        path = folder / f"{stem}.mp4"
        render.render_motion_mp4(path, motion, audio=audio, options=options, progress=progress)
    elif fmt == "html":
        path = folder / f"{stem}.html"
        render.render_motion_html(path, motion, audio=audio, options=options)
    else:  # pragma: no cover - check_formats guards this
        raise AssertionError(fmt)
    return path


def _first_missing(folder: Path) -> Path:
    """The outermost missing folder on the way to ``folder`` (``folder`` itself if only it is missing)."""
    folder = Path(os.path.abspath(folder))
    while not folder.parent.exists() and folder.parent != folder:
        folder = folder.parent
    return folder


def _exists(path: Path) -> bool:
    return path.exists() or path.is_symlink()


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif _exists(path):
        path.unlink()


def _roll_back(placed: list[tuple[Path, Path | None]]) -> None:
    """Undo the moves into place: remove what was moved in, put back what it replaced."""
    for target, backup in reversed(placed):
        if backup is not None and not _exists(backup):
            continue  # the old file was never moved away
        with contextlib.suppress(OSError):
            _remove(target)
            if backup is not None:
                os.replace(backup, target)
