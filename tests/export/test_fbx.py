"""``--format fbx``: written through Blender's exporter, imported back into Blender, joints compared with the npz.

The round trip needs ``blender`` (Debian's package, with python3-numpy for its glTF importer): on CI
(``CI=true``, as ``.ci/run`` sets) a missing Blender fails these tests; elsewhere they skip, saying why.
Without Blender, ``--format fbx`` must fail in one line naming what to install (tested everywhere).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancekit.errors import ExternalToolError
from dancekit.export import export_motion
from dancekit.export.fbx import find_blender, read_fbx_joints, write_fbx
from dancekit.motion.formats import read_motion
from dancekit.motion.formats.bvh import humanoid_motion

ROOT = Path(__file__).resolve().parents[2]
TOL_CM = 0.5  # the acceptance bound: every joint of every frame within 0.5 cm of the npz


@pytest.fixture(scope="module")
def blender() -> str:
    exe = find_blender()
    if exe is None:
        why = "blender not found on PATH (apt-get install blender python3-numpy): the FBX round trip cannot run"
        if os.environ.get("CI", "").strip().lower() in ("true", "1", "yes"):
            pytest.fail(f"{why}, but CI=true")
        pytest.skip(why)
    return exe


def _song(path: Path, seconds: float = 6.0) -> Path:
    sr = 22050
    t = np.arange(int(sr * seconds)) / sr
    beat = (np.mod(t, 0.5) < 0.05) * np.sin(2 * np.pi * 880 * t)  # a click every 0.5 s over a chord
    chord = sum(np.sin(2 * np.pi * f * t) for f in (220, 277, 330)) / 3
    sf.write(path, (0.4 * beat + 0.2 * chord).astype(np.float32), sr)
    return path


def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run([sys.executable, "-m", "dancekit.cli.main", *args], env=env, capture_output=True,
                          text=True, timeout=900)


def _joint_error_cm(fbx: Path, motion) -> tuple[float, float]:
    """Max distance in cm, over every frame and joint, between the FBX's bone heads read back by Blender
    and the joints of ``motion`` (a y-up skeleton); and the FBX's frame rate."""
    assert motion.skeleton.up_axis == "y"
    bones, P, fps = read_fbx_joints(fbx)  # metres, y up
    names = motion.skeleton.joint_names
    got = P[:, [bones.index(n) for n in names]]
    want = np.asarray(motion.positions, np.float64) * motion.skeleton.unit_scale  # skeleton units -> metres
    assert got.shape == want.shape, (got.shape, want.shape)  # every frame of the dance, every joint
    return 100.0 * float(np.linalg.norm(got - want, axis=-1).max()), fps


@pytest.fixture(scope="module")
def danced(tmp_path_factory, blender) -> Path:
    """``dancekit dance`` of a 6 s song at 30 fps, written as npz and fbx."""
    tmp = tmp_path_factory.mktemp("fbx")
    song = _song(tmp / "song.wav")
    p = _cli("dance", str(song), "-o", str(tmp / "out"), "--format", "npz,fbx", "--fps", "30", "--quiet")
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""  # Blender's output kept off the user's terminal
    return tmp / "out"


@pytest.mark.slow
def test_dance_fbx_joints_match_the_npz(danced):
    m = read_motion(danced / "song.npz")
    assert m.fps == 30 and m.num_frames > 150
    err, fps = _joint_error_cm(danced / "song.fbx", m)
    assert fps == 30
    assert err < TOL_CM, f"FBX joints {err:.4f} cm from the npz"


@pytest.mark.slow
@pytest.mark.parametrize("rig", ["exact", "humanoid"])
def test_fbx_at_60_fps_and_on_the_humanoid_rig(danced, tmp_path, rig):
    m = read_motion(danced / "song.npz").resample(60.0)
    assert m.fps == 60
    write_fbx(tmp_path / "d.fbx", m, rig=rig)
    ref = humanoid_motion(m) if rig == "humanoid" else m
    err, fps = _joint_error_cm(tmp_path / "d.fbx", ref)
    assert fps == 60
    assert err < TOL_CM, f"{rig} FBX joints {err:.4f} cm from the motion"
    if rig == "humanoid":
        assert "Hips" in ref.skeleton.joint_names and "LeftUpLeg" in ref.skeleton.joint_names


def test_without_blender_the_error_is_one_line(tmp_path, monkeypatch, capsys):
    from dancekit.cli.main import main

    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.delenv("DANCEKIT_BLENDER", raising=False)
    song = _song(tmp_path / "song.wav", 2.0)
    assert main(["dance", str(song), "-o", str(tmp_path / "out"), "--format", "npz,fbx"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "--format fbx needs Blender" in lines[0] and "apt-get install blender" in lines[0]
    assert not (tmp_path / "out").exists()  # refused before the dance


def test_a_failing_blender_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    fake = tmp_path / "blender"
    fake.write_text("#!/bin/sh\necho 'Blender 9.9 (fake)'\necho 'lots of noise' >&2\n"
                    "echo 'RuntimeError: Error: cannot export'\nexit 3\n")
    fake.chmod(0o755)
    monkeypatch.setenv("DANCEKIT_BLENDER", str(fake))
    m = read_motion(_tiny_npz(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ExternalToolError, match=r"could not write .*d\.fbx \(exit 3\): RuntimeError: Error: cannot") \
            as e:
        export_motion(m, out, stem="d", formats=["npz", "fbx"])
    assert "\n" not in str(e.value)
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]  # no npz, no staging folder


def _tiny_npz(tmp_path: Path) -> Path:
    from dancekit.motion import Motion
    from dancekit.motion.formats import write_motion
    from dancekit.motion.skeleton import get_skeleton

    sk = get_skeleton("tang2018")
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + np.asarray(sk.offsets[j])
    rng = np.random.default_rng(0)
    pos = rest[None] + rng.normal(0, 1, (5, sk.num_joints, 3))
    path = tmp_path / "tiny.npz"
    write_motion(path, Motion(sk, 30.0, positions=pos.astype(np.float32)))
    return path
