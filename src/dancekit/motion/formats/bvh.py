"""BVH (Biovision hierarchy) reading and writing.

Two levels:

- :func:`parse_bvh` / :func:`format_bvh` work on :class:`BvhData`, the file as
  it is (any hierarchy, any channel order per joint, position channels on any
  joint, End Sites); ``format_bvh(parse_bvh(f))`` reproduces the channel values
  to 1e-6.
- :func:`read_bvh` / :func:`write_bvh` convert to and from a :class:`Motion`.
  :func:`write_bvh` writes the skeleton's rig (:meth:`Skeleton.rig`: tang2018
  gets five zero-offset joints ``pelvis_to_<child>`` between the pelvis and
  its children, each with its own rotation); :func:`read_bvh` folds such
  branch joints back into ``Skeleton.branch_joints``, so a written motion
  reads back with the same joints and rotations.

Conventions: rotation channels are intrinsic Euler angles in degrees, applied
in the order they are listed (``CHANNELS 3 Zrotation Xrotation Yrotation`` →
``R = Rz @ Rx @ Ry``, see :mod:`dancekit.motion.rotations`). Position channels
give the joint's local translation and *replace* its OFFSET (as Blender's
importer reads them).

Scale for Blender: BVH has no unit. :func:`write_bvh` writes the skeleton's
units (tang2018: centimetres), so in Blender's BVH importer set *Scale* to
0.01 for cm (1.0 for m) and *Forward*/*Up* to match the skeleton (tang2018:
-Z forward is not needed; leave Y up).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, MotionFormatError, ParameterError
from dancekit.motion.formats._known import adopt_builtin
from dancekit.motion.motion import Motion
from dancekit.motion.skeleton import Skeleton, branch_joint_name

__all__ = ["BVH_RIGS", "HUMANOID_NAMES", "BvhData", "format_bvh", "guess_roles", "humanoid_motion", "parse_bvh",
           "read_bvh", "write_bvh"]

_ROT = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
_POS = {"Xposition": 0, "Yposition": 1, "Zposition": 2}


@dataclass
class BvhData:
    """A BVH file as written: hierarchy, channels and per-frame channel values.

    Attributes
    ----------
    names : list of str, length J (joints in file order; End Sites are not joints)
    parents : list of int, -1 for the root
    offsets : np.ndarray (J, 3) float64
    channels : list of tuple of str (per joint, e.g. ``("Zrotation", "Xrotation", "Yrotation")``)
    end_sites : dict joint index -> list of (3,) offsets of its End Sites
    frame_time : float, seconds
    values : np.ndarray (T, C) float64, C = total number of channels, in file order
    """

    names: list[str]
    parents: list[int]
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    end_sites: dict[int, list[np.ndarray]] = field(default_factory=dict)
    frame_time: float = 1 / 30
    values: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def channel_offsets(self) -> list[int]:
        """Column of each joint's first channel in ``values``."""
        out, c = [], 0
        for ch in self.channels:
            out.append(c)
            c += len(ch)
        return out


# ---------------------------------------------------------------------- parse
def parse_bvh(path: str | os.PathLike) -> BvhData:
    """Parse a BVH file.

    Raises
    ------
    MotionFormatError
        If the file is missing or malformed: no HIERARCHY/MOTION section, a
        joint without OFFSET or CHANNELS, unknown channel names, unbalanced
        braces, a frame count that does not match the data, non-numeric or
        non-finite values (the message names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFormatError(f"BVH file not found: {path}")
    try:
        text = path.read_text(errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise MotionFormatError(f"cannot read BVH file {path}: {exc}") from exc

    def fail(msg: str) -> MotionFormatError:
        return MotionFormatError(f"{path}: {msg}")

    m = re.search(r"^\s*MOTION\s*$", text, flags=re.MULTILINE)
    if not text.lstrip().startswith("HIERARCHY"):
        raise fail("not a BVH file (no HIERARCHY at the start)")
    if m is None:
        raise fail("no MOTION section")
    tokens = text[: m.start()].split()[1:]
    pos = 0

    def take() -> str:
        nonlocal pos
        if pos >= len(tokens):
            raise fail("hierarchy ends unexpectedly")
        t = tokens[pos]
        pos += 1
        return t

    def floats(n: int, what: str) -> list[float]:
        out = []
        for _ in range(n):
            t = take()
            try:
                out.append(float(t))
            except ValueError:
                raise fail(f"bad number {t!r} in {what}") from None
        return out

    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_sites: dict[int, list[np.ndarray]] = {}

    def parse_joint(parent: int) -> None:
        name = take()
        if take() != "{":
            raise fail(f"expected '{{' after joint {name!r}")
        j = len(names)
        names.append(name)
        parents.append(parent)
        if take() != "OFFSET":
            raise fail(f"joint {name!r} has no OFFSET line")
        offsets.append(floats(3, f"OFFSET of {name!r}"))
        if pos >= len(tokens) or tokens[pos] != "CHANNELS":
            raise fail(f"joint {name!r} has no CHANNELS line")
        take()
        try:
            n = int(take())
        except ValueError:
            raise fail(f"bad channel count for joint {name!r}") from None
        chans = tuple(take() for _ in range(n))
        for c in chans:
            if c not in _ROT and c not in _POS:
                raise fail(f"unknown channel {c!r} for joint {name!r}")
        channels.append(chans)
        while True:
            t = take()
            if t == "}":
                return
            if t == "JOINT":
                parse_joint(j)
            elif t == "End":
                if take() != "Site" or take() != "{" or take() != "OFFSET":
                    raise fail(f"malformed End Site under {name!r}")
                off = np.asarray(floats(3, f"End Site of {name!r}"))
                if take() != "}":
                    raise fail(f"malformed End Site under {name!r}")
                end_sites.setdefault(j, []).append(off)
            else:
                raise fail(f"unexpected token {t!r} in joint {name!r}")

    if take() != "ROOT":
        raise fail("hierarchy must start with ROOT")
    parse_joint(-1)
    if pos != len(tokens):
        raise fail(f"unexpected text after the hierarchy: {tokens[pos]!r}")

    rest = text[m.end():]
    mf = re.search(r"Frames:\s*(\S+)", rest)
    mt = re.search(r"Frame Time:\s*(\S+)", rest)
    if mf is None or mt is None:
        raise fail("MOTION section lacks 'Frames:' or 'Frame Time:'")
    try:
        n_frames = int(mf.group(1))
        frame_time = float(mt.group(1))
    except ValueError:
        raise fail("bad 'Frames:' or 'Frame Time:' value") from None
    if not (frame_time > 0 and math.isfinite(frame_time)):
        raise fail(f"Frame Time must be positive, got {frame_time}")
    data_text = rest[mt.end():]
    C = sum(len(c) for c in channels)
    try:
        flat = np.array(data_text.split(), dtype=np.float64)
    except ValueError:
        raise fail("non-numeric value in the MOTION data") from None
    if flat.size != n_frames * C:
        raise fail(f"MOTION data has {flat.size} values, expected {n_frames} frames x {C} channels (truncated?)")
    if not np.all(np.isfinite(flat)):
        raise fail("MOTION data contains NaN/inf")
    return BvhData(
        names=names,
        parents=parents,
        offsets=np.asarray(offsets, dtype=np.float64),
        channels=channels,
        end_sites=end_sites,
        frame_time=frame_time,
        values=flat.reshape(n_frames, C),
    )


def format_bvh(data: BvhData, path: str | os.PathLike) -> None:
    """Write a :class:`BvhData` to ``path`` (atomically; values with 6 decimals)."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(data.parents):
        children.setdefault(p, []).append(j)
    lines = ["HIERARCHY"]

    def fmt3(v) -> str:
        return " ".join(f"{float(x):.6f}" for x in v)

    def emit(j: int, depth: int) -> None:
        ind = "  " * depth
        kw = "ROOT" if data.parents[j] < 0 else "JOINT"
        lines.append(f"{ind}{kw} {data.names[j]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}  OFFSET {fmt3(data.offsets[j])}")
        lines.append(f"{ind}  CHANNELS {len(data.channels[j])} {' '.join(data.channels[j])}".rstrip())
        for c in children.get(j, []):
            emit(c, depth + 1)
        for off in data.end_sites.get(j, []):
            lines.append(f"{ind}  End Site")
            lines.append(f"{ind}  {{")
            lines.append(f"{ind}    OFFSET {fmt3(off)}")
            lines.append(f"{ind}  }}")
        lines.append(f"{ind}}}")

    roots = children.get(-1, [])
    assert len(roots) == 1
    emit(roots[0], 0)
    lines.append("MOTION")
    lines.append(f"Frames: {data.values.shape[0]}")
    lines.append(f"Frame Time: {data.frame_time:.8f}")
    values = np.asarray(data.values, dtype=np.float64)
    with atomic_path(path, suffix=".bvh") as tmp:
        with open(tmp, "w") as f:
            f.write("\n".join(lines) + "\n")
            for a in range(0, len(values), 1000):  # a thousand frames of text at a time, not the whole song's
                f.write("".join(" ".join(f"{v:.6f}" for v in row) + "\n" for row in values[a: a + 1000]))


# ------------------------------------------------------------------ to Motion
def _local_transforms(data: BvhData) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame local rotations (T, J, 3, 3) and translations (T, J, 3) from the channels."""
    T, J = data.values.shape[0], len(data.names)
    rot = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
    trans = np.broadcast_to(data.offsets, (T, J, 3)).copy()
    for j, (chans, c0) in enumerate(zip(data.channels, data.channel_offsets)):
        rot_cols = [c0 + i for i, c in enumerate(chans) if c in _ROT]
        order = "".join(_ROT[c] for c in chans if c in _ROT)
        for i, c in enumerate(chans):
            if c in _POS:
                trans[:, j, _POS[c]] = data.values[:, c0 + i]
        if not rot_cols:
            continue
        ang = np.deg2rad(data.values[:, rot_cols])
        R = _axis_matrix(order[0], ang[:, 0])
        for k in range(1, len(order)):  # intrinsic: R = R_a0 @ R_a1 @ R_a2, any number of axes
            R = R @ _axis_matrix(order[k], ang[:, k])
        rot[:, j] = R
    return rot, trans


def _axis_matrix(axis: str, angle: np.ndarray) -> np.ndarray:
    """(T,) radians about ``axis`` ("X", "Y" or "Z") → (T, 3, 3) rotation matrices (NumPy: reading a BVH
    needs no torch; the same matrices as :func:`dancekit.motion.rotations.euler_angles_to_matrix`)."""
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(angle), np.zeros_like(angle)
    if axis == "X":
        flat = (o, z, z, z, c, -s, z, s, c)
    elif axis == "Y":
        flat = (c, z, s, z, o, z, -s, z, c)
    else:
        flat = (c, -s, z, s, c, z, z, z, o)
    return np.stack(flat, axis=-1).reshape(angle.shape + (3, 3))


def _matrix_to_euler(m: np.ndarray, order: str) -> np.ndarray:
    """(..., 3, 3) rotation matrices → (..., 3) intrinsic Euler angles (radians) in ``order`` (e.g. "ZXY"):
    :func:`dancekit.motion.rotations.matrix_to_euler_angles` in NumPy (writing a BVH needs no torch), the
    same branch rules: the middle angle in [-π/2, π/2]; at gimbal lock the last angle is 0."""
    i, j, k = ("XYZ".index(a) for a in order)
    sign = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    sb = np.clip(sign * m[..., i, k], -1.0, 1.0)
    b = np.arcsin(sb)
    a = np.arctan2(-sign * m[..., j, k], m[..., k, k])
    c = np.arctan2(-sign * m[..., i, j], m[..., i, i])
    locked = np.abs(sb) > 1 - 1e-10
    if locked.any():
        a = np.where(locked, np.arctan2(sign * m[..., k, j], m[..., j, j]), a)
        c = np.where(locked, 0.0, c)
    return np.stack([a, b, c], axis=-1)


def fk_translations(rot: np.ndarray, trans: np.ndarray, parents: list[int]) -> np.ndarray:
    from dancekit.motion.skeleton import parents_first_order

    T, J = rot.shape[:2]
    G = np.zeros_like(rot)
    P = np.zeros((T, J, 3))
    for j in parents_first_order(tuple(parents)):
        p = parents[j]
        if p < 0:
            G[:, j] = rot[:, j]
            P[:, j] = trans[:, j]
        else:
            G[:, j] = G[:, p] @ rot[:, j]
            P[:, j] = P[:, p] + np.einsum("tij,tj->ti", G[:, p], trans[:, j])
    return P


def _split_side(name: str) -> tuple[str | None, str]:
    """('left'|'right'|None, the name without its side marker, lower case, alphanumerics only)."""
    base = name.split(":")[-1].split("|")[-1]
    low = base.lower()
    side = None
    m = re.search(r"[_.\s-](l|r|left|right)$", low)
    if m:
        side = "left" if m.group(1).startswith("l") else "right"
        rest = base[: m.start()]
    elif low.startswith("left") or low.startswith("right"):
        side = "left" if low.startswith("left") else "right"
        rest = base[len(side):]
    elif re.match(r"^[lLrR](?=[A-Z_])", base):
        side = "left" if base[0] in "lL" else "right"
        rest = base[1:]
    elif "left" in low or "right" in low:
        side = "left" if "left" in low else "right"
        rest = re.sub(side, "", low)
    else:
        rest = base
    return side, re.sub(r"[^a-z0-9]", "", rest.lower())


_PART_KEYS = {
    "shoulder": ("upperarm", "arm", "shldr", "humerus", "shoulder"),
    "elbow": ("forearm", "lowerarm", "elbow", "lowarm", "radius"),
    "wrist": ("hand", "wrist"),
    "hip": ("upleg", "upperleg", "thigh", "hip", "femur"),
    "knee": ("leg", "lowerleg", "knee", "shin", "calf", "lowleg", "tibia"),
    "ankle": ("foot", "ankle"),
    "toe": ("toebase", "toes", "toe", "toe0", "toesend"),
    "heel": ("heel",),
}
_CENTER_KEYS = {
    "pelvis": ("hips", "hip", "pelvis"),
    "spine": ("spine", "spine1", "chest", "torso", "spine0"),
    "neck": ("neck", "neck1"),
    "head": ("head",),
}


def guess_roles(joint_names: list[str] | tuple[str, ...], parents=None) -> tuple[dict[str, str], tuple]:
    """Guess canonical roles and left/right pairs from common joint names.

    Recognises Mixamo/CMU/Blender/Bandai-Namco style names: ``Hips``,
    ``Spine``, ``Neck``, ``Head``, ``LeftUpLeg``/``LHip``/``UpperLeg_L``,
    ``LeftLeg``/``LeftKnee``/``LowerLeg_L``, ``LeftFoot``/``LeftAnkle``,
    ``LeftToeBase``/``LeftToe``/``Toes_L``, ``LeftArm``/``LeftShoulder``/``UpperArm_L``
    (the clavicle ``LeftShoulder`` only when there is no ``LeftArm``),
    ``LeftForeArm``/``LeftElbow``, ``LeftHand``/``LeftWrist``, with prefixes
    such as ``mixamorig:``.

    Returns
    -------
    roles : dict role -> joint name
    left_right : tuple of (left name, right name) pairs whose names differ only by side
    """
    parsed = [(n, *_split_side(n)) for n in joint_names]
    roles: dict[str, str] = {}
    for role, keys in _CENTER_KEYS.items():
        for k in keys:
            hit = [n for n, s, part in parsed if s is None and part == k]
            if hit:
                roles[role] = hit[0]
                break
    if "pelvis" not in roles and parents is not None:
        roles["pelvis"] = joint_names[list(parents).index(-1)]
    for side in ("left", "right"):
        for part, keys in _PART_KEYS.items():
            for k in keys:
                hit = [n for n, s, p in parsed if s == side and p == k]
                if hit:
                    roles[f"{side}_{part}"] = hit[0]
                    break
    by_key = {(s, p): n for n, s, p in parsed if s is not None}
    pairs = tuple(
        (n, by_key[("right", p)]) for n, s, p in parsed if s == "left" and ("right", p) in by_key
    )
    return roles, pairs


def _guess_up(positions: np.ndarray, roles: dict[str, str], names: list[str]) -> str:
    idx = {n: i for i, n in enumerate(names)}
    mean = positions.reshape(-1, *positions.shape[-2:]).mean(axis=0)  # (J, 3)
    if "head" in roles and "left_ankle" in roles and "right_ankle" in roles:
        v = mean[idx[roles["head"]]] - 0.5 * (mean[idx[roles["left_ankle"]]] + mean[idx[roles["right_ankle"]]])
    else:
        ext = mean.max(0) - mean.min(0)
        v = np.eye(3)[int(np.argmax(ext))]
    ax = int(np.argmax(np.abs(v)))
    return "z" if ax == 2 else "y"


def read_bvh(path: str | os.PathLike, *, units: str | None = None) -> Motion:
    """Read a BVH file into a :class:`Motion` with rotations, root translation and positions.

    The skeleton is named after the file stem; its offsets are the OFFSET
    lines (End Sites are not joints), roles and mirror pairs are guessed from
    the joint names (:func:`guess_roles`), the up axis (y or z) from the
    average pose (head above the ankles, else the longest extent), and
    ``units`` is ``"m"`` when the figure is under 3 units tall, else ``"cm"``
    unless given. ``fps = 1 / Frame Time``, rounded to an integer when within
    0.1 % of one.

    Branch joints are folded: when every child of a joint ``p`` (at least
    two) is a zero-offset joint without position channels named
    ``"{p}_to_{c}"`` (:func:`~dancekit.motion.skeleton.branch_joint_name`)
    whose only child is ``c``, as :func:`write_bvh` writes the tang2018
    pelvis, those joints are dropped from ``joint_names`` and ``positions``,
    ``p`` is listed in ``skeleton.branch_joints``, and ``rotations`` keep
    them in the order of ``skeleton.rig()``. Forward kinematics is unchanged.

    Position channels on non-root joints are honoured in ``positions``. A
    static root (constant channels) with a single child whose translation is
    animated (as in the Bandai-Namco data set, ``joint_Root`` → ``Hips``) is
    folded into that child, which becomes the root. Other animated non-root
    translations cannot be expressed by rotations on fixed offsets: a warning
    is given and ``positions`` stay exact.

    Raises
    ------
    MotionFormatError
        If the file is missing or malformed (names the file).
    """
    path = Path(path)
    data = parse_bvh(path)
    if data.values.shape[0] == 0:
        raise MotionFormatError(f"{path}: no frames")
    rot, trans = _local_transforms(data)
    names, parents, offsets = list(data.names), list(data.parents), data.offsets.copy()
    root = parents.index(-1)
    scale = max(float(np.abs(offsets).max()), 1e-9)
    animated = np.abs(trans - offsets[None]).max(axis=0).max(axis=-1) > 1e-6 * scale  # (J,)
    animated[root] = False
    kids = [j for j, p in enumerate(parents) if p == root]
    root_static = np.ptp(data.values[:, data.channel_offsets[root]: data.channel_offsets[root] + len(data.channels[root])], axis=0).max(initial=0.0) < 1e-9
    if root_static and len(kids) == 1 and animated[kids[0]]:
        c = kids[0]
        rot_c = np.einsum("tij,tjk->tik", rot[:, root], rot[:, c])
        trans_c = trans[:, root] + np.einsum("tij,tj->ti", rot[:, root], trans[:, c])
        keep = [j for j in range(len(names)) if j != root]
        remap = {old: new for new, old in enumerate(keep)}
        new_parents = [-1 if j == c else remap[parents[j]] for j in keep]
        rot = rot[:, keep]
        rot[:, remap[c]] = rot_c
        trans = trans[:, keep]
        trans[:, remap[c]] = trans_c
        names = [names[j] for j in keep]
        offsets = offsets[keep]
        offsets[remap[c]] = 0.0
        animated = animated[keep]
        parents = new_parents
        root = remap[c]
        animated[root] = False
    if animated.any():
        warnings.warn(
            f"{path}: animated translations on non-root joints {[names[j] for j in np.flatnonzero(animated)]} "
            "are kept in positions only (rotations use the fixed offsets)",
            stacklevel=2,
        )
    positions = fk_translations(rot, trans, parents)
    # fold branch joints (p -> "p_to_c" -> c) back into Skeleton.branch_joints
    branches = find_branch_joints(names, parents, offsets, animated)
    branch_parents: tuple[str, ...] = ()
    file_names = list(names)
    if branches:
        drop = {b for bs in branches.values() for b in bs}
        keep = [j for j in range(len(names)) if j not in drop]
        remap = {old: new for new, old in enumerate(keep)}
        parents = [-1 if parents[j] < 0 else remap[parents[parents[j]] if parents[j] in drop else parents[j]]
                   for j in keep]
        names = [names[j] for j in keep]
        offsets = offsets[keep]
        positions = positions[:, keep]
        root = remap[root]
        branch_parents = tuple(file_names[p] for p in sorted(branches))
    roles, pairs = guess_roles(names, parents)
    up = _guess_up(positions, roles, names)
    if units is None:
        u = 1 if up == "y" else 2
        height = float(np.mean(positions[..., u].max(-1) - positions[..., u].min(-1)))
        units = "m" if height < 3.0 else "cm"
    child_set = set(parents)
    leaves = tuple(n for j, n in enumerate(names) if j not in child_set)
    feet = tuple(roles[r] for r in ("left_ankle", "left_heel", "left_toe", "right_ankle", "right_heel", "right_toe")
                 if r in roles)
    try:
        skeleton = Skeleton(
            name=path.stem, joint_names=tuple(names), parents=tuple(parents), offsets=offsets,
            up_axis=up, units=units, roles=roles, left_right=pairs, feet=feet, end_effectors=leaves,
            branch_joints=branch_parents,
        )
        known = adopt_builtin(names, parents, offsets)  # a built-in skeleton (write_bvh's) reads back as itself
        if known is not None:
            skeleton, order = known
            positions = positions[:, order]
            names = list(skeleton.joint_names)
            root = skeleton.root
        file_index = {n: j for j, n in enumerate(file_names)}
        rig_order = [file_index[n] for n in skeleton.rig().joint_names]
        assert sorted(rig_order) == list(range(len(file_names)))
        fps = 1.0 / data.frame_time
        if abs(fps - round(fps)) < 1e-3 * fps:
            fps = float(round(fps))
        return Motion(skeleton=skeleton, fps=fps, positions=positions, rotations=rot[:, rig_order],
                      root_translation=trans[:, file_index[names[root]]].copy())
    except ParameterError as exc:
        raise MotionFormatError(f"{path}: {exc}") from exc


def find_branch_joints(names: list[str], parents: list[int], offsets: np.ndarray,
                        animated: np.ndarray) -> dict[int, list[int]]:
    """Joints whose children are all branch joints: ``{parent: [branch joint indices]}`` (see :func:`read_bvh`)."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(p, []).append(j)
    scale = max(float(np.abs(offsets).max()), 1e-9)

    def is_branch(b: int) -> bool:
        kids = children.get(b, [])
        return (len(kids) == 1 and not animated[b] and float(np.abs(offsets[b]).max()) <= 1e-9 * scale
                and names[b] == branch_joint_name(names[parents[b]], names[kids[0]]))

    return {p: kids for p, kids in children.items()
            if p >= 0 and len(kids) >= 2 and all(is_branch(b) for b in kids)}


# -------------------------------------------------------------- from Motion
BVH_RIGS = ("exact", "humanoid")

#: The humanoid rig: SMPL joint → Mixamo-style name (SMPL's hand joints become End Sites).
HUMANOID_NAMES = {
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck", "head": "Head",
    **{f"{s}_{a}": f"{S}{b}" for s, S in (("left", "Left"), ("right", "Right")) for a, b in (
        ("collar", "Shoulder"), ("shoulder", "Arm"), ("elbow", "ForeArm"), ("wrist", "Hand"),
        ("hip", "UpLeg"), ("knee", "Leg"), ("ankle", "Foot"), ("foot", "ToeBase"))},
}


def humanoid_motion(motion: Motion) -> Motion:
    """The dance on a standard humanoid rig (Mixamo-like names, T-pose rest, y up, the dance's units).

    ``Hips → Spine → Spine1 → Spine2 → Neck → Head``, ``LeftShoulder → LeftArm → LeftForeArm →
    LeftHand``, ``LeftUpLeg → LeftLeg → LeftFoot → LeftToeBase`` and the right twins: the SMPL
    tree retargeted by :func:`dancekit.motion.retarget.retarget_to_smpl` (limb directions exact)
    with the SMPL rest offsets scaled to the dance's size, so no bone has zero length.

    Raises
    ------
    ParameterError
        For a 2D motion or a skeleton without the limb roles.
    """
    from dancekit.motion.retarget import retarget_to_smpl

    smpl, scaling = retarget_to_smpl(motion)
    keep = [j for j, n in enumerate(smpl.skeleton.joint_names) if n in HUMANOID_NAMES]
    remap = {old: new for new, old in enumerate(keep)}
    names = tuple(HUMANOID_NAMES[smpl.skeleton.joint_names[j]] for j in keep)
    parents = tuple(-1 if smpl.skeleton.parents[j] < 0 else remap[smpl.skeleton.parents[j]] for j in keep)
    offsets = np.asarray(smpl.skeleton.offsets, np.float64)[keep] * scaling
    units = motion.skeleton.units
    roles, pairs = guess_roles(names, parents)
    sk = Skeleton(name="humanoid", joint_names=names, parents=parents, offsets=offsets, up_axis="y", units=units,
                  roles=roles, left_right=pairs,
                  feet=("LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase"),
                  end_effectors=("Head", "LeftHand", "RightHand", "LeftToeBase", "RightToeBase"))
    assert smpl.rotations is not None and smpl.root_translation is not None
    return Motion(sk, motion.fps, rotations=np.asarray(smpl.rotations)[:, keep],
                  root_translation=np.asarray(smpl.root_translation) * scaling).with_positions()


def write_bvh(path: str | os.PathLike, motion: Motion, *, rotation_order: str = "ZXY", rig: str = "exact") -> None:
    """Write a motion as BVH (atomically).

    ``rig="humanoid"`` writes the standard humanoid rig of :func:`humanoid_motion` instead
    (Mixamo-like names, spine and neck, no zero-length bones; retargets in Blender, MotionBuilder
    and Unity's Humanoid importer without hand mapping). The default ``rig="exact"`` writes the
    skeleton's own joints, as follows.

    The joints are those of the skeleton's rig (:meth:`Skeleton.rig`: for
    tang2018, the 23 joints plus the zero-offset branch joints
    ``pelvis_to_head_right``, ``pelvis_to_right_shoulder``, ... between the
    pelvis and its children), parents first. The root gets ``Xposition
    Yposition Zposition`` + rotation channels, the other joints rotation
    channels only, in ``rotation_order`` (intrinsic, default ``Zrotation
    Xrotation Yrotation``), angles in degrees, lengths in the skeleton's units
    (import into Blender with scale 0.01 for cm). A motion with positions only
    gets rotations by inverse kinematics first; the file's forward kinematics
    then reproduces the positions with the skeleton's rest bone lengths
    (exactly on tang2018). Leaf joints get an End Site at 30 % of their own
    bone offset, so that importers draw a visible last bone.

    Raises
    ------
    MotionFormatError
        For a 2D motion or a bad ``rotation_order``.
    """
    sk = motion.skeleton
    if sk.dims != 3:
        raise MotionFormatError(f"cannot write a 2D motion ({sk.name!r}) as BVH: {path}")
    if rig not in BVH_RIGS:
        raise MotionFormatError(f"BVH rig must be one of {', '.join(BVH_RIGS)}, got {rig!r}")
    if rig == "humanoid":
        try:
            motion = humanoid_motion(motion)
        except DancekitError as exc:
            raise MotionFormatError(f"cannot write {path} on the humanoid rig: {exc}") from exc
        sk = motion.skeleton
    order = rotation_order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise MotionFormatError(f"rotation_order must be a permutation of XYZ, got {rotation_order!r}")
    rot_ch = tuple(f"{a}rotation" for a in order)
    rig = sk.rig()
    J = rig.num_joints
    root = rig.root
    channels = [("Xposition", "Yposition", "Zposition") + rot_ch if j == root else rot_ch for j in range(J)]
    # joints in a DFS order where parents precede children (BVH nesting)
    order_idx = list(rig.topological_order)
    remap = {old: new for new, old in enumerate(order_idx)}
    parents = [-1 if rig.parents[j] < 0 else remap[rig.parents[j]] for j in order_idx]
    has_child = set(rig.parents)
    end_sites = {}
    for j in order_idx:
        if j not in has_child:
            off = np.asarray(rig.offsets[j], np.float64) * 0.3
            if not np.any(off):
                off = np.eye(3)[rig.up_index] * 0.05 / rig.unit_scale
            end_sites[remap[j]] = [off]
    # the channel values, IK_CHUNK frames at a time (rotations by IK for a motion with positions only, then
    # Euler angles): no whole-song rotation matrices or float64 temporaries, the same numbers as one pass
    from dancekit.motion.motion import IK_CHUNK

    T = motion.num_frames
    values = np.empty((T, sum(len(channels[j]) for j in order_idx)), np.float64)
    for a in range(0, T, IK_CHUNK):
        try:
            m = motion.slice(a, a + IK_CHUNK).with_rotations() if T > IK_CHUNK else motion.with_rotations()
        except DancekitError as exc:
            raise MotionFormatError(f"cannot compute rotations for {path}: {exc}") from exc
        assert m.rotations is not None and m.root_translation is not None
        eul = np.rad2deg(_matrix_to_euler(np.asarray(m.rotations, np.float64), order))  # (chunk, J, 3)
        col = 0
        for j in order_idx:
            if j == root:
                values[a: a + len(eul), col: col + 3] = m.root_translation
                col += 3
            values[a: a + len(eul), col: col + 3] = eul[:, j]
            col += 3
    data = BvhData(
        names=[rig.joint_names[j] for j in order_idx],
        parents=parents,
        offsets=np.asarray(rig.offsets, np.float64)[order_idx],
        channels=[channels[j] for j in order_idx],
        end_sites=end_sites,
        frame_time=1.0 / motion.fps,
        values=values,
    )
    format_bvh(data, path)
