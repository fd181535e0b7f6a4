"""Forward kinematics of the Appendix A hand: geometry pinned by hand, signs, batching.

Expected numbers are worked out from thesis Table A.1 by hand (see the comments), never by
calling the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from digiteyes.errors import StateError
from digiteyes.kinematics import dh_transform, forward_kinematics

# Finger geometry from Table A.1, worked out by hand. With all joints zero the two constant
# rows of each finger give frame 3 (10, 17, 24): row 1's Rot_z(pi/2) Trans_x(a) turns x onto
# +y and moves a along it, its Rot_x(-pi/2) makes z point along -x; row 2's Trans_z(d) moves d
# along -x and its Rot_x(pi/2) turns z back to +z. So the anchor is (-d, a, 0), with x axis
# +y (the finger direction) and z axis +z (the abduction axis).
FINGERS = {
    # name: (first state, anchor (mm), link lengths (mm), anchor frame, tip row)
    "index": (7, (31.0, 38.0, 0.0), (45.0, 26.0, 24.0), 3, 7),
    "middle": (11, (9.0, 37.0, 0.0), (56.0, 27.0, 22.0), 10, 14),
    "ring": (15, (-6.0, 33.0, 0.0), (53.0, 25.0, 20.0), 17, 21),
    "little": (19, (-26.0, 30.0, 0.0), (38.0, 19.0, 17.0), 24, 28),
}
# Thumb (rows 29-36), by hand: row 29 gives (0, -43, 15), row 30 moves 38 along +x, so the
# thumb base (frame 31) is at (38, -43, 15); with all joints zero the thumb runs along +y:
# metacarpal 46 mm, proximal 34 mm, distal 25 mm.
THUMB_BASE = np.array([38.0, -43.0, 15.0])
THUMB_LENGTHS = (46.0, 34.0, 25.0)
# Thumb base, MP joint (frame 33), IP joint (frame 35) and tip centre at the zero state.
THUMB_POINTS = THUMB_BASE + np.array([[0.0, 0.0, 0.0], [0.0, 46.0, 0.0], [0.0, 80.0, 0.0],
                                      [0.0, 105.0, 0.0]])

# Links of the shipped model in file order: (row, start, end) at the zero state.
ZERO_LINKS = [
    (row, np.add(anchor, (0.0, start, 0.0)), np.add(anchor, (0.0, start + length, 0.0)))
    for _, anchor, lengths, frame, _ in FINGERS.values()
    for row, start, length in zip(
        (frame + 1, frame + 2, frame + 3),
        (0.0, lengths[0], lengths[0] + lengths[1]),
        lengths,
        strict=True,
    )
] + [(row, THUMB_POINTS[i], THUMB_POINTS[i + 1]) for i, row in enumerate((32, 34, 35))]


def rot_z(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def rot_x(alpha: float) -> np.ndarray:
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def trans(x: float, y: float, z: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def zero_state() -> np.ndarray:
    q = np.zeros(28)
    q[0] = 1.0
    return q


# ------------------------------------------------------------------ DH transform (eq. 2.2)
def test_dh_transform_is_product_of_elementary_transforms():
    rng = np.random.default_rng(1)
    for theta, d, a, alpha in rng.uniform(-4.0, 4.0, size=(20, 4)):
        expected = rot_z(theta) @ trans(0, 0, d) @ trans(a, 0, 0) @ rot_x(alpha)
        np.testing.assert_allclose(dh_transform(theta, d, a, alpha), expected, atol=1e-14)


def test_dh_transform_broadcasts():
    out = dh_transform(np.zeros((5, 2)), 1.0, np.arange(2.0), 0.0)
    assert out.shape == (5, 2, 4, 4)
    np.testing.assert_array_equal(out[3, 1, :3, 3], [1.0, 0.0, 1.0])


# ------------------------------------------------------------------ Appendix A, zero state
@pytest.mark.parametrize("finger", FINGERS)
def test_zero_state_mcp_anchor(hand, finger):
    _, anchor, _, frame, _ = FINGERS[finger]
    T = forward_kinematics(hand, zero_state()).T_world_frame[0, frame]
    np.testing.assert_allclose(T[:3, 3], anchor, atol=1e-12)
    # x along the finger (+y), z along the palm normal (+z): the abduction axis.
    np.testing.assert_allclose(T[:3, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], [0, 0, 1], atol=1e-12)


def test_zero_state_link_axes_and_lengths(hand):
    start, end, idx = forward_kinematics(hand, zero_state()).link_segments()
    rows = [hand.links[i].row for i in idx]
    assert rows == [row for row, _, _ in ZERO_LINKS]
    np.testing.assert_allclose(start, [s for _, s, _ in ZERO_LINKS], atol=1e-12)
    np.testing.assert_allclose(end, [e for _, _, e in ZERO_LINKS], atol=1e-12)
    lengths = [length for *_, lengths, _, _ in FINGERS.values() for length in lengths]
    np.testing.assert_allclose(
        np.linalg.norm(end - start, axis=1), [*lengths, *THUMB_LENGTHS], atol=1e-12
    )


def test_zero_state_tip_centres(hand):
    tips, idx = forward_kinematics(hand, zero_state()).tip_centres()
    expected = [np.add(anchor, (0.0, sum(lengths), 0.0))
                for _, anchor, lengths, _, _ in FINGERS.values()]
    expected.append(THUMB_POINTS[3])
    # index (31, 133, 0), middle (9, 142, 0), ring (-6, 131, 0), little (-26, 104, 0),
    # thumb (38, 62, 15)
    np.testing.assert_allclose(tips, expected, atol=1e-12)
    assert [hand.links[i].row for i in idx] == [7, 14, 21, 28, 36]


# ------------------------------------------------------------------ signs
@pytest.mark.parametrize("finger", FINGERS)
def test_positive_flexion_moves_finger_to_palm_side(hand, finger):
    first, anchor, (l1, l2, l3), _, tip_row = FINGERS[finger]
    a, b, c = 0.4, 0.3, 0.2  # MCP, PIP, DIP
    q = zero_state()
    q[first + 1:first + 4] = a, b, c
    tip = forward_kinematics(hand, q).T_world_shape[0, tip_row, :3, 3]
    # A planar chain in the y-z plane, all axes along +x.
    expected = np.add(anchor, (
        0.0,
        l1 * math.cos(a) + l2 * math.cos(a + b) + l3 * math.cos(a + b + c),
        l1 * math.sin(a) + l2 * math.sin(a + b) + l3 * math.sin(a + b + c),
    ))
    np.testing.assert_allclose(tip, expected, atol=1e-12)
    assert tip[2] > 0.0


@pytest.mark.parametrize("finger", FINGERS)
def test_positive_abduction_moves_finger_to_minus_x(hand, finger):
    first, anchor, lengths, _, tip_row = FINGERS[finger]
    alpha, beta = 0.3, 0.5  # abduction, then MCP flexion
    q = zero_state()
    q[first] = alpha
    q[first + 1] = beta
    tip = forward_kinematics(hand, q).T_world_shape[0, tip_row, :3, 3]
    # Abduction turns the finger about +z, so the straight finger points along
    # u = (-sin alpha, cos alpha, 0); flexion then tilts it from u towards +z.
    u = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
    expected = np.add(anchor, sum(lengths) * (math.cos(beta) * u + (0, 0, math.sin(beta))))
    np.testing.assert_allclose(tip, expected, atol=1e-12)


@pytest.mark.parametrize(
    ("state", "pivot", "axis"),
    [
        # (state, point the joint turns about, world axis at the zero state)
        (23, THUMB_POINTS[0], (1, 0, 0)),
        (24, THUMB_POINTS[0], (0, 0, -1)),
        (25, THUMB_POINTS[1], (1, 0, 0)),
        (26, THUMB_POINTS[1], (0, 0, -1)),
        (27, THUMB_POINTS[2], (0, 0, -1)),
    ],
)
def test_thumb_joint_axes(hand, state, pivot, axis):
    # Worked out by hand from rows 29-35: frames 31 and 33 have z along +x, frames 32, 34
    # and 35 z along -z, at the zero state.
    angle = 0.3
    q = zero_state()
    q[state] = angle
    tip = forward_kinematics(hand, q).T_world_shape[0, 36, :3, 3]
    arm = THUMB_POINTS[3] - pivot
    axis = np.asarray(axis, dtype=float)
    # Rodrigues for an arm perpendicular to the axis.
    expected = pivot + math.cos(angle) * arm + math.sin(angle) * np.cross(axis, arm)
    np.testing.assert_allclose(tip, expected, atol=1e-12)


# ------------------------------------------------------------------ palm pose
def test_palm_pose_moves_every_frame(hand):
    q = zero_state()
    half = math.pi / 4  # 90 degrees about +z: (x, y, z) -> (-y, x, z)
    q[0:4] = math.cos(half), 0.0, 0.0, math.sin(half)
    q[4:7] = 10.0, -20.0, 30.0
    kin = forward_kinematics(hand, q)
    np.testing.assert_allclose(kin.T_world_frame[0, 3, :3, 3], [-38 + 10, 31 - 20, 30], atol=1e-12)
    np.testing.assert_allclose(kin.T_world_frame[0, 3, :3, 0], [-1, 0, 0], atol=1e-12)
    T_world_palm = np.eye(4)
    T_world_palm[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T_world_palm[:3, 3] = q[4:7]
    zero = forward_kinematics(hand, zero_state())
    np.testing.assert_allclose(kin.T_world_frame, T_world_palm @ zero.T_world_frame, atol=1e-12)
    np.testing.assert_allclose(kin.T_world_shape, T_world_palm @ zero.T_world_shape, atol=1e-12)


def test_quaternion_scale_does_not_matter(hand, random_states):
    q = random_states(np.random.default_rng(2), 1)[0]
    scaled = q.copy()
    scaled[0:4] *= 2.5
    np.testing.assert_allclose(
        forward_kinematics(hand, scaled).T_world_frame,
        forward_kinematics(hand, q).T_world_frame,
        atol=1e-12,
    )


# ------------------------------------------------------------------ structure on random states
def test_frames_follow_the_table(hand, random_states):
    """Every child frame is its parent times the parent row's DH transform (eq. 2.2) and
    every shape frame is its row frame times Rot_z(theta) (eq. 2.4)."""
    q = random_states(np.random.default_rng(3), 1)[0]
    kin = forward_kinematics(hand, q)
    for row in hand.rows:
        theta = row.theta + (q[row.theta_state] if row.theta_state is not None else 0.0)
        T = kin.T_world_frame[0, row.index]
        np.testing.assert_allclose(kin.T_world_shape[0, row.index], T @ rot_z(theta), atol=1e-10)
        step = rot_z(theta) @ trans(0, 0, row.d) @ trans(row.a, 0, 0) @ rot_x(row.alpha)
        for child in row.next:
            np.testing.assert_allclose(kin.T_world_frame[0, child], T @ step, atol=1e-10)


def test_frames_are_rigid_transforms(hand, random_states):
    kin = forward_kinematics(hand, random_states(np.random.default_rng(4), 8))
    for T in (kin.T_world_frame, kin.T_world_shape):
        R = T[..., :3, :3]
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape),
                                   atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
        bottom = np.broadcast_to([0.0, 0.0, 0.0, 1.0], T[..., 3, :].shape)
        np.testing.assert_array_equal(T[..., 3, :], bottom)


def test_batch_matches_single(hand, random_states):
    Q = random_states(np.random.default_rng(5), 6)
    batch = forward_kinematics(hand, Q)
    assert batch.T_world_frame.shape == (6, hand.n_frames, 4, 4)
    assert batch.T_world_shape.shape == (6, hand.n_frames, 4, 4)
    rows, p = np.array([0, 4, 36]), np.array([[1.0, 2.0, 3.0], [45.0, 0, 0], [0, 0, 8.0]])
    for n, q in enumerate(Q):
        single = forward_kinematics(hand, q)
        np.testing.assert_allclose(batch.T_world_frame[n], single.T_world_frame[0], atol=1e-12)
        np.testing.assert_allclose(batch.T_world_shape[n], single.T_world_shape[0], atol=1e-12)
        np.testing.assert_allclose(batch.points(rows, p)[n], single.points(rows, p), atol=1e-12)
        np.testing.assert_allclose(batch.tip_centres()[0][n], single.tip_centres()[0], atol=1e-12)
        np.testing.assert_allclose(batch.link_segments()[1][n], single.link_segments()[1],
                                   atol=1e-12)


def test_helper_shapes_single_and_batch(hand, random_states):
    single = forward_kinematics(hand, random_states(np.random.default_rng(6), 1)[0])
    batch = forward_kinematics(hand, random_states(np.random.default_rng(6), 3))
    start, end, idx = single.link_segments()
    assert start.shape == end.shape == (15, 3) and idx.shape == (15,)
    assert batch.link_segments()[0].shape == (3, 15, 3)
    assert single.tip_centres()[0].shape == (5, 3)
    assert batch.tip_centres()[0].shape == (3, 5, 3)
    assert single.points([4, 5], np.zeros((2, 3))).shape == (2, 3)
    assert batch.points([4, 5], np.zeros((2, 3))).shape == (3, 2, 3)


def test_points_are_shape_frame_coordinates(hand, random_states):
    kin = forward_kinematics(hand, random_states(np.random.default_rng(7), 1)[0])
    p_shape = np.array([[10.0, -2.0, 3.0], [0.0, 0.0, 0.0]])
    p = kin.points([11, 36], p_shape)
    for i, row in enumerate((11, 36)):
        expected = kin.T_world_shape[0, row] @ np.append(p_shape[i], 1.0)
        np.testing.assert_allclose(p[i], expected[:3], atol=1e-12)


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize(
    ("q", "match"),
    [
        (np.zeros(27), r"needs states of size 28.*got shape \(27,\)"),
        (np.zeros((2, 3, 28)), r"needs states of size 28.*got shape \(2, 3, 28\)"),
        (np.r_[1.0, np.zeros(8), np.nan, np.zeros(18)], r"q9 \(index\.pip\) is not finite"),
        (np.r_[1.0, np.zeros(3), np.inf, np.zeros(23)], r"q4 \(palm\.x\) is not finite"),
    ],
)
def test_invalid_states_are_rejected(hand, q, match):
    with pytest.raises(StateError, match=match):
        forward_kinematics(hand, q)
