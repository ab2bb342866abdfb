"""Forward and inverse kinematics on a :class:`~dancekit.motion.skeleton.Skeleton` tree (pure torch).

Conventions (as in :mod:`dancekit.motion.rotations`): column vectors,
``rotations[..., j, :, :]`` is joint j's rotation **local** to its parent's
frame, and it rotates the rest offsets of j's **children** (the BVH
convention). Global rotations compose ``G[j] = G[parent[j]] @ R[j]`` and
positions ``p[j] = p[parent[j]] + G[parent[j]] @ offsets[j]``; the root is
placed at ``root_translation`` and oriented by ``R[root]``.

Rotations live on the skeleton's **rig** (:meth:`Skeleton.rig`): the
skeleton's J joints first, then one zero-offset virtual *branch joint* per
child of each joint in ``skeleton.branch_joints`` (tang2018: the pelvis, whose
five children, head, shoulders and hips, move relative to each other because
the data has no spine joint). With one rotation per joint, a joint with several
children can only be fitted in the least-squares sense when their layout is
not rigid (2.2-3.6 cm mean error per joint on tang2018, 4-6 cm at the head);
a branch joint gives each child bone its own rotation, so every real bone hangs
from a joint that rotates for it alone. Skeletons without branch joints (SMPL,
BODY_25, BVH files) are their own rig and nothing changes for them.

Inverse kinematics here is position-based bone-direction alignment (no
optimisation loop): for each rig joint, parents first, the local rotation that
maps the rest directions of its child bones onto the observed ones. Zero-offset
single-child joints (branch joints) are looked through: a joint aligns the
first non-zero bone below each of them. So the tang2018 pelvis gets the
least-squares (Kabsch) fit of its five bones, i.e. the body's orientation, and
each branch joint the smallest rotation that corrects its bone from there. The
result is exact: ``rig_forward_kinematics(*inverse_kinematics(p, sk), sk)``
equals ``normalize_bone_lengths(p, sk)`` (to float precision) at every joint
whose ancestors each have a single child bone, looking through branch joints
(every joint of tang2018); the residual elsewhere (zero on tang2018, and for
rigid input such as SMPL or BVH rotations) is reported by :func:`ik_residual`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from dancekit.errors import ParameterError
from dancekit.motion.skeleton import Skeleton, parents_first_order

__all__ = [
    "forward_kinematics",
    "ik_residual",
    "inverse_kinematics",
    "normalize_bone_lengths",
    "rig_forward_kinematics",
    "rig_rotations",
]


def _as_tensor(x, name: str, dtype=None) -> torch.Tensor:
    if isinstance(x, torch.Tensor):
        return x if dtype is None else x.to(dtype)
    try:
        arr = np.asarray(x)
        if not arr.flags.writeable:
            arr = arr.copy()
        return torch.as_tensor(arr, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be an array, got {type(x).__name__}") from exc


def _order(parents: Sequence[int]) -> list[int]:
    parents = tuple(int(p) for p in parents)
    order = parents_first_order(parents)
    if len(order) != len(parents) or sum(p == -1 for p in parents) != 1:
        raise ParameterError("parents must describe a tree with one root (-1)")
    return order


def forward_kinematics(
    rotations: torch.Tensor,
    root_translation: torch.Tensor,
    *,
    offsets: torch.Tensor | np.ndarray,
    parents: Sequence[int],
) -> torch.Tensor:
    """Joint positions from local rotations and the root translation.

    Parameters
    ----------
    rotations : torch.Tensor, shape (..., J, 3, 3)
        Local joint rotations (column-vector convention).
    root_translation : torch.Tensor, shape (..., 3)
        World position of the root joint, in skeleton units.
    offsets : array, shape (J, 3)
        Rest offsets of each joint from its parent (root's is ignored).
    parents : sequence of int, length J
        Parent indices, ``-1`` for the root (any order; a topological order is computed).

    Returns
    -------
    torch.Tensor, shape (..., J, 3)
        World positions, dtype of ``rotations``.

    Raises
    ------
    ParameterError
        On inconsistent shapes.
    """
    rotations = _as_tensor(rotations, "rotations")
    J = len(parents)
    if rotations.dim() < 3 or tuple(rotations.shape[-3:]) != (J, 3, 3):
        raise ParameterError(f"rotations must have shape (..., {J}, 3, 3), got {tuple(rotations.shape)}")
    lead = rotations.shape[:-3]
    root_translation = _as_tensor(root_translation, "root_translation", rotations.dtype)
    if tuple(root_translation.shape) != tuple(lead) + (3,):
        raise ParameterError(
            f"root_translation must have shape {tuple(lead) + (3,)}, got {tuple(root_translation.shape)}"
        )
    offsets = _as_tensor(offsets, "offsets", rotations.dtype).to(rotations.device)
    if tuple(offsets.shape) != (J, 3):
        raise ParameterError(f"offsets must have shape ({J}, 3), got {tuple(offsets.shape)}")
    order = _order(parents)
    glob: list[torch.Tensor | None] = [None] * J
    pos: list[torch.Tensor | None] = [None] * J
    for j in order:
        p = parents[j]
        if p < 0:
            glob[j] = rotations[..., j, :, :]
            pos[j] = root_translation
        else:
            gp = glob[p]
            glob[j] = gp @ rotations[..., j, :, :]
            pos[j] = pos[p] + (gp @ offsets[j, :, None])[..., 0]
    return torch.stack(pos, dim=-2)  # type: ignore[arg-type]


def rig_rotations(rotations, skeleton: Skeleton):
    """Rotations on ``skeleton.rig()``: rig rotations unchanged, per-joint rotations with identity branch joints.

    Rotations of the skeleton's own J joints (``(..., J, 3, 3)``) are the
    rig's rotations with every branch joint at the identity (the same pose), so
    both layouts are accepted wherever rotations are.

    Parameters
    ----------
    rotations : torch.Tensor or np.ndarray, shape (..., J, 3, 3) or (..., J_rig, 3, 3)
    skeleton : Skeleton

    Returns
    -------
    Same array type, shape (..., J_rig, 3, 3), ``J_rig = skeleton.rig().num_joints``.

    Raises
    ------
    ParameterError
        If the shape is neither.
    """
    J, Jr = skeleton.num_joints, skeleton.rig().num_joints
    shape = tuple(rotations.shape)
    if len(shape) < 3 or shape[-2:] != (3, 3) or shape[-3] not in (J, Jr):
        expect = f"(..., {Jr}, 3, 3)" + (f" or (..., {J}, 3, 3)" if Jr != J else "")
        raise ParameterError(f"rotations must have shape {expect} for skeleton {skeleton.name!r}, got {shape}")
    if shape[-3] == Jr:
        return rotations
    if isinstance(rotations, torch.Tensor):
        eye = torch.eye(3, dtype=rotations.dtype, device=rotations.device).expand(shape[:-3] + (Jr - J, 3, 3))
        return torch.cat([rotations, eye], dim=-3)
    rotations = np.asarray(rotations)
    eye = np.broadcast_to(np.eye(3, dtype=rotations.dtype), shape[:-3] + (Jr - J, 3, 3))
    return np.concatenate([rotations, eye], axis=-3)


def rig_forward_kinematics(rotations, root_translation, skeleton: Skeleton) -> torch.Tensor:
    """Positions of the skeleton's joints from rotations on its rig (see :func:`rig_rotations`).

    Parameters
    ----------
    rotations : torch.Tensor or np.ndarray, shape (..., J_rig, 3, 3) or (..., J, 3, 3)
        Local rotations on ``skeleton.rig()`` (or on the skeleton itself:
        branch joints at the identity), e.g. from :func:`inverse_kinematics`.
    root_translation : shape (..., 3)
        World position of the root, in skeleton units.
    skeleton : Skeleton

    Returns
    -------
    torch.Tensor, shape (..., J, 3)
        World positions of the J real joints (branch joints coincide with their parent and are dropped).

    Raises
    ------
    ParameterError
        On inconsistent shapes.
    """
    rotations = rig_rotations(_as_tensor(rotations, "rotations"), skeleton)
    rig = skeleton.rig()
    pos = forward_kinematics(rotations, root_translation, offsets=rig.offsets, parents=rig.parents)
    return pos[..., : skeleton.num_joints, :]


def _skeleton_offsets(skeleton: Skeleton, dtype: torch.dtype) -> torch.Tensor:
    return torch.tensor(np.array(skeleton.offsets), dtype=dtype)


def _minimal_rotation(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Smallest rotation ``(..., 3, 3)`` taking unit vectors ``a`` onto unit vectors ``b`` ``(..., 3)``."""
    from dancekit.motion.rotations import quaternion_to_matrix

    c = (a * b).sum(-1, keepdim=True)
    axis = torch.linalg.cross(a, b, dim=-1)
    q = torch.cat([1.0 + c, axis], dim=-1)
    opposite = (1.0 + c) < 1e-9
    if bool(opposite.any()):
        # rotate by π about any axis perpendicular to a
        ex = torch.zeros_like(a)
        ex[..., 0] = 1.0
        ey = torch.zeros_like(a)
        ey[..., 1] = 1.0
        helper = torch.where(a[..., :1].abs() < 0.9, ex, ey)
        perp = torch.linalg.cross(a, helper, dim=-1)
        perp = perp / perp.norm(dim=-1, keepdim=True)
        q = torch.where(opposite, torch.cat([torch.zeros_like(c), perp], dim=-1), q)
    return quaternion_to_matrix(q)


def _kabsch(rest: torch.Tensor, obs: torch.Tensor, weights: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Best rotation R (..., 3, 3) with R @ rest_c ≈ obs_c; also whether the fit is well-posed.

    rest: (C, 3), obs: (..., C, 3), weights: (C,).
    """
    H = torch.einsum("c,...ci,cj->...ij", weights, obs, rest)  # (..., 3, 3) = Σ w obs restᵀ
    U, S, Vh = torch.linalg.svd(H)
    d = torch.sign(torch.linalg.det(U @ Vh))
    d = torch.where(d == 0, torch.ones_like(d), d)
    D = torch.ones(U.shape[:-1], dtype=U.dtype, device=U.device)
    D[..., -1] = d
    R = U @ (D[..., :, None] * Vh)
    ok = S[..., 1] > 1e-6 * S[..., 0].clamp_min(1e-30)
    return R, ok


def inverse_kinematics(positions, skeleton: Skeleton):
    """Local rotations on ``skeleton.rig()`` and the root translation whose FK follows the observed bones.

    For each joint of the rig (parents first) with child bones, the local
    rotation maps the rest directions of its child bones onto the observed
    directions expressed in the parent's (already solved) frame. A
    zero-offset child with a single child (a branch joint) is looked through:
    the bone below it counts as the joint's own child bone.

    - one child bone: the smallest such rotation (no twist about the bone);
    - several: the weighted Kabsch/SVD best fit, weighting each bone by
      (rest length)² x (joints in its subtree), i.e. minimising the squared
      position error summed over all joints; if the observed directions are
      degenerate (collinear), the smallest rotation for the heaviest bone is
      used instead;
    - leaves (and bones whose observed or rest length is zero): identity.

    On the tang2018 rig the pelvis gets the Kabsch fit of its five bones (the
    body's orientation) and each of its branch joints the smallest rotation
    that takes its bone from there onto the observed one.

    ``rig_forward_kinematics`` of the result equals
    ``normalize_bone_lengths(positions, skeleton)`` exactly (to float
    precision) at every joint whose ancestors each have a single child bone
    (looking through branch joints), i.e. at every joint of tang2018; below a
    multi-child joint that is not a branch joint (SMPL's pelvis and upper
    spine) the least-squares residual moves that child's subtree (zero for
    rigid input, such as SMPL or BVH rotations).

    Parameters
    ----------
    positions : torch.Tensor or np.ndarray, shape (..., J, 3)
        World positions of the skeleton's J joints, in skeleton units (3D skeletons only).
    skeleton : Skeleton

    Returns
    -------
    rotations : shape (..., J_rig, 3, 3)
        Local rotations on ``skeleton.rig()`` (``J_rig == J`` for a skeleton
        without branch joints; 28 for tang2018), same array type as
        ``positions`` (float64 for NumPy input).
    root_translation : shape (..., 3)
        ``positions[..., root, :]``.

    Raises
    ------
    ParameterError
        On a 2D skeleton or a shape mismatch.

    Examples
    --------
    >>> sk = get_skeleton("tang2018")
    >>> R, tr = inverse_kinematics(positions, sk)   # (T, 28, 3, 3), (T, 3)
    >>> fk = rig_forward_kinematics(R, tr, sk)      # (T, 23, 3) == normalize_bone_lengths(positions, sk)
    """
    is_numpy = not isinstance(positions, torch.Tensor)
    x = _as_tensor(positions, "positions")
    if is_numpy or not x.is_floating_point():
        x = x.to(torch.float64)
    J = skeleton.num_joints
    if skeleton.dims != 3:
        raise ParameterError(f"inverse kinematics needs a 3D skeleton, {skeleton.name!r} is 2D")
    if x.dim() < 2 or tuple(x.shape[-2:]) != (J, 3):
        raise ParameterError(f"positions must have shape (..., {J}, 3) for skeleton {skeleton.name!r}, got {tuple(x.shape)}")
    rig = skeleton.rig()
    if rig.num_joints > J:  # branch joints sit at their parent
        x = torch.cat([x, x[..., list(rig.parents[J:]), :]], dim=-2)
    rotations = _align_bones(x, rig)
    root_translation = x[..., skeleton.root, :]
    if is_numpy:
        return rotations.numpy(), root_translation.numpy().copy()
    return rotations, root_translation


def _align_bones(x: torch.Tensor, skeleton: Skeleton) -> torch.Tensor:
    """Bone-direction IK on one tree: positions (..., J, 3) -> local rotations (..., J, 3, 3)."""
    J = skeleton.num_joints
    lead = x.shape[:-2]
    offsets = _skeleton_offsets(skeleton, x.dtype).to(x.device)
    rest_len = offsets.norm(dim=-1)
    parents = skeleton.parents
    eps = 1e-9
    zero = [float(n) <= eps for n in rest_len]
    children = {j: skeleton.children(j) for j in range(J)}

    def bone_end(c: int) -> int | None:
        # look through zero-offset single-child joints (branch joints) to the first real bone
        while zero[c] and len(children[c]) == 1:
            c = children[c][0]
        return None if zero[c] else c

    subtree = _subtree_sizes(parents)
    eye = torch.eye(3, dtype=x.dtype, device=x.device).expand(tuple(lead) + (3, 3))
    local: list[torch.Tensor] = [eye] * J
    glob: list[torch.Tensor] = [eye] * J
    for j in skeleton.topological_order:
        p = parents[j]
        gp = glob[p] if p >= 0 else eye
        kids = [e for e in (bone_end(c) for c in children[j]) if e is not None]
        if kids:
            vec = x[..., kids, :] - x[..., j : j + 1, :]  # (..., C, 3) world
            n = vec.norm(dim=-1, keepdim=True)
            valid = n > eps
            d_world = vec / n.clamp_min(eps)
            d_local = torch.einsum("...ji,...cj->...ci", gp, d_world)  # gpᵀ d
            rest = offsets[kids] / rest_len[kids, None]
            if len(kids) == 1:
                R = _minimal_rotation(rest[0].expand_as(d_local[..., 0, :]), d_local[..., 0, :])
                R = torch.where(valid[..., 0, :, None], R, eye)
            else:
                w = rest_len[kids] ** 2 * torch.as_tensor([subtree[c] for c in kids], dtype=x.dtype, device=x.device)
                # zero-length observed bones get zero weight per frame
                d_fit = torch.where(valid, d_local, torch.zeros_like(d_local))
                R, ok = _kabsch(rest, d_fit, w)
                heavy = int(torch.argmax(w))
                R1 = _minimal_rotation(rest[heavy].expand_as(d_local[..., heavy, :]), d_local[..., heavy, :])
                R1 = torch.where(valid[..., heavy, :, None], R1, eye)
                R = torch.where(ok[..., None, None], R, R1)
            local[j] = R
            glob[j] = gp @ R
        else:
            glob[j] = gp
    return torch.stack(local, dim=-3)


def _subtree_sizes(parents: Sequence[int]) -> list[int]:
    J = len(parents)
    size = [1] * J
    for j in reversed(_order(parents)):
        if parents[j] >= 0:
            size[parents[j]] += size[j]
    return size


def normalize_bone_lengths(positions, skeleton: Skeleton):
    """Positions with every bone set to its rest length, keeping observed bone directions.

    The root stays where it is; each joint is placed at its (already
    normalised) parent plus ``rest_length * unit(observed bone)``. A bone of
    zero observed length takes its rest offset unrotated.

    Parameters
    ----------
    positions : torch.Tensor or np.ndarray, shape (..., J, 3) or (..., J, 2)
    skeleton : Skeleton

    Returns
    -------
    Same type and shape as ``positions`` (float64 for NumPy input).
    """
    is_numpy = not isinstance(positions, torch.Tensor)
    x = _as_tensor(positions, "positions")
    if is_numpy or not x.is_floating_point():
        x = x.to(torch.float64)
    J = skeleton.num_joints
    D = x.shape[-1] if x.dim() >= 2 else -1
    if x.dim() < 2 or x.shape[-2] != J or D not in (2, 3):
        raise ParameterError(f"positions must have shape (..., {J}, 3|2) for skeleton {skeleton.name!r}, got {tuple(x.shape)}")
    offsets = _skeleton_offsets(skeleton, x.dtype).to(x.device)[:, :D]
    rest_len = torch.as_tensor(np.linalg.norm(skeleton.offsets[:, :D], axis=-1), dtype=x.dtype, device=x.device)
    out: list[torch.Tensor | None] = [None] * J
    for j in skeleton.topological_order:
        p = skeleton.parents[j]
        if p < 0:
            out[j] = x[..., j, :]
            continue
        v = x[..., j, :] - x[..., p, :]
        n = v.norm(dim=-1, keepdim=True)
        d = torch.where(n > 1e-9, v / n.clamp_min(1e-9) * rest_len[j], offsets[j].expand_as(v))
        out[j] = out[p] + d
    res = torch.stack(out, dim=-2)  # type: ignore[arg-type]
    return res.numpy() if is_numpy else res


def ik_residual(positions, skeleton: Skeleton) -> np.ndarray:
    """Per-joint error ``(..., J)`` of ``FK(IK(positions))`` against ``normalize_bone_lengths(positions)``.

    Zero (to float precision) wherever IK is exact (every joint of a skeleton
    whose multi-child joints are branch joints, e.g. tang2018); elsewhere the
    size of the least-squares residual at multi-child joints. Units of the skeleton.
    """
    x = torch.as_tensor(np.asarray(positions), dtype=torch.float64)
    R, t = inverse_kinematics(x, skeleton)
    fk = rig_forward_kinematics(R, t, skeleton)
    ref = normalize_bone_lengths(x, skeleton)
    return (fk - ref).norm(dim=-1).numpy()
