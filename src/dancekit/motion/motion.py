"""The :class:`Motion` container: a skeleton, a frame rate and per-frame poses."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancekit._checks import check_fps
from dancekit.errors import ParameterError
from dancekit.motion.analysis import resample_indices, resample_positions
from dancekit.motion.skeleton import Skeleton, get_skeleton

__all__ = ["Motion"]

_VIEWS = ("front", "back", "left", "right")

#: Frames per inverse-kinematics call in :meth:`Motion.with_rotations` (IK is per frame: a long song's is
#: solved in chunks so that its float64 work arrays do not grow with the song).
IK_CHUNK = 4096


def _float_array(x, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if not np.issubdtype(arr.dtype, np.floating):
        try:
            arr = arr.astype(np.float64)
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"{name} must be a numeric array, got dtype {arr.dtype}") from exc
    return arr


@dataclass(eq=False)
class Motion:
    """A dance: poses at a fixed frame rate on a :class:`Skeleton`.

    At least one of ``positions`` and ``rotations`` is given. Arrays keep their
    float dtype (float32 or float64; integers become float64).

    Parameters
    ----------
    skeleton : Skeleton
    fps : float
        Frames per second (> 0). Frame ``i`` is at ``i / fps`` seconds.
    positions : np.ndarray, shape (T, J, 3) or (T, J, 2), optional
        World joint positions in skeleton units (2D for image skeletons).
    rotations : np.ndarray, shape (T, J_rig, 3, 3) or (T, J, 3, 3), optional
        Local joint rotations on the skeleton's rig, ``skeleton.rig()`` (its J
        joints, then its zero-offset branch joints: ``J_rig`` is 28 for
        tang2018, ``J`` for skeletons without branch joints); see
        :mod:`dancekit.motion.kinematics`. Rotations of the J joints alone are
        accepted and stored with identity branch joints (the same pose).
    root_translation : np.ndarray, shape (T, 3), optional
        World position of the root; required with ``rotations`` unless
        ``positions`` are given (then it defaults to the root's positions).

    Raises
    ------
    ParameterError
        On a bad fps, wrong shapes, mismatched frame counts or non-finite values.

    Examples
    --------
    >>> from dancekit.motion import Motion, get_skeleton
    >>> sk = get_skeleton("tang2018")
    >>> m = Motion(skeleton=sk, fps=25, positions=np.zeros((50, 23, 3), np.float32))
    >>> m.num_frames, m.duration
    (50, 2.0)
    """

    skeleton: Skeleton
    fps: float
    positions: np.ndarray | None = None
    rotations: np.ndarray | None = None
    root_translation: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.skeleton, Skeleton):
            raise ParameterError(f"skeleton must be a Skeleton, got {type(self.skeleton).__name__}")
        self.fps = check_fps(self.fps)
        sk = self.skeleton
        J, D = sk.num_joints, sk.dims
        if self.positions is None and self.rotations is None:
            raise ParameterError("a Motion needs positions or rotations")
        T = None
        if self.positions is not None:
            pos = _float_array(self.positions, "positions")
            if pos.ndim != 3 or pos.shape[1:] != (J, D):
                raise ParameterError(
                    f"positions must have shape (T, {J}, {D}) for skeleton {sk.name!r}, got {pos.shape}"
                )
            if not np.all(np.isfinite(pos)):
                bad = np.argwhere(~np.isfinite(pos))[0]
                raise ParameterError(f"positions contain NaN/inf (first at frame {bad[0]}, joint {bad[1]})")
            self.positions = pos
            T = pos.shape[0]
        if self.rotations is not None:
            if D != 3:
                raise ParameterError(f"rotations need a 3D skeleton, {sk.name!r} is 2D")
            rot = _float_array(self.rotations, "rotations")
            Jr = sk.rig().num_joints
            if rot.ndim != 4 or rot.shape[1:] not in ((J, 3, 3), (Jr, 3, 3)):
                also = f" (or (T, {J}, 3, 3) without its branch joints)" if Jr != J else ""
                raise ParameterError(
                    f"rotations must have shape (T, {Jr}, 3, 3) for skeleton {sk.name!r}{also}, got {rot.shape}"
                )
            if rot.shape[1] != Jr:  # the same pose with identity branch joints (kinematics.rig_rotations)
                eye = np.broadcast_to(np.eye(3, dtype=rot.dtype), (rot.shape[0], Jr - J, 3, 3))
                rot = np.concatenate([rot, eye], axis=1)
            if T is not None and rot.shape[0] != T:
                raise ParameterError(f"rotations have {rot.shape[0]} frames but positions have {T}")
            if not np.all(np.isfinite(rot)):
                raise ParameterError("rotations contain NaN/inf")
            self.rotations = rot
            T = rot.shape[0]
        if self.root_translation is not None:
            tr = _float_array(self.root_translation, "root_translation")
            if tr.shape != (T, 3):
                raise ParameterError(f"root_translation must have shape ({T}, 3), got {tr.shape}")
            if not np.all(np.isfinite(tr)):
                raise ParameterError("root_translation contains NaN/inf")
            self.root_translation = tr
        elif self.rotations is not None:
            if self.positions is None:
                raise ParameterError("rotations need a root_translation (T, 3) when positions are not given")
            self.root_translation = self.positions[:, sk.root, :].astype(self.rotations.dtype)

    # ------------------------------------------------------------------ basics
    @property
    def num_frames(self) -> int:
        """Number of frames T."""
        arr = self.positions if self.positions is not None else self.rotations
        assert arr is not None
        return int(arr.shape[0])

    @property
    def duration(self) -> float:
        """Duration in seconds, ``num_frames / fps``."""
        return self.num_frames / self.fps

    @property
    def times(self) -> np.ndarray:
        """``(T,)`` time of each frame in seconds (``i / fps``)."""
        return np.arange(self.num_frames) / self.fps

    def __repr__(self) -> str:
        have = [k for k in ("positions", "rotations", "root_translation") if getattr(self, k) is not None]
        return (f"Motion(skeleton={self.skeleton.name!r}, fps={self.fps:g}, frames={self.num_frames}, "
                f"duration={self.duration:.2f}s, has={have})")

    # -------------------------------------------------------------- kinematics
    def to_positions(self) -> np.ndarray:
        """World positions ``(T, J, 3|2)``: stored ones, else forward kinematics of the rotations on the rig."""
        if self.positions is not None:
            return self.positions
        import torch

        from dancekit.motion.kinematics import rig_forward_kinematics

        assert self.rotations is not None and self.root_translation is not None
        pos = rig_forward_kinematics(
            torch.from_numpy(np.ascontiguousarray(self.rotations)),
            torch.from_numpy(np.ascontiguousarray(self.root_translation, dtype=self.rotations.dtype)),
            self.skeleton,
        )
        return pos.numpy()

    def with_positions(self) -> Motion:
        """This motion with ``positions`` filled in (forward kinematics if needed)."""
        if self.positions is not None:
            return self
        return Motion(self.skeleton, self.fps, self.to_positions(), self.rotations, self.root_translation)

    def with_rotations(self) -> Motion:
        """This motion with ``rotations`` and ``root_translation`` (inverse kinematics if needed).

        Positions are kept as they are. The rotations, on ``skeleton.rig()``
        (``(T, J_rig, 3, 3)``), follow every bone direction, so their forward
        kinematics is the positions with the rest bone lengths
        (:func:`dancekit.motion.kinematics.inverse_kinematics`,
        :func:`~dancekit.motion.kinematics.normalize_bone_lengths`). They get
        the dtype of the positions.

        Raises
        ------
        ParameterError
            For a 2D motion.
        """
        if self.rotations is not None:
            return self
        from dancekit.motion.kinematics import inverse_kinematics

        assert self.positions is not None
        pos, dt, sk = self.positions, self.positions.dtype, self.skeleton
        if len(pos) <= IK_CHUNK:
            rot, tr = inverse_kinematics(pos.astype(np.float64), sk)
            return Motion(sk, self.fps, pos, rot.astype(dt), tr.astype(dt))
        # IK is per frame: IK_CHUNK frames at a time, so the float64 work arrays (a few times the
        # (T, J_rig, 3, 3) rotations) stay the size of a chunk; the same numbers as one call
        rot = np.empty((len(pos), sk.rig().num_joints, 3, 3), dt)
        tr = np.empty((len(pos), 3), dt)
        for a in range(0, len(pos), IK_CHUNK):
            r, t = inverse_kinematics(pos[a: a + IK_CHUNK].astype(np.float64), sk)
            rot[a: a + IK_CHUNK], tr[a: a + IK_CHUNK] = r, t
        return Motion(sk, self.fps, pos, rot, tr)

    # ------------------------------------------------------------------ timing
    def resample(self, fps: float) -> Motion:
        """The motion at another frame rate.

        New frame ``k`` is at ``k / fps`` seconds, for every such time up to
        the last original frame (no extrapolation): ``floor((T - 1) * fps /
        self.fps) + 1`` frames. Positions and root translation are
        interpolated linearly, rotations by quaternion slerp.

        Raises
        ------
        ParameterError
            If ``fps`` is not a positive number.
        """
        new_fps = check_fps(fps)
        i0, i1, w = resample_indices(self.num_frames, orig_fps=self.fps, target_fps=new_fps)
        n = len(w)

        def lerp(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else resample_positions(a, orig_fps=self.fps, target_fps=new_fps)

        rot = None
        if self.rotations is not None:
            import torch

            from dancekit.motion.rotations import matrix_to_quaternion, quaternion_slerp, quaternion_to_matrix

            R = torch.from_numpy(self.rotations.astype(np.float64))
            q = matrix_to_quaternion(R)
            tt = torch.from_numpy(w)[:, None].expand(n, R.shape[1])
            rot = quaternion_to_matrix(quaternion_slerp(q[i0], q[i1], tt)).numpy().astype(self.rotations.dtype)
        return Motion(self.skeleton, new_fps, lerp(self.positions), rot, lerp(self.root_translation))

    def slice(self, start_frame: int = 0, end_frame: int | None = None) -> Motion:
        """Frames ``start_frame`` (inclusive) to ``end_frame`` (exclusive; None = to the end).

        Negative indices count from the end, as in Python slicing.

        Raises
        ------
        ParameterError
            If the slice is empty.
        """
        T = self.num_frames
        a, b, _ = slice(start_frame, end_frame).indices(T)
        if b <= a:
            raise ParameterError(f"empty slice [{start_frame}:{end_frame}] of a {T}-frame motion")

        def cut(x: np.ndarray | None) -> np.ndarray | None:
            return None if x is None else x[a:b].copy()

        return Motion(self.skeleton, self.fps, cut(self.positions), cut(self.rotations), cut(self.root_translation))

    # --------------------------------------------------------------- geometry
    def mirror(self) -> Motion:
        """Left-right mirror image.

        3D: the world x coordinate is negated (mirror about the y-z plane, for
        both y-up and z-up skeletons) and the joints of each ``left_right``
        pair are swapped. 2D: x is reflected about the mean root x. If the
        motion had rotations, they are recomputed from the mirrored positions
        by inverse kinematics (the rest offsets need not be symmetric).
        """
        pos = self.to_positions().copy()
        perm = self.skeleton.mirror_permutation()
        if self.skeleton.dims == 3:
            pos[..., 0] = -pos[..., 0]
        else:
            cx = pos[:, self.skeleton.root, 0].mean()
            pos[..., 0] = 2 * cx - pos[..., 0]
        pos = pos[:, perm]
        out = Motion(self.skeleton, self.fps, pos)
        return out.with_rotations() if self.rotations is not None else out

    def project_2d(
        self,
        *,
        view: str = "front",
        width: int = 1280,
        height: int = 720,
        pixels_per_metre: float | None = None,
        follow: bool = True,
    ) -> Motion:
        """Orthographic projection onto an image, as a 2D motion on the ``body25`` skeleton.

        The camera looks horizontally at the scene from the world ``view``
        side ("front" = from +z towards -z for y-up skeletons; "back",
        "left" = from +x, "right" = from -x). Image x grows to the right and
        image y downwards (BODY_25 convention).

        Placement: ``pixels_per_metre`` defaults to ``height / 2.4`` (a
        1.7 m dancer is about 70 % of the image height). The lowest point of
        the whole motion sits at 90 % of the height. Horizontally, with
        ``follow=True`` (default) the camera pans with the root so the root is
        at the image centre in every frame (dancers that travel stay in view);
        with ``follow=False`` the mean root position is at the centre.

        BODY_25 points come from the skeleton's roles: shoulders, elbows,
        wrists, hips, knees, ankles directly; ``MidHip`` = mid-hips (or the
        ``pelvis`` role); ``Neck`` = the ``neck`` role, else mid-shoulders;
        ``Nose`` = the ``head`` role (tang2018: mid-point of its two head
        markers); eyes = head ± 3.5 cm along the shoulder line, 3 cm up; ears
        = head ± 7.5 cm along the shoulder line; big toes = the ``toe`` roles;
        small toes = big toe + 4 cm outwards along the shoulder line; heels =
        the ``left_heel``/``right_heel`` roles if present, else ankle - 30 % of
        (toe - ankle).

        Raises
        ------
        ParameterError
            For a 2D motion, an unknown view, a non-positive size, or a
            skeleton without the needed roles.
        """
        sk = self.skeleton
        if sk.dims != 3:
            raise ParameterError("project_2d needs a 3D motion")
        if view not in _VIEWS:
            raise ParameterError(f"view must be one of {_VIEWS}, got {view!r}")
        if width <= 0 or height <= 0:
            raise ParameterError(f"width and height must be positive, got {width}x{height}")
        ppm = height / 2.4 if pixels_per_metre is None else float(pixels_per_metre)
        if not ppm > 0:
            raise ParameterError(f"pixels_per_metre must be positive, got {pixels_per_metre!r}")
        pos = self.to_positions().astype(np.float64) * sk.unit_scale  # metres
        if sk.up_axis == "z":  # to y-up: (x, y, z) -> (x, z, -y)
            pos = np.stack([pos[..., 0], pos[..., 2], -pos[..., 1]], axis=-1)
        kp = _body25_points(pos, sk)  # (T, 25, 3) metres, y up
        # camera right vector for each view (y up)
        right = {"front": (1.0, 0.0, 0.0), "back": (-1.0, 0.0, 0.0),
                 "left": (0.0, 0.0, -1.0), "right": (0.0, 0.0, 1.0)}[view]
        u = kp @ np.asarray(right)
        v = kp[..., 1]
        root_u = pos[:, sk.root] @ np.asarray(right)
        centre = root_u[:, None] if follow else root_u.mean()
        x = (u - centre) * ppm + width / 2.0
        y = 0.9 * height - (v - pos[..., 1].min()) * ppm
        out = np.stack([x, y], axis=-1).astype(np.float32)
        return Motion(get_skeleton("body25"), self.fps, out)


def _body25_points(pos: np.ndarray, sk: Skeleton) -> np.ndarray:
    """BODY_25 keypoints (T, 25, 3) in metres (y up) from 3D positions with canonical roles."""

    def get(role: str) -> np.ndarray:
        if not sk.has(role):
            raise ParameterError(f"skeleton {sk.name!r} has no {role!r} joint, needed for the BODY_25 projection")
        return pos[:, sk.index(role)]

    ls, rs = get("left_shoulder"), get("right_shoulder")
    lh, rh = get("left_hip"), get("right_hip")
    neck = get("neck") if sk.has("neck") else 0.5 * (ls + rs)
    mid_hip = 0.5 * (lh + rh)
    if sk.has("head_left") and sk.has("head_right"):
        head = 0.5 * (get("head_left") + get("head_right"))
    else:
        head = get("head")
    lateral = ls - rs
    lateral = lateral / np.maximum(np.linalg.norm(lateral, axis=-1, keepdims=True), 1e-9)
    up = np.array([0.0, 1.0, 0.0])
    la, ra = get("left_ankle"), get("right_ankle")
    lt, rt = get("left_toe"), get("right_toe")
    lheel = get("left_heel") if sk.has("left_heel") else la - 0.3 * (lt - la)
    rheel = get("right_heel") if sk.has("right_heel") else ra - 0.3 * (rt - ra)
    pts = {
        "Nose": head, "Neck": neck,
        "RShoulder": rs, "RElbow": get("right_elbow"), "RWrist": get("right_wrist"),
        "LShoulder": ls, "LElbow": get("left_elbow"), "LWrist": get("left_wrist"),
        "MidHip": mid_hip, "RHip": rh, "RKnee": get("right_knee"), "RAnkle": ra,
        "LHip": lh, "LKnee": get("left_knee"), "LAnkle": la,
        "REye": head - 0.035 * lateral + 0.03 * up, "LEye": head + 0.035 * lateral + 0.03 * up,
        "REar": head - 0.075 * lateral, "LEar": head + 0.075 * lateral,
        "LBigToe": lt, "LSmallToe": lt + 0.04 * lateral, "LHeel": lheel,
        "RBigToe": rt, "RSmallToe": rt - 0.04 * lateral, "RHeel": rheel,
    }
    b25 = get_skeleton("body25")
    return np.stack([pts[n] for n in b25.joint_names], axis=1)
