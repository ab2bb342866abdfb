"""Forward and inverse kinematics on a :class:`~dancekit.motion.skeleton.Skeleton` tree (pure torch).

Conventions (as in :mod:`dancekit.motion.rotations`): column vectors,
``rotations[..., j, :, :]`` is joint j's rotation **local** to its parent's
frame, and it rotates the rest offsets of j's **children** (the BVH
convention). Global rotations compose ``G[j] = G[parent[j]] @ R[j]`` and
positions ``p[j] = p[parent[j]] + G[parent[j]] @ offsets[j]``; the root is
placed at ``root_translation`` and oriented by ``R[root]``.

Inverse kinematics here is position-based bone-direction alignment (no
optimisation loop): for each joint, the local rotation that maps the rest
directions of its children onto the observed ones. It is exact (up to bone
lengths) for joints with one child; for joints with several children it is
the weighted least-squares (Kabsch) fit, which cannot be exact when the
children move relative to each other (e.g. a pelvis with hips, shoulders and
head in data without spine joints): that residual is reported by
:func:`ik_residual`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from dancekit.errors import ParameterError
from dancekit.motion.skeleton import Skeleton, _topological_order

__all__ = ["forward_kinematics", "ik_residual", "inverse_kinematics", "normalize_bone_lengths"]


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
    order = _topological_order(parents)
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
    """Local rotations and root translation whose FK follows the observed bone directions.

    For each joint (parents first) with children, the local rotation maps the
    rest directions of its children onto the observed child directions
    expressed in the parent's (already solved) frame:

    - one child: the smallest such rotation (no twist about the bone);
    - several children: the weighted Kabsch/SVD best fit, weighting each child
      by (rest length)² x (joints in its subtree), i.e. minimising the squared
      position error summed over all joints; if the observed child directions
      are degenerate (collinear), the smallest rotation for the heaviest child
      is used instead;
    - leaves (and children whose observed or rest bone has zero length): identity.

    ``forward_kinematics`` of the result equals
    ``normalize_bone_lengths(positions, skeleton)`` exactly (to float
    precision) at every joint whose ancestors each have a single child; at a
    multi-child joint the least-squares residual moves that child's subtree.

    Parameters
    ----------
    positions : torch.Tensor or np.ndarray, shape (..., J, 3)
        World joint positions in skeleton units (3D skeletons only).
    skeleton : Skeleton

    Returns
    -------
    rotations : shape (..., J, 3, 3)
        Local rotations (same array type as ``positions``; float64 for NumPy input).
    root_translation : shape (..., 3)
        ``positions[..., root, :]``.

    Raises
    ------
    ParameterError
        On a 2D skeleton or a shape mismatch.
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
    lead = x.shape[:-2]
    offsets = _skeleton_offsets(skeleton, x.dtype).to(x.device)
    rest_len = offsets.norm(dim=-1)
    parents = skeleton.parents
    children = {j: [c for c in skeleton.children(j)] for j in range(J)}
    subtree = _subtree_sizes(parents)
    eye = torch.eye(3, dtype=x.dtype, device=x.device).expand(tuple(lead) + (3, 3))
    local: list[torch.Tensor] = [eye] * J
    glob: list[torch.Tensor] = [eye] * J
    eps = 1e-9
    for j in skeleton.topological_order:
        p = parents[j]
        gp = glob[p] if p >= 0 else eye
        kids = [c for c in children[j] if float(rest_len[c]) > eps]
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
    rotations = torch.stack(local, dim=-3)
    root_translation = x[..., skeleton.root, :]
    if is_numpy:
        return rotations.numpy(), root_translation.numpy().copy()
    return rotations, root_translation


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

    Zero (to float precision) below single-child chains; the size of the
    least-squares residual at multi-child joints elsewhere. Units of the skeleton.
    """
    x = torch.as_tensor(np.asarray(positions), dtype=torch.float64)
    R, t = inverse_kinematics(x, skeleton)
    fk = forward_kinematics(R, t, offsets=skeleton.offsets, parents=skeleton.parents)
    ref = normalize_bone_lengths(x, skeleton)
    return (fk - ref).norm(dim=-1).numpy()
