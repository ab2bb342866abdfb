"""Recognising the built-in skeletons in files that carry only joint names (BVH, glTF).

A tang2018 dance written as BVH (``--bvh-rig exact``) or glb keeps its joint names and tree but not its
roles, mirror pairs or units: read back, it would be a skeleton named after the file that no model can map.
:func:`adopt_builtin` gives such a skeleton back the built-in one it was written from, so a dance read from
any format the toolkit writes is the same dance (same joints, roles and units) as the npz.
"""

from __future__ import annotations

import numpy as np

from dancekit.motion.skeleton import Skeleton, get_skeleton

#: Built-in skeletons recognised by their joint names and tree (body25 and smpl are read by their own readers).
RECOGNISED = ("tang2018",)


def builtin_for(joint_names, parents) -> tuple[Skeleton, list[int]] | None:
    """The built-in skeleton with these joints and tree, in any order: ``(skeleton, order)`` where
    ``order[i]`` is the given index of the skeleton's joint ``i`` (a BVH lists joints depth first); or None."""
    names = list(joint_names)
    parent_name = {n: (names[p] if p >= 0 else None) for n, p in zip(names, parents)}
    for name in RECOGNISED:
        sk = get_skeleton(name)
        if set(sk.joint_names) != set(names) or len(names) != sk.num_joints:
            continue
        if all(parent_name[n] == (sk.joint_names[p] if p >= 0 else None) for n, p in zip(sk.joint_names, sk.parents)):
            return sk, [names.index(n) for n in sk.joint_names]
    return None


def adopt_builtin(joint_names, parents, offsets: np.ndarray) -> tuple[Skeleton, list[int]] | None:
    """The built-in skeleton a file's joints (names, parents, rest ``offsets`` in the built-in's units) were
    written from, and the order of its joints in the file (see :func:`builtin_for`); or None.

    The built-in's roles, pairs, feet, units, up axis and branch joints are taken; its rest offsets are kept
    when the file's equal them to 1e-4 of the largest offset (text files round), else the file's offsets
    are kept on the built-in's roles.
    """
    hit = builtin_for(joint_names, parents)
    if hit is None:
        return None
    sk, order = hit
    off = np.asarray(offsets, np.float64)[order]
    if np.abs(off - sk.offsets).max() > 1e-4 * float(np.abs(sk.offsets).max()):
        sk = sk.replace(offsets=off)
    return sk, order
