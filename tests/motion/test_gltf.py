"""glTF 2.0 (.glb) output: re-read with pygltflib, node FK = the npz joints; the Khronos validator when installed."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch

from dancekit.errors import MotionFormatError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import read_motion, write_motion
from dancekit.motion.kinematics import rig_forward_kinematics
from dancekit.motion.rotations import axis_angle_to_matrix

pygltflib = pytest.importorskip("pygltflib")


def dance(skeleton_name: str = "tang2018", frames: int = 12, seed: int = 0, up: str | None = None) -> Motion:
    """Random rotations on the rig (bone lengths kept), so the positions are FK-consistent."""
    sk = get_skeleton(skeleton_name)
    if up is not None:
        sk = sk.replace(up_axis=up, name=f"{sk.name}_{up}")
    rng = np.random.default_rng(seed)
    J = sk.rig().num_joints
    rot = axis_angle_to_matrix(torch.from_numpy(rng.normal(scale=0.5, size=(frames, J, 3)))).numpy()
    tr = rng.normal(scale=20.0 * (1 if sk.units == "cm" else 0.01), size=(frames, 3)).cumsum(0)
    pos = rig_forward_kinematics(rot, tr, sk).numpy()
    return Motion(sk, 30.0, positions=pos.astype(np.float32), rotations=rot.astype(np.float32),
                  root_translation=tr.astype(np.float32))


def _accessor(gltf, blob: bytes, i: int) -> np.ndarray:
    acc = gltf.accessors[i]
    view = gltf.bufferViews[acc.bufferView]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}[acc.componentType]
    n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(blob, dtype=dtype, count=acc.count * n, offset=start).reshape(acc.count, n)


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = np.moveaxis(q.astype(np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def glb_joint_positions(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(node names, (T, N, 3) world positions of every node at the keyframes, key times) by FK of the nodes."""
    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    N = len(gltf.nodes)
    anim = gltf.animations[0]
    times = _accessor(gltf, blob, anim.samplers[0].input)[:, 0]
    T = len(times)
    rot = np.tile(np.eye(3), (T, N, 1, 1))
    trans = np.zeros((T, N, 3))
    for n, node in enumerate(gltf.nodes):
        if node.rotation is not None:
            rot[:, n] = _quat_to_matrix(np.asarray(node.rotation))
        if node.translation is not None:
            trans[:, n] = node.translation
    for ch in anim.channels:
        out = _accessor(gltf, blob, anim.samplers[ch.sampler].output).astype(np.float64)
        if ch.target.path == "rotation":
            rot[:, ch.target.node] = _quat_to_matrix(out)
        elif ch.target.path == "translation":
            trans[:, ch.target.node] = out
    parent = {c: n for n, node in enumerate(gltf.nodes) for c in (node.children or [])}
    G = np.zeros((T, N, 3, 3))
    P = np.zeros((T, N, 3))
    done: set[int] = set()

    def visit(n: int) -> None:
        if n in done:
            return
        p = parent.get(n)
        if p is None:
            G[:, n], P[:, n] = rot[:, n], trans[:, n]
        else:
            visit(p)
            G[:, n] = G[:, p] @ rot[:, n]
            P[:, n] = P[:, p] + np.einsum("tij,tj->ti", G[:, p], trans[:, n])
        done.add(n)

    for n in range(N):
        visit(n)
    return [node.name for node in gltf.nodes], P, times


@pytest.mark.parametrize("up", [None, "z"])
def test_glb_joints_equal_the_npz(tmp_path, up):
    m = dance(up=up)
    write_motion(tmp_path / "d.npz", m)
    write_motion(tmp_path / "d.glb", m)
    ref = read_motion(tmp_path / "d.npz")
    names, P, times = glb_joint_positions(tmp_path / "d.glb")
    sk = ref.skeleton
    assert np.allclose(times, np.arange(m.num_frames) / m.fps, atol=1e-6)
    idx = [names.index(n) for n in sk.joint_names]
    got = P[:, idx] / sk.unit_scale  # back to skeleton units
    if up == "z":  # glTF is y up: the file turns (x, y, z) into (x, z, -y)
        got = np.stack([got[..., 0], -got[..., 2], got[..., 1]], axis=-1)
    err = np.abs(got - ref.positions).max()
    print(f"glb vs npz max joint error ({up or 'y'} up): {err:.2e} {sk.units}")
    assert err < 1e-3
    rig_names = set(sk.rig().joint_names)
    assert rig_names <= set(names) and "body" in names


def test_glb_keeps_varying_bone_lengths(tmp_path):
    """Raw capture data: bones change length; translation channels keep every joint where the npz has it."""
    m = dance(frames=8, seed=3)
    rng = np.random.default_rng(5)
    pos = m.positions.astype(np.float64)
    pos = pos + rng.normal(scale=2.0, size=pos.shape)  # cm of marker noise
    raw = Motion(m.skeleton, m.fps, positions=pos.astype(np.float32))
    write_motion(tmp_path / "raw.npz", raw)
    write_motion(tmp_path / "raw.glb", raw)
    ref = read_motion(tmp_path / "raw.npz")
    names, P, _ = glb_joint_positions(tmp_path / "raw.glb")
    got = P[:, [names.index(n) for n in ref.skeleton.joint_names]] / ref.skeleton.unit_scale
    err = np.abs(got - ref.positions).max()
    print(f"glb vs npz with varying bone lengths: max joint error {err:.2e} cm")
    assert err < 1e-3


def test_glb_body_is_skinned_to_the_rig(tmp_path):
    m = dance(frames=3)
    write_motion(tmp_path / "d.glb", m)
    gltf = pygltflib.GLTF2().load(str(tmp_path / "d.glb"))
    blob = gltf.binary_blob()
    (skin,) = gltf.skins
    assert len(skin.joints) == m.skeleton.rig().num_joints
    prim = gltf.meshes[0].primitives[0]
    pos = _accessor(gltf, blob, prim.attributes.POSITION)
    joints = _accessor(gltf, blob, prim.attributes.JOINTS_0)
    weights = _accessor(gltf, blob, prim.attributes.WEIGHTS_0)
    assert len(pos) > 500 and np.allclose(weights.sum(1), 1.0)
    assert joints.max() < len(skin.joints)
    assert len(set(joints[:, 0].tolist())) >= 15  # limbs, torso and head follow their own joints
    height = pos[:, 1].max() - pos[:, 1].min()
    assert 1.2 < height < 2.5  # metres: a human-sized mannequin
    assert len(gltf.animations[0].channels) == m.skeleton.rig().num_joints + 1
    # bind pose: every joint's world matrix (static node TRS) times its inverse bind matrix is the identity
    ibm = _accessor(gltf, blob, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    parent = {c: n for n, node in enumerate(gltf.nodes) for c in (node.children or [])}

    def world(n: int) -> np.ndarray:
        node = gltf.nodes[n]
        M = np.eye(4)
        if node.rotation is not None:
            M[:3, :3] = _quat_to_matrix(np.asarray(node.rotation))
        if node.translation is not None:
            M[:3, 3] = node.translation
        return M if n not in parent else world(parent[n]) @ M

    for k, j in enumerate(skin.joints):
        assert np.allclose(world(j) @ ibm[k], np.eye(4), atol=1e-5), gltf.nodes[j].name


def test_glb_rejects_2d(tmp_path):
    m = dance(frames=2).project_2d()
    with pytest.raises(MotionFormatError, match="2D"):
        write_motion(tmp_path / "d.glb", m)


def _validator() -> tuple[str, str] | None:
    node = shutil.which("node")
    npm = shutil.which("npm")
    if node is None or npm is None:
        return None
    root = subprocess.run([npm, "root", "-g"], capture_output=True, text=True, timeout=120).stdout.strip()
    for base in (Path(root), Path.cwd() / "node_modules"):
        if (base / "gltf-validator" / "package.json").is_file():
            return node, str(base)
    return None


_VALIDATE_JS = """
const fs = require('fs');
const validator = require('gltf-validator');
const bytes = new Uint8Array(fs.readFileSync(process.argv[2]));
validator.validateBytes(bytes, {maxIssues: 100}).then(r => {
  process.stdout.write(JSON.stringify(r.issues));
}).catch(e => { console.error(e); process.exit(1); });
"""


@pytest.mark.parametrize("skeleton", ["tang2018", "smpl"])
def test_glb_passes_the_khronos_validator(tmp_path, skeleton):
    found = _validator()
    if found is None:
        print("SKIPPED: gltf-validator (npm) not installed: npm install -g gltf-validator")
        pytest.skip("gltf-validator (npm) not installed")
    node, modules = found
    write_motion(tmp_path / "d.glb", dance(skeleton, frames=5))
    script = tmp_path / "validate.js"
    script.write_text(_VALIDATE_JS)
    res = subprocess.run([node, str(script), str(tmp_path / "d.glb")], capture_output=True, text=True,
                         env={"NODE_PATH": modules, "PATH": ""}, check=True, timeout=120)
    issues = json.loads(res.stdout)
    print(f"gltf-validator: {issues['numErrors']} errors, {issues['numWarnings']} warnings, "
          f"{issues['numInfos']} infos")
    assert issues["numErrors"] == 0, issues["messages"]
    assert issues["numWarnings"] == 0, issues["messages"]


def test_convert_cli_writes_glb(tmp_path, fixtures_dir, capsys):
    from dancekit.cli.main import main

    src = fixtures_dir / "bvh" / "pymo_walk.bvh"
    assert main(["convert", str(src), "-o", str(tmp_path / "walk.glb")]) == 0
    ref = read_motion(src)
    names, P, times = glb_joint_positions(tmp_path / "walk.glb")
    idx = [names.index(n) for n in ref.skeleton.joint_names]
    err = np.abs(P[:, idx] / ref.skeleton.unit_scale - ref.positions).max()
    print(f"pymo_walk.bvh -> glb max joint error: {err:.2e} {ref.skeleton.units}")
    assert err < 1e-3 and len(times) == ref.num_frames
    assert main(["convert", str(src), "-o", str(tmp_path / "walk.txt")]) == 2
    assert "output must end in" in capsys.readouterr().err
