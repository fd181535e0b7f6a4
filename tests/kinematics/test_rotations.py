"""Rotations: quaternions (w, x, y, z), matrices, exponential and logarithm maps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from digiteyes.kinematics.rotations import (
    matrix_angle,
    matrix_from_quaternion,
    quaternion_from_matrix,
    quaternion_from_rotvec,
    quaternion_multiply,
    quaternion_rate_matrix,
    rotvec_from_quaternion,
    skew,
)


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def axis_angle_matrix(axis, angle: float) -> np.ndarray:
    """Rodrigues' formula, written out for the test."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def test_matrix_angle_matches_the_rotation_and_is_accurate_near_zero():
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(6, 3))
    angles = np.array([0.0, 1e-9, 1e-4, 0.3, 2.0, math.pi])
    rotations = np.array([axis_angle_matrix(k, t) for k, t in zip(axes, angles, strict=True)])
    base = axis_angle_matrix([0.2, -1.0, 0.5], 0.7)
    np.testing.assert_allclose(matrix_angle(base, base @ rotations), angles, atol=1e-12)
    np.testing.assert_allclose(matrix_angle(base @ rotations, base), angles, atol=1e-12)


# ------------------------------------------------------------------ skew
def test_skew_is_cross_product():
    rng = np.random.default_rng(40)
    v, u = rng.normal(size=(2, 5, 3))
    np.testing.assert_allclose(skew(v) @ u[..., None], np.cross(v, u)[..., None], atol=1e-14)
    assert skew(v).shape == (5, 3, 3)


# ------------------------------------------------------------------ matrix_from_quaternion
@pytest.mark.parametrize(
    ("axis", "angle"),
    [((1, 0, 0), math.pi / 2), ((0, 1, 0), 0.3), ((0, 0, 1), -2.0), ((1, 2, -2), 2.5)],
)
def test_matrix_from_quaternion_known_values(axis, angle):
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    quat = np.r_[math.cos(angle / 2), math.sin(angle / 2) * k]
    np.testing.assert_allclose(matrix_from_quaternion(quat), axis_angle_matrix(axis, angle),
                               atol=1e-14)


def test_matrix_from_quaternion_normalises_and_ignores_sign():
    rng = np.random.default_rng(41)
    quat = random_quaternions(rng, 6)
    R = matrix_from_quaternion(quat)
    assert R.shape == (6, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    np.testing.assert_allclose(matrix_from_quaternion(3.5 * quat), R, atol=1e-14)
    np.testing.assert_allclose(matrix_from_quaternion(-quat), R, atol=1e-14)


# ------------------------------------------------------------------ quaternion_from_matrix
def test_quaternion_from_matrix_round_trip_all_branches():
    rng = np.random.default_rng(42)
    # Random rotations plus half turns about each axis and the identity: each of
    # Shepperd's four branches (largest of trace, R00, R11, R22) is taken.
    quat = np.vstack([random_quaternions(rng, 50), [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1],
                                                    [1, 0, 0, 0]]])
    back = quaternion_from_matrix(matrix_from_quaternion(quat))
    assert back.shape == quat.shape
    assert (back[:, 0] >= 0.0).all()
    # Same rotation: equal up to sign.
    np.testing.assert_allclose(np.abs(np.sum(back * quat, axis=1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1.0, atol=1e-14)


def test_quaternion_from_matrix_keeps_batch_shape():
    R = np.broadcast_to(np.eye(3), (2, 3, 3, 3))
    np.testing.assert_allclose(quaternion_from_matrix(R), np.broadcast_to([1.0, 0, 0, 0],
                                                                          (2, 3, 4)))


# ------------------------------------------------------------------ products
def test_quaternion_multiply_composes_rotations():
    rng = np.random.default_rng(43)
    q1, q2 = random_quaternions(rng, 8), random_quaternions(rng, 8)
    np.testing.assert_allclose(
        matrix_from_quaternion(quaternion_multiply(q1, q2)),
        matrix_from_quaternion(q1) @ matrix_from_quaternion(q2),
        atol=1e-14,
    )
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(quaternion_multiply(identity, q1), q1, atol=1e-15)
    np.testing.assert_allclose(quaternion_multiply(q1, identity), q1, atol=1e-15)


def test_quaternion_multiply_hamilton_units():
    w, i, j, k = np.eye(4)
    np.testing.assert_array_equal(quaternion_multiply(i, j), k)
    np.testing.assert_array_equal(quaternion_multiply(j, k), i)
    np.testing.assert_array_equal(quaternion_multiply(i, i), -w)


# ------------------------------------------------------------------ exp / log
def test_rotvec_round_trip():
    rng = np.random.default_rng(44)
    axes = rng.normal(size=(20, 3))
    angles = rng.uniform(0.0, math.pi - 1e-6, size=(20, 1))
    rotvec = axes / np.linalg.norm(axes, axis=1, keepdims=True) * angles
    quat = quaternion_from_rotvec(rotvec)
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rotvec_from_quaternion(quat), rotvec, atol=1e-12)
    for r, R in zip(rotvec, matrix_from_quaternion(quat), strict=True):
        np.testing.assert_allclose(R, axis_angle_matrix(r, np.linalg.norm(r)), atol=1e-14)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-9, 3e-8])
def test_exponential_near_zero(angle):
    rotvec = np.array([angle, -2 * angle, 0.5 * angle])
    quat = quaternion_from_rotvec(rotvec)
    np.testing.assert_allclose(quat, np.r_[1.0, 0.5 * rotvec], rtol=1e-12, atol=1e-30)
    np.testing.assert_allclose(rotvec_from_quaternion(quat), rotvec, rtol=1e-9, atol=1e-30)


def test_logarithm_takes_the_short_way_and_normalises():
    # 270 degrees about +z is -90 degrees about +z; the sign of q and its scale do not matter.
    quat = quaternion_from_rotvec([0.0, 0.0, 1.5 * math.pi])
    np.testing.assert_allclose(rotvec_from_quaternion(quat), [0, 0, -math.pi / 2], atol=1e-14)
    np.testing.assert_allclose(rotvec_from_quaternion(-4.0 * quat), [0, 0, -math.pi / 2],
                               atol=1e-14)
    half_turn = rotvec_from_quaternion(np.array([0.0, 0.0, 1.0, 0.0]))
    np.testing.assert_allclose(np.abs(half_turn), [0, math.pi, 0], atol=1e-15)


# ------------------------------------------------------------------ rate matrix
@pytest.mark.parametrize("scale", [1.0, 0.3, 4.0])
def test_quaternion_rate_matrix_matches_finite_differences(scale):
    """d R(q / |q|) / d q_j @ R^T is the cross matrix of column j of G."""
    rng = np.random.default_rng(45)
    h = 1e-6
    for quat in scale * random_quaternions(rng, 5):
        G = quaternion_rate_matrix(quat)
        assert G.shape == (3, 4)
        R = matrix_from_quaternion(quat)
        for j in range(4):
            dq = np.zeros(4)
            dq[j] = h
            dR = (matrix_from_quaternion(quat + dq) - matrix_from_quaternion(quat - dq)) / (2 * h)
            np.testing.assert_allclose(dR @ R.T, skew(G[:, j]), atol=1e-8 / scale)
        np.testing.assert_allclose(G @ quat, 0.0, atol=1e-14)
