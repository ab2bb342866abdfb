"""From a :class:`dancekit.motion.Motion` to the plain arrays the renderers take.

Besides positions, parents, fps, up axis and units, this picks the drawing colours from
the skeleton's mirror pairs (``left_right``; else joint names such as ``LeftArm``,
``left_knee``, ``LShoulder``) and makes two drawing-only additions when
the skeleton calls for them (the motion itself is never changed):

* a virtual **neck** at the midpoint of the shoulders when the skeleton has no ``neck``
  role (tang2018: the shoulders and head hang from the pelvis), so the torso is drawn
  as pelvis - neck - shoulders instead of a V;
* a virtual **head centre** at the midpoint of the ``head`` joint and its mirror twin
  (tang2018 has two head-side markers), where the head disc is drawn; the two markers
  themselves are left out of the drawing.

2D motions (``units == "px"``, image space) are lifted onto the plane ``z = 0`` and
scaled so the figure is 1.75 m tall.
"""

from __future__ import annotations

import numpy as np

from dancekit.errors import ParameterError


def _side_of(name: str) -> int:
    n = name.lower()
    if n.startswith(("left", "l_")) or (len(name) > 1 and name[0] == "L" and name[1].isupper()):
        return 1
    if n.startswith(("right", "r_")) or (len(name) > 1 and name[0] == "R" and name[1].isupper()):
        return -1
    return 0


def _drop_joints(pos: np.ndarray, parents: list[int], sides: list[int], head: int, drop: set[int]):
    """Remove the joints in ``drop``; their children hang from ``head`` instead."""
    keep = [j for j in range(len(parents)) if j not in drop]
    new_index = {j: i for i, j in enumerate(keep)}
    new_parents = []
    for j in keep:
        p = head if parents[j] in drop else parents[j]
        assert p not in drop and p != j
        new_parents.append(-1 if p < 0 else new_index[p])
    return pos[:, keep], new_parents, [sides[j] for j in keep], new_index[head]


#: Frames per piece in the render's per-frame work (:func:`motion_arrays` of 3D motions, the scene's
#: conversion and camera distance, the html's quantisation): every output frame depends on its own frame only.
_CHUNK = 4096


class _Piece:
    """Frames of a 3D motion, as much of a :class:`~dancekit.motion.Motion` as :func:`motion_arrays` reads."""

    def __init__(self, skeleton, fps: float, positions: np.ndarray) -> None:
        self.skeleton, self.fps, self._positions = skeleton, fps, positions

    def to_positions(self) -> np.ndarray:
        return self._positions


def motion_arrays(motion) -> dict:
    """Keyword arguments for :func:`render_mp4` / :func:`render_html` describing ``motion``.

    Returns
    -------
    dict
        ``positions (T, J', 3)``, ``parents (J',)``, ``fps``, ``up_axis``, ``unit_scale``,
        ``sides (J',)``, ``head`` (int or None); ``J'`` counts the virtual joints and
        leaves out the replaced head markers.

    Raises
    ------
    ParameterError
        If ``motion`` does not look like a :class:`dancekit.motion.Motion`.
    """
    try:
        sk = motion.skeleton
        fps = float(motion.fps)
        pos = motion.to_positions()
    except AttributeError as exc:
        raise ParameterError(f"expected a dancekit.motion.Motion, got {type(motion).__name__}") from exc
    if np.ndim(pos) != 3 or np.shape(pos)[1] != sk.num_joints or np.shape(pos)[2] not in (2, 3):
        raise ParameterError(f"motion positions must be (T, {sk.num_joints}, 2|3), got {np.shape(pos)}")
    if np.shape(pos)[2] == 3 and len(pos) > _CHUNK:  # per frame: in pieces, no whole-song float64 copies
        pieces = [motion_arrays(_Piece(sk, fps, pos[a: a + _CHUNK])) for a in range(0, len(pos), _CHUNK)]
        return {**pieces[0], "positions": np.concatenate([piece["positions"] for piece in pieces])}
    pos = np.asarray(pos, dtype=np.float64)
    parents = list(sk.parents)
    up_axis, unit_scale = sk.up_axis, sk.unit_scale
    if pos.shape[2] == 2:  # image space -> plane z = 0, a 1.75 m figure
        pos = np.concatenate([pos, np.zeros(pos.shape[:2] + (1,))], axis=2)
        ui = sk.up_index
        extent = np.median(pos[:, :, ui].max(axis=1) - pos[:, :, ui].min(axis=1))
        unit_scale = 1.75 / extent if extent > 0 else 1.0

    sides = [_side_of(n) for n in sk.joint_names]  # by name when a joint is in no mirror pair
    for a, b in sk.left_right:
        ia, ib = sk.index(a), sk.index(b)
        sa, sb = _side_of(a), _side_of(b)
        # pairs are (left, right); names decide when they say otherwise
        sides[ia], sides[ib] = (sa, sb) if sa and sb and sa != sb else (1, -1)

    head = sk.index("head") if sk.has("head") else None
    extra = []  # (T, 3) virtual joints
    root = sk.root
    if not sk.has("neck") and sk.has("left_shoulder") and sk.has("right_shoulder"):
        ls, rs = sk.index("left_shoulder"), sk.index("right_shoulder")
        neck = len(parents)
        extra.append(0.5 * (pos[:, ls] + pos[:, rs]))
        torso = sk.index("pelvis") if sk.has("pelvis") else root
        parents.append(torso)
        sides.append(0)
        for j in (ls, rs) + ((head,) if head is not None else ()):
            if parents[j] == torso:
                parents[j] = neck
    drop: set[int] = set()
    if head is not None:
        twin = [
            b if a == sk.joint_names[head] else a for a, b in sk.left_right if sk.joint_names[head] in (a, b)
        ]
        if twin:  # two head-side markers: one disc at their midpoint replaces both
            t = sk.index(twin[0])
            centre = len(parents)
            extra.append(0.5 * (pos[:, head] + pos[:, t]))
            parents.append(parents[t] if parents[head] == t else parents[head])
            sides.append(0)
            drop = {head, t}
            head = centre
    if extra:
        pos = np.concatenate([pos, np.stack(extra, axis=1)], axis=1)
    if drop:
        pos, parents, sides, head = _drop_joints(pos, parents, sides, head, drop)
    return {
        "positions": pos.astype(np.float32),
        "parents": np.asarray(parents, dtype=np.int64),
        "fps": fps,
        "up_axis": up_axis,
        "unit_scale": float(unit_scale),
        "sides": np.asarray(sides, dtype=np.int8),
        "head": head,
    }
