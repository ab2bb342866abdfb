"""FBX output through Blender's own exporter (``--format fbx``), and FBX joints read back through Blender.

:func:`write_fbx` writes the dance as a ``.glb`` (:func:`dancekit.motion.formats.gltf.write_glb`: the rig,
the skinned mannequin and the animation) into a temporary folder, then runs headless Blender on
:mod:`dancekit.export.blender_fbx` (``blender -b --factory-startup --python blender_fbx.py -- export ...``),
which imports the glb and exports an FBX 7.4 binary: the armature (the skeleton's rig, or the standard
humanoid rig of :func:`dancekit.motion.formats.bvh.humanoid_motion`), the mannequin skinned to it and the
whole dance baked at every frame at the motion's frame rate (30 or 60 fps after ``--fps``). Blender's
units: metres in the scene, FBX's centimetres in the file (``apply_unit_scale``), y up, -z forward.

Blender comes from ``$DANCEKIT_BLENDER`` or ``blender`` on PATH (Debian / Ubuntu: ``apt-get install blender
python3-numpy``; Blender's glTF importer needs NumPy). Without it the error is one line naming that.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import ExternalToolError, MotionFormatError, ParameterError
from dancekit.motion import Motion

SCRIPT = Path(__file__).with_name("blender_fbx.py")
INSTALL_HINT = ("install Blender (Debian / Ubuntu: apt-get install blender python3-numpy; elsewhere "
                "https://www.blender.org/download/) and put `blender` on PATH, or set DANCEKIT_BLENDER to it")
TIMEOUT_S = 1800


def find_blender() -> str | None:
    """The Blender executable: ``$DANCEKIT_BLENDER``, else ``blender`` on PATH; None when there is none."""
    env = os.environ.get("DANCEKIT_BLENDER")
    if env:
        return shutil.which(env)
    return shutil.which("blender")


def require_blender() -> str:
    """:func:`find_blender`, or :class:`ExternalToolError` (one line naming what to install)."""
    exe = find_blender()
    if exe is None:
        where = f"DANCEKIT_BLENDER={os.environ['DANCEKIT_BLENDER']!r} is not" if os.environ.get(
            "DANCEKIT_BLENDER") else "no `blender` on PATH; it is"
        raise ExternalToolError(f"--format fbx needs Blender ({where} an executable): {INSTALL_HINT}")
    return exe


def _run_blender(args: list[str], what: str) -> None:
    """Run the job ``args`` of :mod:`~dancekit.export.blender_fbx` in headless Blender, output captured."""
    exe = require_blender()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    cmd = [exe, "-b", "--factory-startup", "--python-exit-code", "3", "--python", str(SCRIPT), "--", *args]
    try:
        subprocess.run(cmd, check=True, capture_output=True, text=True, errors="replace", env=env,
                       timeout=TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.CalledProcessError as exc:
        out = f"{exc.stdout or ''}\n{exc.stderr or ''}"
        if "No module named 'numpy'" in out:
            raise ExternalToolError(f"Blender could not {what}: its Python has no NumPy, which its glTF importer "
                                    "needs (Debian / Ubuntu: apt-get install python3-numpy)") from None
        lines = [x.strip() for x in out.splitlines() if x.strip()]
        errs = [x for x in lines if x.startswith(("Error", "RuntimeError", "ValueError", "Exception"))
                or "Error:" in x]
        last = (errs or lines or ["no output"])[-1][:300]
        full = f"\n{out}" if os.environ.get("DANCEKIT_DEBUG") == "1" else ""
        raise ExternalToolError(f"Blender ({exe}) could not {what} (exit {exc.returncode}): {last}; "
                                f"run the same command with DANCEKIT_DEBUG=1 for its full output{full}") from exc
    except subprocess.TimeoutExpired:
        raise ExternalToolError(f"Blender ({exe}) did not {what} within {TIMEOUT_S} s") from None
    except OSError as exc:
        raise ExternalToolError(f"cannot run Blender ({exe}): {exc.strerror}") from exc


def write_fbx(path: str | os.PathLike, motion: Motion, *, rig: str = "exact") -> None:
    """Write a 3D motion as FBX through Blender (atomically): armature, skinned mannequin, baked animation.

    ``rig="humanoid"``: the standard humanoid rig (Mixamo-like names, T-pose rest) instead of the
    skeleton's own joints. The animation has one key per frame of ``motion`` at ``motion.fps``.

    Raises
    ------
    ExternalToolError
        Without Blender (one line naming what to install), or when Blender fails.
    MotionFormatError
        For a 2D motion.
    ParameterError
        For an unknown ``rig``.
    """
    from dancekit.motion.formats.bvh import humanoid_motion
    from dancekit.motion.formats.gltf import write_glb

    path = Path(path)
    if rig not in ("exact", "humanoid"):
        raise ParameterError(f"rig must be 'exact' or 'humanoid', got {rig!r}")
    if motion.skeleton.dims != 3:
        raise MotionFormatError(f"cannot write a 2D motion ({motion.skeleton.name!r}) as FBX: {path}")
    require_blender()
    fps = Fraction(float(motion.fps)).limit_denominator(1001)
    with tempfile.TemporaryDirectory(prefix="dancekit-fbx-") as tmp:
        glb, out = Path(tmp) / "dance.glb", Path(tmp) / "dance.fbx"
        write_glb(glb, humanoid_motion(motion) if rig == "humanoid" else motion)
        _run_blender(["export", str(glb), str(out), str(fps.numerator), str(fps.denominator)], f"write {path}")
        if not out.is_file():
            raise ExternalToolError(f"Blender wrote no FBX for {path}")
        with atomic_path(path, suffix=".fbx") as dst:
            shutil.move(out, dst)


def read_fbx_joints(path: str | os.PathLike) -> tuple[list[str], np.ndarray, float]:
    """The joints of an FBX's armature over its animation, read through Blender.

    Returns
    -------
    names : list of str
        The armature's bones (J).
    positions : ndarray, (T, J, 3)
        The world position of every bone's head at every frame, metres, y up (glTF's axes).
    fps : float
        The file's frame rate.

    Raises
    ------
    MotionFormatError
        For a missing file. :class:`ExternalToolError` without Blender or when it cannot read the file.
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFormatError(f"FBX file not found: {path}")
    with tempfile.TemporaryDirectory(prefix="dancekit-fbx-") as tmp:
        out = Path(tmp) / "joints.npz"
        _run_blender(["read", str(path.resolve()), str(out)], f"read {path}")
        with np.load(out) as z:
            return [str(n) for n in z["names"]], np.asarray(z["positions"], np.float64), float(z["fps"])
