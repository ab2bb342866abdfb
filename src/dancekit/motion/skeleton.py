"""Skeletons: joint names, the kinematic tree, rest offsets, roles and mirror pairs.

A :class:`Skeleton` is an immutable description of a body: ``J`` joints named
in ``joint_names``, a tree given by ``parents`` (``parents[root] == -1``;
parents need not have a smaller index, but the tree must be acyclic and have one
root) and rest ``offsets`` (``(J, 3)``, each joint's position relative to its
parent in the rest pose, in ``units``). Forward kinematics of identity rotations
reproduces the rest pose.

Rotations live on the skeleton's *rig* (:meth:`Skeleton.rig`): the same
joints, plus one zero-offset virtual *branch joint* per child of every joint
listed in ``branch_joints`` (joints whose children do not keep a rigid layout,
such as the tang2018 pelvis, which carries the hips, the shoulders and the
head without any spine joint). Each branch joint has its own rotation, so
every real bone hangs from a joint that rotates for it alone and inverse
kinematics reproduces every bone direction exactly (see
:mod:`dancekit.motion.kinematics`). Skeletons without ``branch_joints`` (SMPL,
BODY_25, BVH files) are their own rig.

Canonical roles let metrics and models find body parts on any skeleton:
``pelvis``, ``spine`` (optional), ``neck``, ``head`` and the ``left_``/``right_``
twins of ``shoulder``, ``elbow``, ``wrist``, ``hip``, ``knee``, ``ankle``, ``toe``.
``Skeleton.index("left_ankle")`` works on every built-in skeleton that has one.

Built-in skeletons (:func:`get_skeleton`):

``tang2018``
    The 23 joints of Tang et al. 2018 ("Dance with Melody"), centimetres, y up,
    root = joint 2 (pelvis). See :func:`tang2018_skeleton` for how sides and
    offsets were established from the data.
``body25``
    OpenPose BODY_25 (25 keypoints), 2D, pixels, image space (x right, y *down*:
    ``up_axis == "-y"``), root = MidHip.
``smpl``
    The 24 SMPL joints in SMPL order, metres, y up, hand-set approximate offsets
    (the licensed SMPL model files are never needed); see :func:`smpl_skeleton`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from dancekit.errors import MotionFormatError, ParameterError

__all__ = [
    "BRANCH_SEPARATOR",
    "CANONICAL_ROLES",
    "Skeleton",
    "branch_joint_name",
    "body25_skeleton",
    "get_skeleton",
    "keep_bone_lengths",
    "smpl_skeleton",
    "tang2018_skeleton",
]

CANONICAL_ROLES: tuple[str, ...] = (
    "pelvis",
    "spine",
    "neck",
    "head",
    *(f"{side}_{part}" for side in ("left", "right")
      for part in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe")),
)

_UP_AXES = ("y", "z", "-y")

#: Branch joints of the rig are named ``f"{parent}{BRANCH_SEPARATOR}{child}"``, e.g. ``"pelvis_to_left_hip"``.
BRANCH_SEPARATOR = "_to_"


def branch_joint_name(parent: str, child: str) -> str:
    """Name of the rig's branch joint between joint ``parent`` and its child ``child``."""
    return f"{parent}{BRANCH_SEPARATOR}{child}"
_UNIT_SCALE = {"cm": 0.01, "m": 1.0, "mm": 0.001, "px": 1.0}


@dataclass(frozen=True, eq=False)
class Skeleton:
    """An immutable kinematic tree with rest offsets, roles and mirror pairs.

    Parameters
    ----------
    name : str
        Identifier (``"tang2018"``, ``"body25"``, ``"smpl"``, or a BVH file stem).
    joint_names : tuple of str, length J
        Unique joint names.
    parents : tuple of int, length J
        Parent index of each joint; exactly one ``-1`` (the root).
    offsets : np.ndarray, shape (J, 3), float64
        Rest position of each joint relative to its parent, in ``units``
        (the root's offset is ignored by forward kinematics and stored as 0).
        2D skeletons keep a zero third column.
    up_axis : {"y", "z", "-y"}
        The vertical axis. ``"-y"`` is image space (y grows downwards).
    units : {"cm", "m", "mm", "px"}
        Length unit of offsets and positions. ``"px"`` marks a 2D (image) skeleton.
    roles : Mapping[str, str]
        Canonical role -> joint name, e.g. ``"left_ankle" -> "LeftFoot"``.
    left_right : tuple of (str, str)
        Mirrored joint pairs by name ``(left, right)``.
    feet : tuple of str
        Joints used for foot contact (ankles, heels, toes).
    end_effectors : tuple of str
        Joints at the ends of the chains.
    branch_joints : tuple of str
        Joints (each with at least two children) whose children move relative
        to each other; :meth:`rig` gives each of their children its own
        zero-offset branch joint. Default: none (the skeleton is its own rig).

    Raises
    ------
    ParameterError
        If the tree, names, offsets, roles or pairs are inconsistent.
    """

    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    up_axis: str = "y"
    units: str = "cm"
    roles: Mapping[str, str] = field(default_factory=dict)
    left_right: tuple[tuple[str, str], ...] = ()
    feet: tuple[str, ...] = ()
    end_effectors: tuple[str, ...] = ()
    branch_joints: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.joint_names)
        parents = tuple(int(p) for p in self.parents)
        J = len(names)
        if J == 0:
            raise ParameterError(f"skeleton {self.name!r}: no joints")
        if len(set(names)) != J:
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ParameterError(f"skeleton {self.name!r}: duplicate joint names {dup}")
        if len(parents) != J:
            raise ParameterError(f"skeleton {self.name!r}: {len(parents)} parents for {J} joints")
        roots = [j for j, p in enumerate(parents) if p == -1]
        if len(roots) != 1:
            raise ParameterError(f"skeleton {self.name!r}: need exactly one root (parent -1), got {roots}")
        for j, p in enumerate(parents):
            if p != -1 and not 0 <= p < J:
                raise ParameterError(f"skeleton {self.name!r}: joint {names[j]!r} has bad parent {p}")
        order = parents_first_order(parents)
        if len(order) != J:
            raise ParameterError(f"skeleton {self.name!r}: parents contain a cycle")
        offsets = np.array(self.offsets, dtype=np.float64)
        if offsets.shape == (J, 2):
            offsets = np.concatenate([offsets, np.zeros((J, 1))], axis=1)
        if offsets.shape != (J, 3):
            raise ParameterError(f"skeleton {self.name!r}: offsets must be ({J}, 3), got {offsets.shape}")
        if not np.all(np.isfinite(offsets)):
            raise ParameterError(f"skeleton {self.name!r}: offsets are not finite")
        offsets[roots[0]] = 0.0
        offsets.setflags(write=False)
        if self.up_axis not in _UP_AXES:
            raise ParameterError(f"skeleton {self.name!r}: up_axis must be one of {_UP_AXES}, got {self.up_axis!r}")
        if self.units not in _UNIT_SCALE:
            raise ParameterError(f"skeleton {self.name!r}: units must be one of {tuple(_UNIT_SCALE)}, got {self.units!r}")
        name_set = set(names)
        roles = {str(k): str(v) for k, v in dict(self.roles).items()}
        for role, joint in roles.items():
            if joint not in name_set:
                raise ParameterError(f"skeleton {self.name!r}: role {role!r} names unknown joint {joint!r}")
        left_right = tuple((str(a), str(b)) for a, b in self.left_right)
        seen: set[str] = set()
        for a, b in left_right:
            for n in (a, b):
                if n not in name_set:
                    raise ParameterError(f"skeleton {self.name!r}: mirror pair names unknown joint {n!r}")
                if n in seen:
                    raise ParameterError(f"skeleton {self.name!r}: joint {n!r} is in two mirror pairs")
                seen.add(n)
        feet = tuple(str(n) for n in self.feet)
        ends = tuple(str(n) for n in self.end_effectors)
        for n in feet + ends:
            if n not in name_set:
                raise ParameterError(f"skeleton {self.name!r}: unknown joint {n!r} in feet/end_effectors")
        branch = tuple(str(n) for n in self.branch_joints)
        for n in branch:
            if n not in name_set:
                raise ParameterError(f"skeleton {self.name!r}: unknown branch joint {n!r}")
            bi = names.index(n)
            kids = [names[j] for j, p in enumerate(parents) if p == bi]
            if len(kids) < 2:
                raise ParameterError(f"skeleton {self.name!r}: branch joint {n!r} needs at least 2 children, has {kids}")
            clash = [branch_joint_name(n, c) for c in kids if branch_joint_name(n, c) in name_set]
            if clash:
                raise ParameterError(f"skeleton {self.name!r}: joint names {clash} are reserved for branch joints")
        if len(set(branch)) != len(branch):
            raise ParameterError(f"skeleton {self.name!r}: duplicate branch joints {branch}")
        set_ = object.__setattr__
        set_(self, "joint_names", names)
        set_(self, "parents", parents)
        set_(self, "offsets", offsets)
        set_(self, "roles", MappingProxyType(roles))
        set_(self, "left_right", left_right)
        set_(self, "feet", feet)
        set_(self, "end_effectors", ends)
        set_(self, "branch_joints", tuple(sorted(branch, key=names.index)))
        set_(self, "_rig", None)
        set_(self, "_index", {n: j for j, n in enumerate(names)})
        set_(self, "_order", tuple(order))

    def __reduce__(self):
        """Pickled by its constructor's arguments (its roles a read-only view, which pickle cannot copy)."""
        return (_skeleton_from, ({"name": self.name, "joint_names": self.joint_names, "parents": self.parents,
                                  "offsets": np.array(self.offsets), "up_axis": self.up_axis, "units": self.units,
                                  "roles": dict(self.roles), "left_right": self.left_right, "feet": self.feet,
                                  "end_effectors": self.end_effectors, "branch_joints": self.branch_joints},))

    # ------------------------------------------------------------------ lookup
    def index(self, name_or_role: str) -> int:
        """Index of a joint given its name or its canonical role.

        Joint names take precedence over roles.

        Raises
        ------
        ParameterError
            If ``name_or_role`` is neither a joint name nor a role of this skeleton.
        """
        idx: dict[str, int] = self._index  # type: ignore[attr-defined]
        if name_or_role in idx:
            return idx[name_or_role]
        if name_or_role in self.roles:
            return idx[self.roles[name_or_role]]
        raise ParameterError(
            f"skeleton {self.name!r} has no joint or role {name_or_role!r} "
            f"(roles: {sorted(self.roles)})"
        )

    def has(self, name_or_role: str) -> bool:
        """Whether ``name_or_role`` is a joint name or a role of this skeleton."""
        return name_or_role in self._index or name_or_role in self.roles  # type: ignore[attr-defined]

    # -------------------------------------------------------------- properties
    @property
    def num_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)

    @property
    def root(self) -> int:
        """Index of the root joint."""
        return self.parents.index(-1)

    @property
    def dims(self) -> int:
        """2 for image-space skeletons (``units == "px"``), else 3."""
        return 2 if self.units == "px" else 3

    @property
    def unit_scale(self) -> float:
        """Metres per unit (cm: 0.01, m: 1, mm: 0.001; px: 1, i.e. no metric scale)."""
        return _UNIT_SCALE[self.units]

    @property
    def up_index(self) -> int:
        """Index of the vertical axis in a position vector (0, 1 or 2)."""
        return {"y": 1, "-y": 1, "z": 2}[self.up_axis]

    @property
    def bones(self) -> list[tuple[int, int]]:
        """``(parent, child)`` index pairs, parents before children."""
        return [(self.parents[j], j) for j in self.topological_order if self.parents[j] >= 0]

    @property
    def topological_order(self) -> tuple[int, ...]:
        """Joint indices ordered so that every parent comes before its children."""
        return self._order  # type: ignore[attr-defined]

    def children(self, joint: int) -> list[int]:
        """Indices of the children of ``joint``."""
        return [j for j, p in enumerate(self.parents) if p == joint]

    def mirror_permutation(self) -> np.ndarray:
        """``(J,)`` int array ``perm`` with ``perm[j]`` = the mirror twin of joint j (or j).

        ``positions[:, perm]`` swaps left and right joints.
        """
        perm = np.arange(self.num_joints)
        for a, b in self.left_right:
            ia, ib = self.index(a), self.index(b)
            perm[ia], perm[ib] = ib, ia
        return perm

    def rig(self) -> Skeleton:
        """The skeleton that rotations live on: this one plus a branch joint per child of each branch joint.

        The rig's first ``num_joints`` joints are this skeleton's joints, in the
        same order, with the same names and offsets (so ``rig_positions[...,
        :num_joints, :]`` are this skeleton's positions). Then, for each joint
        ``p`` in ``branch_joints`` (in index order) and each child ``c`` of ``p``
        (in index order), one virtual joint named ``branch_joint_name(p, c)``
        (``"pelvis_to_left_hip"``) with parent ``p``, a zero offset and ``c``
        as its only child. A branch joint sits where ``p`` is; its rotation
        turns ``c``'s bone alone. Roles, feet and end effectors are unchanged;
        branch joints of mirrored children are mirror pairs. The rig itself has
        no ``branch_joints``; a skeleton without them is its own rig.

        Examples
        --------
        >>> sk = get_skeleton("tang2018")
        >>> rig = sk.rig()
        >>> rig.num_joints, rig.joint_names[23], rig.joint_names[rig.parents[7]]
        (28, 'pelvis_to_head_right', 'pelvis_to_right_hip')
        """
        if not self.branch_joints:
            return self
        cached: Skeleton | None = self._rig  # type: ignore[attr-defined]
        if cached is not None:
            return cached
        names = list(self.joint_names)
        parents = list(self.parents)
        offsets = [np.asarray(self.offsets)]
        branch_of: dict[str, str] = {}
        for p in sorted(self.index(n) for n in self.branch_joints):
            for c in self.children(p):
                b = branch_joint_name(names[p], self.joint_names[c])
                branch_of[self.joint_names[c]] = b
                parents[c] = len(names)
                names.append(b)
                parents.append(p)
        offsets.append(np.zeros((len(names) - self.num_joints, 3)))
        pairs = list(self.left_right) + [
            (branch_of[a], branch_of[b]) for a, b in self.left_right if a in branch_of and b in branch_of
        ]
        rig = Skeleton(
            name=f"{self.name}_rig", joint_names=tuple(names), parents=tuple(parents),
            offsets=np.concatenate(offsets), up_axis=self.up_axis, units=self.units, roles=dict(self.roles),
            left_right=tuple(pairs), feet=self.feet, end_effectors=self.end_effectors,
        )
        object.__setattr__(self, "_rig", rig)
        return rig

    def bone_lengths(self) -> np.ndarray:
        """``(J,)`` rest length of the bone ending at each joint (0 at the root)."""
        return np.linalg.norm(self.offsets, axis=-1)

    # -------------------------------------------------------------- (de)serialise
    def to_dict(self) -> dict[str, Any]:
        """A JSON-able dict (lists and plain types) that :meth:`from_dict` reads back."""
        return {
            "name": self.name,
            "joint_names": list(self.joint_names),
            "parents": list(self.parents),
            "offsets": [[float(v) for v in row] for row in self.offsets],
            "up_axis": self.up_axis,
            "units": self.units,
            "roles": dict(self.roles),
            "left_right": [list(p) for p in self.left_right],
            "feet": list(self.feet),
            "end_effectors": list(self.end_effectors),
            "branch_joints": list(self.branch_joints),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Skeleton:
        """Rebuild a skeleton from :meth:`to_dict` output.

        Raises
        ------
        ParameterError
            If keys are missing or the values are inconsistent.
        """
        try:
            return cls(
                name=str(d["name"]),
                joint_names=tuple(d["joint_names"]),
                parents=tuple(int(p) for p in d["parents"]),
                offsets=np.asarray(d["offsets"], dtype=np.float64),
                up_axis=str(d.get("up_axis", "y")),
                units=str(d.get("units", "cm")),
                roles=dict(d.get("roles", {})),
                left_right=tuple(tuple(p) for p in d.get("left_right", ())),
                feet=tuple(d.get("feet", ())),
                end_effectors=tuple(d.get("end_effectors", ())),
                branch_joints=tuple(d.get("branch_joints", ())),
            )
        except (KeyError, TypeError) as exc:
            raise ParameterError(f"bad skeleton dict: {exc!r}") from exc

    def replace(self, **changes: Any) -> Skeleton:
        """A copy with some fields changed (like :func:`dataclasses.replace`)."""
        d = {
            "name": self.name, "joint_names": self.joint_names, "parents": self.parents,
            "offsets": self.offsets, "up_axis": self.up_axis, "units": self.units,
            "roles": dict(self.roles), "left_right": self.left_right, "feet": self.feet,
            "end_effectors": self.end_effectors, "branch_joints": self.branch_joints,
        }
        d.update(changes)
        return Skeleton(**d)

    def same_as(self, other: Skeleton, *, atol: float = 1e-6) -> bool:
        """Structural equality: names, tree, units, roles, pairs, branch joints and offsets (to ``atol``)."""
        return (
            self.joint_names == other.joint_names
            and self.parents == other.parents
            and self.up_axis == other.up_axis
            and self.units == other.units
            and dict(self.roles) == dict(other.roles)
            and self.left_right == other.left_right
            and self.branch_joints == other.branch_joints
            and np.allclose(self.offsets, other.offsets, atol=atol)
        )

    def __repr__(self) -> str:
        return (f"Skeleton(name={self.name!r}, joints={self.num_joints}, root={self.joint_names[self.root]!r}, "
                f"units={self.units!r}, up_axis={self.up_axis!r})")


def _skeleton_from(kwargs: dict) -> Skeleton:
    """:class:`Skeleton` from its constructor's arguments (how a pickled skeleton is rebuilt)."""
    return Skeleton(**kwargs)


def keep_bone_lengths(q: np.ndarray, x: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Positions ``q`` (T, J, 3) moved so that each frame has the bone lengths of ``x`` (T, J, 3).

    Bone directions come from ``q``, parents first, starting from ``q``'s root; what a filter or a lift did
    to the positions stays, only the lengths are restored. Units those of the inputs. Returns float64.
    """
    q = np.asarray(q, np.float64)
    x = np.asarray(x, np.float64)
    o = q.copy()
    for j in skeleton.topological_order:
        parent = skeleton.parents[j]
        if parent >= 0:
            d = q[:, j] - q[:, parent]
            length = np.linalg.norm(x[:, j] - x[:, parent], axis=-1, keepdims=True)
            o[:, j] = o[:, parent] + length * d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    return o


def parents_first_order(parents: tuple[int, ...]) -> list[int]:
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(p, []).append(j)
    order: list[int] = []
    stack = list(reversed(children.get(-1, [])))
    visited: set[int] = set()
    while stack:
        j = stack.pop()
        if j in visited:
            return []
        visited.add(j)
        order.append(j)
        stack.extend(reversed(children.get(j, [])))
    return order


# ---------------------------------------------------------------------------
# tang2018
# ---------------------------------------------------------------------------

_TANG2018_NAMES = (
    "head_right",      # 0  head marker on the right side of the head
    "head_left",       # 1  head marker on the left side (10.6 cm from 0)
    "pelvis",          # 2  root
    "right_shoulder",  # 3
    "right_elbow",     # 4
    "right_forearm",   # 5  marker on the forearm, 11.6 cm from the elbow
    "right_wrist",     # 6  25 cm from the elbow
    "right_hip",       # 7
    "right_knee",      # 8
    "right_ankle",     # 9
    "right_heel",      # 10 behind and below the ankle
    "right_toe",       # 11 in front of the ankle
    "left_shoulder",   # 12
    "left_elbow",      # 13
    "left_forearm",    # 14 marker on the forearm, 17 cm from the elbow
    "left_wrist",      # 15 24 cm from the elbow
    "left_hip",        # 16
    "left_knee",       # 17
    "left_ankle",      # 18
    "left_heel",       # 19
    "left_toe",        # 20
    "left_aux",        # 21 undrawn marker: 6 cm from 14, 12.0 +- 0.6 cm from 13, 14.7 cm from 15
    "right_aux",       # 22 undrawn marker: 4.7 +- 0.8 cm from 6 (the right hand)
)

# Tree: the neck is virtual in this data, so the shoulders and the head hang
# directly from the pelvis; each foot is a chain ankle -> heel -> toe and each
# undrawn marker hangs from the wrist, so every joint below the pelvis has at
# most one child. The pelvis is a branch joint: its five children (head,
# shoulders, hips) move relative to each other as the torso bends, so the rig
# gives each of them its own zero-offset branch joint (Skeleton.rig).
_TANG2018_PARENTS = (2, 0, -1, 2, 3, 4, 5, 2, 7, 8, 9, 10, 2, 12, 13, 14, 2, 16, 17, 18, 19, 15, 6)

# Rest offsets (cm) = the mean pose of the data set: for every bone, the mean of
# the bone vector expressed in a per-frame body frame (x = left, y = up,
# z = forward; left = horizontal part of (16 - 7) + (12 - 3), forward =
# left x up), rescaled to the mean bone length. Measured once over all 37
# dances (58 876 frames) of ../shared/data/tang2018 by
# ``python -m dancekit.motion._tang2018_rest ../shared/data/tang2018``,
# which also prints the per-bone length standard deviation (1 to 5 cm: the
# data is not rigid; see docs/MOTION.md).
_TANG2018_OFFSETS = np.array([
    [-5.97, 46.04, -12.74],   # 0  head_right   <- pelvis     len 48.14 std 2.07
    [9.42, 3.16, 3.57],       # 1  head_left    <- head_right len 10.56 std 1.37
    [0.0, 0.0, 0.0],          # 2  pelvis (root)
    [-15.59, 29.27, -6.43],   # 3  r shoulder   <- pelvis     len 33.78 std 1.26
    [-27.98, -10.08, 1.90],   # 4  r elbow                    len 29.80 std 2.83
    [-2.71, 0.42, 11.32],     # 5  r forearm                  len 11.64 std 1.41
    [1.80, 2.65, 14.07],      # 6  r wrist                    len 14.43 std 2.67
    [-9.75, -15.29, -4.56],   # 7  r hip        <- pelvis     len 18.70 std 1.93
    [-3.44, -46.81, 5.50],    # 8  r knee                     len 47.26 std 4.92
    [1.78, -31.43, -9.92],    # 9  r ankle                    len 33.00 std 2.13
    [6.16, -7.50, -6.97],     # 10 r heel       <- r ankle    len 11.95 std 2.14
    [-6.48, -6.08, 19.41],    # 11 r toe        <- r heel     len 21.35 std 1.19
    [13.08, 31.39, -7.53],    # 12 l shoulder   <- pelvis     len 34.83 std 1.22
    [27.17, -9.49, 4.46],     # 13 l elbow                    len 29.12 std 3.12
    [8.18, 13.87, 5.66],      # 14 l forearm                  len 17.07 std 1.74
    [10.14, -2.67, 6.19],     # 15 l wrist                    len 12.18 std 1.42
    [11.32, -14.68, -3.50],   # 16 l hip        <- pelvis     len 18.87 std 2.08
    [3.25, -48.05, 4.94],     # 17 l knee                     len 48.42 std 3.55
    [-1.77, -31.78, -10.40],  # 18 l ankle                    len 33.49 std 2.85
    [-7.32, -5.96, -7.87],    # 19 l heel       <- l ankle    len 12.29 std 1.60
    [8.85, -6.21, 19.75],     # 20 l toe        <- l heel     len 22.52 std 1.34
    [-11.93, -2.12, -8.37],   # 21 l aux        <- l wrist    len 14.73 std 2.50
    [1.81, -0.87, 4.29],      # 22 r aux        <- r wrist    len 4.74 std 0.79
])


def tang2018_skeleton() -> Skeleton:
    """The 23-joint skeleton of Tang et al. 2018 (cm, y up, root = joint 2 pelvis).

    Which side is left was derived from the data (all 37 dances): the facing
    direction was estimated in two independent ways, from the feet (toe
    markers 11/20 minus ankles 9/18) and from knee flexion (knee minus the
    hip-ankle midpoint, which points forward when the knee bends); with a
    right-handed y-up frame, left = up x forward. On every dance, joints
    16-20 and 12-15 lie on the left side in 87-100 % of frames by the feet
    estimate, 60-100 % by the knee estimate (the two agree on which marker is
    the toe: on 10 dances checked, 11/20 are in front of the ankle in 72-97 %
    of bent-knee frames, 10/19 behind). Measured by
    ``python -m dancekit.motion._tang2018_rest`` (this assumes the data's
    frame is right-handed, as the README's y-up convention suggests). So chain 7-8-9-10-11 and arm 3-4-5-6 are the *right* side,
    16-20 and 12-15 the left; 10/19 are heels, 11/20 toes; 0 is the right and
    1 the left side of the head. Joint 22 sits 4.7 cm from the right wrist 6;
    joint 21 is *not* symmetric to it: it sits 6 cm from 14 and 14.7 cm from
    the left wrist 15. The neck is virtual (midpoint of 3 and 12), so there
    is no ``neck`` role. Offsets: see ``_TANG2018_OFFSETS`` and docs/MOTION.md.

    ``branch_joints = ("pelvis",)``: the rig (:meth:`Skeleton.rig`, 28 joints)
    adds ``pelvis_to_head_right``, ``pelvis_to_right_shoulder``,
    ``pelvis_to_right_hip``, ``pelvis_to_left_shoulder`` and
    ``pelvis_to_left_hip`` (joints 23-27) between the pelvis and its children.
    """
    names = _TANG2018_NAMES
    roles = {
        "pelvis": "pelvis",
        "head": "head_right",
        **{f"{s}_{p}": f"{s}_{p}" for s in ("left", "right")
           for p in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe", "heel", "forearm")},
    }
    pairs = tuple((n, "right_" + n[5:]) for n in names if n.startswith("left_")) + (("head_left", "head_right"),)
    return Skeleton(
        name="tang2018",
        joint_names=names,
        parents=_TANG2018_PARENTS,
        offsets=_TANG2018_OFFSETS,
        up_axis="y",
        units="cm",
        roles=roles,
        left_right=pairs,
        feet=("left_ankle", "left_heel", "left_toe", "right_ankle", "right_heel", "right_toe"),
        end_effectors=("head_left", "left_toe", "right_toe", "left_aux", "right_aux"),
        branch_joints=("pelvis",),
    )


# ---------------------------------------------------------------------------
# body25
# ---------------------------------------------------------------------------

_BODY25_NAMES = (
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip",
    "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
    "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel",
)
_BODY25_PARENTS = (1, 8, 1, 2, 3, 1, 5, 6, -1, 8, 9, 10, 8, 12, 13, 0, 0, 15, 16, 14, 19, 14, 11, 22, 11)
# Rest pose of a front-facing person about 400 px tall, image space (x right,
# y down): the person's right side is on the image's left (negative x).
_BODY25_OFFSETS = np.array([
    [0, -30, 0],    # Nose      <- Neck
    [0, -110, 0],   # Neck      <- MidHip
    [-35, 0, 0],    # RShoulder <- Neck
    [-10, 60, 0],   # RElbow
    [-5, 55, 0],    # RWrist
    [35, 0, 0],     # LShoulder <- Neck
    [10, 60, 0],    # LElbow
    [5, 55, 0],     # LWrist
    [0, 0, 0],      # MidHip (root)
    [-20, 0, 0],    # RHip
    [0, 85, 0],     # RKnee
    [0, 85, 0],     # RAnkle
    [20, 0, 0],     # LHip
    [0, 85, 0],     # LKnee
    [0, 85, 0],     # LAnkle
    [-7, -7, 0],    # REye      <- Nose
    [7, -7, 0],     # LEye      <- Nose
    [-8, 3, 0],     # REar      <- REye
    [8, 3, 0],      # LEar      <- LEye
    [6, 12, 0],     # LBigToe   <- LAnkle
    [6, 0, 0],      # LSmallToe <- LBigToe
    [-2, 8, 0],     # LHeel     <- LAnkle
    [-6, 12, 0],    # RBigToe   <- RAnkle
    [-6, 0, 0],     # RSmallToe <- RBigToe
    [2, 8, 0],      # RHeel     <- RAnkle
], dtype=np.float64)


def body25_skeleton() -> Skeleton:
    """OpenPose BODY_25 (25 keypoints, 2D, pixels, image space with y down).

    ``up_axis`` is ``"-y"``: image rows grow downwards, so "up" is -y. The
    root is MidHip (8). The offsets describe a front-facing person about
    400 px tall (only used as a rest pose for drawing and tests).
    """
    names = _BODY25_NAMES
    roles = {
        "pelvis": "MidHip", "neck": "Neck", "head": "Nose",
        "left_shoulder": "LShoulder", "left_elbow": "LElbow", "left_wrist": "LWrist",
        "left_hip": "LHip", "left_knee": "LKnee", "left_ankle": "LAnkle", "left_toe": "LBigToe",
        "right_shoulder": "RShoulder", "right_elbow": "RElbow", "right_wrist": "RWrist",
        "right_hip": "RHip", "right_knee": "RKnee", "right_ankle": "RAnkle", "right_toe": "RBigToe",
        "left_heel": "LHeel", "right_heel": "RHeel",
    }
    pairs = tuple((n, "R" + n[1:]) for n in names if n.startswith("L"))
    return Skeleton(
        name="body25",
        joint_names=names,
        parents=_BODY25_PARENTS,
        offsets=_BODY25_OFFSETS,
        up_axis="-y",
        units="px",
        roles=roles,
        left_right=pairs,
        feet=("LAnkle", "LBigToe", "LSmallToe", "LHeel", "RAnkle", "RBigToe", "RSmallToe", "RHeel"),
        end_effectors=("LEar", "REar", "LWrist", "RWrist", "LSmallToe", "RSmallToe", "LHeel", "RHeel"),
    )


# ---------------------------------------------------------------------------
# smpl
# ---------------------------------------------------------------------------

SMPL_JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)
SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)
# Hand-set approximate offsets in metres for an average adult in the SMPL rest
# pose (T-pose, facing +z, left = +x, y up). Not taken from the licensed model.
_SMPL_OFFSETS = np.array([
    [0.0, 0.0, 0.0],        # pelvis
    [0.06, -0.09, 0.0],     # left_hip
    [-0.06, -0.09, 0.0],    # right_hip
    [0.0, 0.11, -0.02],     # spine1
    [0.04, -0.38, 0.0],     # left_knee
    [-0.04, -0.38, 0.0],    # right_knee
    [0.0, 0.13, 0.01],      # spine2
    [-0.01, -0.40, -0.04],  # left_ankle
    [0.01, -0.40, -0.04],   # right_ankle
    [0.0, 0.05, 0.02],      # spine3
    [0.02, -0.06, 0.12],    # left_foot
    [-0.02, -0.06, 0.12],   # right_foot
    [0.0, 0.21, -0.03],     # neck
    [0.08, 0.12, -0.01],    # left_collar
    [-0.08, 0.12, -0.01],   # right_collar
    [0.0, 0.09, 0.05],      # head
    [0.12, 0.04, -0.02],    # left_shoulder
    [-0.12, 0.04, -0.02],   # right_shoulder
    [0.25, -0.01, -0.02],   # left_elbow
    [-0.25, -0.01, -0.02],  # right_elbow
    [0.25, 0.01, 0.0],      # left_wrist
    [-0.25, 0.01, 0.0],     # right_wrist
    [0.08, -0.01, -0.01],   # left_hand
    [-0.08, -0.01, -0.01],  # right_hand
])


def smpl_skeleton(offsets_path: str | os.PathLike | None = None) -> Skeleton:
    """The 24-joint SMPL skeleton (SMPL order, metres, y up).

    Parameters
    ----------
    offsets_path : path, optional
        A ``(24, 3)`` array of joint offsets (metres, relative to the parent)
        in ``.npy``, ``.npz`` (first array, or key ``offsets``) or ``.json``
        (a list of 24 triples, or ``{"offsets": [...]}``), e.g. measured from
        a licensed SMPL model. By default hand-set approximate offsets are used.

    Raises
    ------
    MotionFormatError
        If ``offsets_path`` is missing, unreadable or not ``(24, 3)``.
    """
    offsets = _SMPL_OFFSETS
    if offsets_path is not None:
        offsets = _load_offsets(Path(offsets_path), 24)
    roles = {
        "pelvis": "pelvis", "spine": "spine1", "neck": "neck", "head": "head",
        **{f"{s}_{p}": f"{s}_{p}" for s in ("left", "right")
           for p in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")},
        "left_toe": "left_foot", "right_toe": "right_foot",
    }
    pairs = tuple((n, "right_" + n[5:]) for n in SMPL_JOINT_NAMES if n.startswith("left_"))
    return Skeleton(
        name="smpl",
        joint_names=SMPL_JOINT_NAMES,
        parents=SMPL_PARENTS,
        offsets=offsets,
        up_axis="y",
        units="m",
        roles=roles,
        left_right=pairs,
        feet=("left_ankle", "left_foot", "right_ankle", "right_foot"),
        end_effectors=("head", "left_hand", "right_hand", "left_foot", "right_foot"),
    )


def _load_offsets(path: Path, J: int) -> np.ndarray:
    if not path.is_file():
        raise MotionFormatError(f"offsets file not found: {path}")
    try:
        if path.suffix == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                arr = z["offsets"] if "offsets" in z.files else z[z.files[0]]
        elif path.suffix == ".json":
            obj = json.loads(path.read_text())
            arr = np.asarray(obj["offsets"] if isinstance(obj, dict) else obj, dtype=np.float64)
        else:
            raise MotionFormatError(f"offsets file must be .npy, .npz or .json: {path}")
    except MotionFormatError:
        raise
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise MotionFormatError(f"cannot read offsets from {path}: {exc}") from exc
    arr = np.asarray(arr, dtype=np.float64)
    if arr.shape != (J, 3) or not np.all(np.isfinite(arr)):
        raise MotionFormatError(f"offsets in {path} must be finite ({J}, 3), got {arr.shape}")
    return arr


_BUILTIN = {"tang2018": tang2018_skeleton, "body25": body25_skeleton, "smpl": smpl_skeleton}
_CACHE: dict[str, Skeleton] = {}


def get_skeleton(name: str) -> Skeleton:
    """A built-in skeleton by name: ``"tang2018"``, ``"body25"`` or ``"smpl"``.

    Raises
    ------
    ParameterError
        If ``name`` is not a built-in skeleton.
    """
    if name not in _BUILTIN:
        raise ParameterError(f"unknown skeleton {name!r}; built-in: {sorted(_BUILTIN)}")
    if name not in _CACHE:
        _CACHE[name] = _BUILTIN[name]()
    return _CACHE[name]
