"""glTF 2.0 binary (``.glb``): the rig as a node hierarchy, the dance as an animation, a skinned body.

:func:`write_glb` writes one self-contained ``.glb`` (written with ``pygltflib``):

- **nodes**: one per joint of the skeleton's rig (:meth:`Skeleton.rig`, so tang2018 keeps its
  zero-offset branch joints ``pelvis_to_*``), named after the joints, each with its rest offset
  as ``translation``; a z-up skeleton hangs under a node ``"y_up"`` that turns it to glTF's
  y up. Lengths are in **metres** (glTF's unit): skeleton units times ``skeleton.unit_scale``.
- **animation** ``"dance"``: a ``rotation`` channel per joint (the motion's local rotations as
  ``(x, y, z, w)`` quaternions) and a ``translation`` channel on the root, keyed at the frame
  times ``k / fps`` with ``LINEAR`` interpolation (slerp for rotations). When the motion's
  bone lengths vary (raw capture data), every joint whose bone changes length also gets a
  ``translation`` channel, so the nodes reproduce the stored positions exactly.
- **body**: a low-poly mannequin built here, skinned rigidly to the joints: one capsule per
  bone (attached to the joint that turns that bone), a torso from the pelvis to the neck and a
  head, so viewers (Blender, three.js, model-viewer) show a moving body rather than empty nodes.
  The bind pose is the rest pose (identity rotations, root at the origin).

Forward kinematics of the file's nodes gives the motion's joint positions (those of the npz).

:func:`read_glb` reads such a file back (and other glb files with one skin and one node animation): the
skin's joints with their parents and rest translations, the animation's rotation and translation keys, the
fps from the key times. A file with a tang2018 rig reads back as the tang2018 skeleton in centimetres; any
other rig is a skeleton named after the file, in metres, y up (z up under a ``y_up`` node).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, MotionFormatError
from dancekit.motion.formats._known import adopt_builtin, builtin_for
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import Skeleton

__all__ = ["body_mesh", "read_glb", "write_glb"]

_FLOAT, _USHORT, _UINT = 5126, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_SIDES = 10  # segments around a capsule
_RINGS = 3   # rings per hemispherical cap


def _rest_positions(rig: Skeleton) -> np.ndarray:
    """(J, 3) rest positions of the rig's joints, root at the origin."""
    out = np.zeros((rig.num_joints, 3))
    for j in rig.topological_order:
        p = rig.parents[j]
        if p >= 0:
            out[j] = out[p] + rig.offsets[j]
    return out


def _capsule(a: np.ndarray, b: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A capsule from ``a`` to ``b`` of radius ``r``: vertices (V, 3), normals (V, 3), triangles (F, 3)."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 1e-12 else np.array([0.0, 1.0, 0.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    # profile: (height along z from a, radius factor, normal z component), bottom pole to top pole
    prof = []
    for i in range(_RINGS + 1):  # bottom cap, from the pole
        t = -np.pi / 2 + (np.pi / 2) * i / _RINGS
        prof.append((r * np.sin(t), np.cos(t), np.sin(t)))
    for i in range(_RINGS + 1):  # top cap, up to the pole
        t = (np.pi / 2) * i / _RINGS
        prof.append((length + r * np.sin(t), np.cos(t), np.sin(t)))
    ang = 2 * np.pi * np.arange(_SIDES) / _SIDES
    verts, norms = [], []
    for h, rf, nz in prof:
        for t in ang:
            radial = np.cos(t) * x + np.sin(t) * y
            verts.append(a + z * h + r * rf * radial)
            n = rf * radial + nz * z
            norms.append(n / max(np.linalg.norm(n), 1e-12))
    faces = []
    for i in range(len(prof) - 1):
        for k in range(_SIDES):
            k1 = (k + 1) % _SIDES
            v00, v01 = i * _SIDES + k, i * _SIDES + k1
            v10, v11 = (i + 1) * _SIDES + k, (i + 1) * _SIDES + k1
            faces.append((v00, v01, v11))
            faces.append((v00, v11, v10))
    return np.asarray(verts), np.asarray(norms), np.asarray(faces, dtype=np.int64)


def body_mesh(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A rigidly skinned mannequin in the rest pose of ``skeleton.rig()`` (metres, root at the origin).

    One capsule per bone of non-zero length, attached to the rig joint whose rotation turns that
    bone (the bone's parent joint); a torso capsule from the pelvis to the neck (the shoulders'
    midpoint without a neck joint) attached to the pelvis (or the spine joint), and a head
    sphere on the head joint.

    Returns
    -------
    vertices : (V, 3) float64, normals : (V, 3) float64, faces : (F, 3) int64,
    joint : (V,) int64, the rig joint each vertex follows
    """
    rig = skeleton.rig()
    s = skeleton.unit_scale
    rest = _rest_positions(rig) * s
    top = rest[:, skeleton.up_index].max() - rest[:, skeleton.up_index].min()
    height = float(top) if top > 0 else 1.7
    k = height / 1.7  # radii scale with the figure
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]] = []

    def add(a, b, r, joint):
        v, n, f = _capsule(np.asarray(a, float), np.asarray(b, float), r)
        parts.append((v, n, f, joint))

    def role(name: str) -> int | None:
        return skeleton.index(name) if skeleton.has(name) else None

    thick = {"hip": 0.075, "knee": 0.06, "ankle": 0.045, "toe": 0.035, "heel": 0.03,
             "shoulder": 0.06, "elbow": 0.045, "wrist": 0.035}
    role_of = {skeleton.index(r): r for r in skeleton.roles if skeleton.has(r)}
    for c in range(rig.num_joints):
        p = rig.parents[c]
        if p < 0 or np.linalg.norm(rig.offsets[c]) * s < 1e-4:
            continue
        # the bone ending at c belongs to the body part one level up the chain (thigh: hip -> knee)
        part = role_of.get(p if p < skeleton.num_joints else rig.parents[p], "")
        r = thick.get(part.split("_", 1)[-1], 0.04) * k
        add(rest[p], rest[c], r, p)
    pelvis, spine, neck, head = role("pelvis"), role("spine"), role("neck"), role("head")
    ls, rs = role("left_shoulder"), role("right_shoulder")
    if pelvis is not None:
        if neck is not None:
            top_pt = rest[neck]
        elif ls is not None and rs is not None:
            top_pt = 0.5 * (rest[ls] + rest[rs])
        else:
            top_pt = None
        if top_pt is not None:
            add(rest[pelvis], top_pt, 0.12 * k, spine if spine is not None else pelvis)
    if head is not None:
        add(rest[head], rest[head], 0.1 * k, head)
    verts = np.concatenate([v for v, _, _, _ in parts])
    norms = np.concatenate([n for _, n, _, _ in parts])
    starts = np.cumsum([0] + [len(v) for v, _, _, _ in parts[:-1]])
    faces = np.concatenate([f + o for (_, _, f, _), o in zip(parts, starts)])
    joint = np.concatenate([np.full(len(v), j) for v, _, _, j in parts])
    return verts, norms, faces, joint


def _to_y_up(skeleton: Skeleton) -> np.ndarray:
    """3x3 rotation from the skeleton's frame to glTF's y-up frame."""
    if skeleton.up_axis == "z":
        return np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    return np.eye(3)


def _quat_xyzw(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) → (..., 4) (x, y, z, w), unit, float32, sign-continuous along the first axis."""
    import torch

    from dancekit.motion.rotations import matrix_to_quaternion

    q = matrix_to_quaternion(torch.from_numpy(np.asarray(R, np.float64))).numpy()
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    if q.ndim >= 2:  # no flips between frames, so LINEAR keys turn the short way
        for t in range(1, q.shape[0]):
            flip = np.sum(q[t] * q[t - 1], axis=-1) < 0
            q[t][flip] *= -1
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1).astype(np.float32)


def _stretched_bones(m: Motion) -> dict[int, np.ndarray]:
    """``{rig joint: (T, 3) local translation}`` for the joints whose stored positions leave their rest offset."""
    if m.positions is None:
        return {}
    rig = m.skeleton.rig()
    J = m.skeleton.num_joints
    R = np.asarray(m.rotations, np.float64)
    T = R.shape[0]
    G = np.zeros_like(R)
    P = np.zeros((T, rig.num_joints, 3))
    P[:, :J] = np.asarray(m.positions, np.float64)
    for j in rig.topological_order:
        p = rig.parents[j]
        G[:, j] = R[:, j] if p < 0 else G[:, p] @ R[:, j]
        if j >= J:  # a branch joint sits on its parent
            P[:, j] = P[:, p]
    scale = max(float(np.abs(rig.offsets).max()), 1e-9)
    out = {}
    for j in range(rig.num_joints):
        p = rig.parents[j]
        if p < 0:
            continue
        local = np.einsum("tji,tj->ti", G[:, p], P[:, j] - P[:, p])  # G_p^T (P_j - P_p)
        if np.abs(local - rig.offsets[j]).max() > 1e-6 * scale:
            out[j] = local
    return out


def write_glb(path: str | os.PathLike, motion: Motion) -> None:
    """Write a 3D motion as a glTF 2.0 binary (``.glb``) with a skinned body (atomically).

    See the module docstring for the layout. A motion with positions only gets rotations by
    inverse kinematics first (:meth:`Motion.with_rotations`).

    Raises
    ------
    MotionFormatError
        For a 2D motion, or if the rotations cannot be computed.
    """
    import pygltflib as g

    path = Path(path)
    sk = motion.skeleton
    if sk.dims != 3:
        raise MotionFormatError(f"cannot write a 2D motion ({sk.name!r}) as glTF: {path}")
    try:
        m = motion.with_rotations()
    except DancekitError as exc:
        raise MotionFormatError(f"cannot compute rotations for {path}: {exc}") from exc
    assert m.rotations is not None and m.root_translation is not None
    rig = sk.rig()
    J, T = rig.num_joints, m.num_frames
    s = sk.unit_scale
    C = _to_y_up(sk)
    z_up = not np.allclose(C, np.eye(3))

    blob = bytearray()
    views: list[g.BufferView] = []
    accessors: list[g.Accessor] = []

    def add(arr: np.ndarray, ctype: int, atype: str, target: int | None = None, minmax: bool = False) -> int:
        arr = np.ascontiguousarray(arr)
        while len(blob) % 4:
            blob.append(0)
        views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes, target=target))
        blob.extend(arr.tobytes())
        count = arr.shape[0]
        acc = g.Accessor(bufferView=len(views) - 1, componentType=ctype, count=count, type=atype)
        if minmax:
            flat = arr.reshape(count, -1)
            acc.min = [float(v) for v in flat.min(axis=0)]
            acc.max = [float(v) for v in flat.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    # nodes: the rig's joints (0..J-1), then the y-up wrapper (if any), then the body
    nodes = []
    for j in range(J):
        nodes.append(g.Node(name=rig.joint_names[j], translation=[float(v) for v in rig.offsets[j] * s],
                            children=[c for c in range(J) if rig.parents[c] == j]))
    nodes[rig.root].translation = [0.0, 0.0, 0.0]
    scene_roots = [rig.root]
    if z_up:
        q = _quat_xyzw(C)
        nodes.append(g.Node(name="y_up", rotation=[float(v) for v in q], children=[rig.root]))
        scene_roots = [J]

    # skin: bind pose = rest pose (identity rotations, root at the origin), in glTF world space
    rest = _rest_positions(rig) * s
    ibm = np.tile(np.eye(4, dtype=np.float64), (J, 1, 1))
    ibm[:, :3, :3] = C.T
    ibm[:, :3, 3] = -rest  # inverse of [C | C @ rest]: x -> C^T x - rest
    ibm_acc = add(np.transpose(ibm, (0, 2, 1)).astype(np.float32).reshape(J, 16), _FLOAT, "MAT4")  # column-major

    verts, norms, faces, joint = body_mesh(sk)
    verts = verts @ C.T
    norms = norms @ C.T
    V = len(verts)
    pos_acc = add(verts.astype(np.float32), _FLOAT, "VEC3", _ARRAY_BUFFER, minmax=True)
    nrm_acc = add(norms.astype(np.float32), _FLOAT, "VEC3", _ARRAY_BUFFER)
    joints = np.zeros((V, 4), np.uint16)
    joints[:, 0] = joint
    weights = np.zeros((V, 4), np.float32)
    weights[:, 0] = 1.0
    jnt_acc = add(joints, _USHORT, "VEC4", _ARRAY_BUFFER)
    wgt_acc = add(weights, _FLOAT, "VEC4", _ARRAY_BUFFER)
    idx_type = _USHORT if V < 65535 else _UINT
    idx_acc = add(faces.reshape(-1).astype(np.uint16 if idx_type == _USHORT else np.uint32), idx_type, "SCALAR",
                  _ELEMENT_ARRAY_BUFFER, minmax=True)
    accessors[idx_acc].min = [int(accessors[idx_acc].min[0])]
    accessors[idx_acc].max = [int(accessors[idx_acc].max[0])]
    mesh = g.Mesh(name="body", primitives=[g.Primitive(
        attributes=g.Attributes(POSITION=pos_acc, NORMAL=nrm_acc, JOINTS_0=jnt_acc, WEIGHTS_0=wgt_acc),
        indices=idx_acc, material=0)])
    body_node = len(nodes)
    nodes.append(g.Node(name="body", mesh=0, skin=0))
    scene_roots.append(body_node)

    # animation: rotations of every rig joint, translation of the root, at k / fps
    times = (np.arange(T) / m.fps).astype(np.float32)
    t_acc = add(times, _FLOAT, "SCALAR", minmax=True)
    quats = _quat_xyzw(np.asarray(m.rotations, np.float64))  # (T, J, 4)
    samplers, channels = [], []
    for j in range(J):
        out = add(np.ascontiguousarray(quats[:, j]), _FLOAT, "VEC4")
        samplers.append(g.AnimationSampler(input=t_acc, output=out, interpolation="LINEAR"))
        channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                           target=g.AnimationChannelTarget(node=j, path="rotation")))
    for j, local in _stretched_bones(m).items():
        samplers.append(g.AnimationSampler(input=t_acc, output=add((local * s).astype(np.float32), _FLOAT, "VEC3"),
                                           interpolation="LINEAR"))
        channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                           target=g.AnimationChannelTarget(node=j, path="translation")))
    tr = np.asarray(m.root_translation, np.float64) * s
    samplers.append(g.AnimationSampler(input=t_acc, output=add(tr.astype(np.float32), _FLOAT, "VEC3"),
                                       interpolation="LINEAR"))
    channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                       target=g.AnimationChannelTarget(node=rig.root, path="translation")))

    gltf = g.GLTF2(
        asset=g.Asset(version="2.0", generator="dancekit"),
        scene=0,
        scenes=[g.Scene(name=sk.name, nodes=scene_roots)],
        nodes=nodes,
        meshes=[mesh],
        skins=[g.Skin(name=f"{sk.name}_rig", joints=list(range(J)), inverseBindMatrices=ibm_acc,
                      skeleton=None if z_up else rig.root)],
        materials=[g.Material(name="mannequin", doubleSided=False, pbrMetallicRoughness=g.PbrMetallicRoughness(
            baseColorFactor=[0.8, 0.55, 0.4, 1.0], metallicFactor=0.0, roughnessFactor=0.7))],
        animations=[g.Animation(name="dance", samplers=samplers, channels=channels)],
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    gltf.set_binary_blob(bytes(blob))
    with atomic_path(path, suffix=".glb") as tmp:
        gltf.save_binary(str(tmp))


# ------------------------------------------------------------------ reading
_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def _accessor(gltf, blob: bytes, index: int) -> np.ndarray:
    """The array of accessor ``index`` (count, width), float64 (normalised integers are not used here)."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    dtype = np.dtype(_COMPONENTS[acc.componentType])
    width = _WIDTH[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    stride = view.byteStride or dtype.itemsize * width
    raw = np.frombuffer(blob, np.uint8, count=stride * (acc.count - 1) + dtype.itemsize * width, offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, (acc.count, dtype.itemsize * width), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(acc.count, width).astype(np.float64)


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) (x, y, z, w) quaternions (normalised here) → (..., 3, 3) rotation matrices."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
    ], axis=-1).reshape(q.shape[:-1] + (3, 3))


def read_glb(path: str | os.PathLike) -> Motion:
    """Read the dance of a glTF 2.0 binary (``.glb``): its skin's joints and its first animation.

    Returns a :class:`Motion` with rotations (on the rig, ``(T, J_rig, 3, 3)``), root translation and
    positions at ``fps = 1 / (t1 - t0)`` of the animation's keys (rounded to an integer within 0.1 %). A
    tang2018 rig (as :func:`write_glb` writes it) reads back as the built-in ``tang2018`` skeleton in its
    units (cm); another rig keeps the file's joint names, roles guessed from them
    (:func:`~dancekit.motion.formats.bvh.guess_roles`), metres, and z up when its root hangs under a node
    ``y_up`` (as :func:`write_glb` writes a z-up skeleton), else y up.

    Raises
    ------
    MotionFormatError
        If the file is not a glb, has no skin or no animation, or its keys are not evenly spaced (names the
        file).
    """
    import pygltflib as g

    path = Path(path)
    try:
        gltf = g.GLTF2().load_binary(str(path))
        blob = gltf.binary_blob()
    except Exception as exc:  # pygltflib raises several kinds for a file that is not a glb
        raise MotionFormatError(f"cannot read glb {path}: not a glTF 2.0 binary ({type(exc).__name__})") from None
    if gltf is None or blob is None:
        raise MotionFormatError(f"cannot read glb {path}: not a glTF 2.0 binary")
    if not gltf.skins or not gltf.animations:
        raise MotionFormatError(f"{path}: a glb without a skin and an animation holds no dance")
    joints = list(gltf.skins[0].joints)
    index = {n: j for j, n in enumerate(joints)}
    parent_of = {c: p for p, node in enumerate(gltf.nodes) for c in (node.children or [])}
    parents = [index.get(parent_of.get(n, -1), -1) for n in joints]
    if parents.count(-1) != 1:
        raise MotionFormatError(f"{path}: the skin's joints form {parents.count(-1)} trees, not one")
    names = [gltf.nodes[n].name or f"joint{j}" for j, n in enumerate(joints)]
    offsets = np.array([gltf.nodes[n].translation or [0.0, 0.0, 0.0] for n in joints], np.float64)
    root = parents.index(-1)
    z_up = gltf.nodes[parent_of[joints[root]]].name == "y_up" if joints[root] in parent_of else False

    anim = gltf.animations[0]
    times, rot_keys, trans_keys = None, {}, {}
    for ch in anim.channels:
        if ch.target.node not in index or ch.target.path not in ("rotation", "translation"):
            continue
        sampler = anim.samplers[ch.sampler]
        t = _accessor(gltf, blob, sampler.input)[:, 0]
        if times is None:
            times = t
        elif len(t) != len(times) or np.abs(t - times).max() > 1e-4:
            raise MotionFormatError(f"{path}: the animation's channels are keyed at different times")
        values = _accessor(gltf, blob, sampler.output)
        (rot_keys if ch.target.path == "rotation" else trans_keys)[index[ch.target.node]] = values
    if times is None or len(times) < 1:
        raise MotionFormatError(f"{path}: the animation has no keys on the skin's joints")
    T = len(times)
    if T > 1:
        steps = np.diff(times)
        if steps.min() <= 0 or (steps.max() - steps.min()) > 1e-3 * steps.mean():
            raise MotionFormatError(f"{path}: the animation's keys are not evenly spaced in time")
        fps = 1.0 / float(np.mean(steps))
        if abs(fps - round(fps)) < 1e-3 * fps:
            fps = float(round(fps))
    else:
        fps = 30.0

    J = len(joints)
    rest_q = np.array([gltf.nodes[n].rotation or [0.0, 0.0, 0.0, 1.0] for n in joints], np.float64)
    quats = np.broadcast_to(rest_q, (T, J, 4)).copy()
    for j, v in rot_keys.items():
        quats[:, j] = v
    rot = _quat_to_matrix(quats)
    trans = np.broadcast_to(offsets, (T, J, 3)).copy()
    for j, v in trans_keys.items():
        trans[:, j] = v

    from dancekit.motion.formats.bvh import find_branch_joints, fk_translations, guess_roles

    positions = fk_translations(rot, trans, parents)
    animated = np.array([j in trans_keys and j != root for j in range(J)])
    branches = find_branch_joints(names, parents, offsets, animated)
    drop = {b for bs in branches.values() for b in bs}
    keep = [j for j in range(J) if j not in drop]
    remap = {old: new for new, old in enumerate(keep)}
    kept_parents = [-1 if parents[j] < 0 else remap[parents[parents[j]] if parents[j] in drop else parents[j]]
                    for j in keep]
    kept_names = [names[j] for j in keep]
    known = builtin_for(kept_names, kept_parents)
    try:
        if known is not None:
            unit = 1.0 / known[0].unit_scale  # metres → the skeleton's units
            skeleton, order = adopt_builtin(kept_names, kept_parents, offsets[keep] * unit)
            keep = [keep[i] for i in order]
        else:
            roles, pairs = guess_roles(kept_names, kept_parents)
            unit = 1.0
            skeleton = Skeleton(name=path.stem, joint_names=tuple(kept_names), parents=tuple(kept_parents),
                                offsets=offsets[keep], up_axis="z" if z_up else "y", units="m", roles=roles,
                                left_right=pairs, branch_joints=tuple(names[p] for p in sorted(branches)))
        rig_order = [names.index(n) for n in skeleton.rig().joint_names]
        if sorted(rig_order) != list(range(J)):
            raise MotionFormatError(f"{path}: the skin's joints do not form the rig of {skeleton.name!r}")
        return Motion(skeleton=skeleton, fps=fps, positions=positions[:, keep] * unit, rotations=rot[:, rig_order],
                      root_translation=trans[:, root] * unit)
    except MotionFormatError:
        raise
    except DancekitError as exc:
        raise MotionFormatError(f"{path}: {exc}") from exc
