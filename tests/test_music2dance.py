"""Music2Dance (paper §4.4): the rotations_rootdelta representation, the WaveNet generator, its GMM head,
incremental generation, the training objective and the pipeline. Tiny configurations, CPU, float64 maths."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancekit.motion import Motion, get_skeleton
from dancekit.motion.representations import decode_motion, encode_motion, pose_dim
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta, rootdelta_layout
from dancekit.motion.rotations import axis_angle_to_matrix, euler_angles_to_matrix

SK = get_skeleton("tang2018")


def _random_motion(rng: np.random.Generator, T: int = 120) -> Motion:
    """Random rig rotations (up to ~70° per joint), a wandering root that turns through ±π, tilts up to ~30°."""
    Jr = SK.rig().num_joints
    R = axis_angle_to_matrix(torch.from_numpy(rng.normal(0, 0.7, (T, Jr, 3)))).numpy()
    heading = np.cumsum(rng.normal(0.15, 0.3, T)) + 3.0  # crosses ±π several times
    tilt = rng.normal(0, 0.25, (T, 2))
    R[:, SK.root] = euler_angles_to_matrix(torch.from_numpy(np.stack([heading, tilt[:, 0], tilt[:, 1]], -1)),
                                           "YXZ").numpy()
    tr = np.cumsum(rng.normal(0, 3.0, (T, 3)), axis=0)
    tr[:, 1] = 90 + rng.normal(0, 2, T)
    return Motion(skeleton=SK, fps=25.0, rotations=R, root_translation=tr)


def test_rootdelta_layout_of_tang2018():
    lay = rootdelta_layout(SK)
    assert lay.dim == pose_dim(SK, "rotations_rootdelta") == 6 + 6 * 22 + 3 * 5 + 2 == 155
    assert lay.contact_cols == (153, 154)
    assert [SK.joint_names[j] for j in lay.end_effectors] == ["head_left", "left_toe", "right_toe", "left_aux",
                                                              "right_aux"]
    assert SK.root not in lay.rot_joints and all(SK.rig().children(j) for j in lay.rot_joints)


def test_rootdelta_round_trip_is_exact(rng):
    """Deltas integrate back to the trajectory and rotations give the positions, to 1e-4 cm (float64)."""
    m = _random_motion(rng)
    x = encode_rootdelta(m)
    heading0 = float(np.arctan2(m.rotations[0, SK.root, 0, 2], m.rotations[0, SK.root, 2, 2]))  # YXZ: atan2(R02, R22)
    back = decode_rootdelta(x, SK, 25.0, origin=(m.root_translation[0, 0], m.root_translation[0, 2], heading0))
    np.testing.assert_allclose(back.root_translation, m.root_translation, atol=1e-4)
    np.testing.assert_allclose(back.to_positions(), m.to_positions(), atol=1e-4)
    lay = rootdelta_layout(SK)
    np.testing.assert_allclose(back.rotations[:, list(lay.rot_joints)], m.rotations[:, list(lay.rot_joints)],
                               atol=1e-9)
    # heading deltas are wrapped: no 2π jumps although the heading crosses ±π
    assert np.abs(x[:, 3]).max() < 2.0


def test_rootdelta_decodes_from_the_origin_facing_forward(rng):
    """Default decoding = the dance moved to the origin and turned to face +z at frame 0 (a rigid motion)."""
    m = _random_motion(rng, T=60)
    back = decode_motion(encode_motion(m, "rotations_rootdelta"), SK, 25.0, "rotations_rootdelta")  # float32 path
    p, q = m.to_positions().astype(np.float64), back.to_positions().astype(np.float64)
    a = np.arctan2(m.rotations[0, SK.root, 0, 2], m.rotations[0, SK.root, 2, 2])
    c, s = np.cos(-a), np.sin(-a)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    shift = np.array([m.root_translation[0, 0], 0.0, m.root_translation[0, 2]])
    np.testing.assert_allclose(q, (p - shift) @ Ry.T, atol=2e-3)  # float32 features: ~1e-5 relative


def test_rootdelta_end_effectors_are_root_relative_in_the_heading_frame(rng):
    m = _random_motion(rng, T=10)
    x = encode_rootdelta(m)
    lay = rootdelta_layout(SK)
    toe = SK.index("left_toe")
    pos = m.to_positions()
    a = np.arctan2(m.rotations[:, SK.root, 0, 2], m.rotations[:, SK.root, 2, 2])
    rel = pos[:, toe] - m.root_translation
    local_x = np.cos(a) * rel[:, 0] - np.sin(a) * rel[:, 2]  # R_Y(a)ᵀ rel, x component
    np.testing.assert_allclose(x[:, list(lay.end_effector_col(toe))][:, 0], local_x, atol=1e-9)
    np.testing.assert_allclose(x[:, list(lay.end_effector_col(toe))][:, 1], rel[:, 1], atol=1e-9)


# Hand-checked from the printed toe heights (cm above the running floor) and speeds (cm/s) of the raw
# tang2018 markers (commit message of this test): (dance, foot, first frame, end frame, in contact?)
CONTACT_FIXTURE = [
    ("DANCE_R_4", 0, 464, 485, 1),  # left toe 0.7-1.8 cm up, 0.6-15 cm/s: planted
    ("DANCE_R_4", 0, 405, 413, 0),  # left toe gliding at 190-460 cm/s, 0.2-3.6 cm up: a step, not a contact
    ("DANCE_R_4", 0, 487, 496, 0),  # 90-400 cm/s
    ("DANCE_R_4", 0, 499, 520, 1),  # 0.3-1.0 cm up, 3-11 cm/s
    ("DANCE_R_4", 1, 442, 467, 1),  # right toe 0.6-2.5 cm up, 2-10 cm/s
    ("DANCE_R_4", 1, 425, 433, 0),  # 77-440 cm/s
    ("DANCE_R_4", 1, 506, 519, 0),  # 66-263 cm/s
    ("DANCE_W_10", 0, 1000, 1004, 0),  # left toe 147-152 cm up (a kick); slow (17 cm/s) at the top: height rules
]


def test_contacts_on_real_dances_match_the_hand_checked_fixture(tang2018_dir):
    from dancekit.motion.formats import read_tang2018

    for dance in sorted({d for d, *_ in CONTACT_FIXTURE}):
        motion, _ = read_tang2018(tang2018_dir / dance)
        contacts = encode_motion(motion, "rotations_rootdelta")[:, -2:]
        assert set(np.unique(contacts)) <= {0.0, 1.0}
        assert 0.1 < contacts.mean() < 0.8  # the thresholds flag a plausible share of frames
        for d, foot, start, end, expected in CONTACT_FIXTURE:
            if d == dance:
                got = contacts[start:end, foot]
                assert (got == expected).all(), f"{dance} foot {foot} frames {start}-{end}: {got}"
