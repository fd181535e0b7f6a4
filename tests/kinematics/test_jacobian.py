"""Point Jacobians against central finite differences, batching and sparsity.

Tangent form: the base is stepped through ``integrate`` (the retraction solvers use);
quaternion form: the raw state numbers are stepped, including off the unit sphere.
"""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import forward_kinematics, integrate, point_jacobian

STEP = 1e-6  # radians or mm; central differences are accurate to ~1e-10 relative here
RTOL = 1e-6


def hand_points(model, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Both ends of every link axis, every tip centre and one random point per row (mm)."""
    axis_rows, axis_offsets = model.axis_and_tip_points()
    rows, offsets = list(axis_rows), list(axis_offsets)
    rows += list(range(model.n_frames))
    offsets += list(rng.uniform(-20.0, 20.0, size=(model.n_frames, 3)))
    return np.array(rows), np.array(offsets)


def numeric_jacobian(model, q, rows, offsets, step_fn, n_cols) -> np.ndarray:
    """Central differences of the world points along each column's step, (P, 3, n_cols)."""
    J = np.empty((len(rows), 3, n_cols))
    for j in range(n_cols):
        plus = forward_kinematics(model, step_fn(q, j, STEP)).points(rows, offsets)
        minus = forward_kinematics(model, step_fn(q, j, -STEP)).points(rows, offsets)
        J[..., j] = (plus - minus) / (2.0 * STEP)
    return J


def assert_jacobians_close(J, J_num):
    """Relative agreement: every entry within RTOL of the largest entry."""
    scale = np.abs(J_num).max()
    np.testing.assert_allclose(J, J_num, rtol=0.0, atol=RTOL * scale)


def tangent_step(model):
    def step(q, j, h):
        dv = np.zeros(model.n_v)
        dv[j] = h
        return integrate(model, q, dv)

    return step


def raw_step(q, j, h):
    out = q.copy()
    out[j] += h
    return out


@pytest.mark.parametrize("seed", [10, 11, 12])
def test_tangent_jacobian_matches_finite_differences(hand, random_states, seed):
    rng = np.random.default_rng(seed)
    q = random_states(rng, 1)[0]
    rows, offsets = hand_points(hand, rng)
    p, J = point_jacobian(forward_kinematics(hand, q), rows, offsets)
    assert J.shape == (len(rows), 3, 27)
    np.testing.assert_allclose(p, forward_kinematics(hand, q).points(rows, offsets), atol=1e-12)
    assert_jacobians_close(J, numeric_jacobian(hand, q, rows, offsets, tangent_step(hand), 27))


@pytest.mark.parametrize(("seed", "quat_norm"), [(20, 1.0), (21, 1.0), (22, 0.4), (23, 2.7)])
def test_quaternion_jacobian_matches_finite_differences(hand, random_states, seed, quat_norm):
    rng = np.random.default_rng(seed)
    q = random_states(rng, 1, quat_norm=quat_norm)[0]
    rows, offsets = hand_points(hand, rng)
    _, J = point_jacobian(forward_kinematics(hand, q), rows, offsets, form="quaternion")
    assert J.shape == (len(rows), 3, 28)
    assert_jacobians_close(J, numeric_jacobian(hand, q, rows, offsets, raw_step, 28))


def test_quaternion_columns_ignore_scaling(hand, random_states):
    """Moving the quaternion along itself only rescales it: no point moves (thesis 2.2.1)."""
    q = random_states(np.random.default_rng(24), 1, quat_norm=1.6)[0]
    rows, offsets = hand_points(hand, np.random.default_rng(25))
    _, J = point_jacobian(forward_kinematics(hand, q), rows, offsets, form="quaternion")
    np.testing.assert_allclose(J[..., 0:4] @ q[0:4], 0.0, atol=1e-10)


def test_forms_agree_on_joints_and_translation(hand, random_states):
    q = random_states(np.random.default_rng(26), 1)[0]
    rows, offsets = hand_points(hand, np.random.default_rng(27))
    kin = forward_kinematics(hand, q)
    _, J_tan = point_jacobian(kin, rows, offsets, form="tangent")
    _, J_quat = point_jacobian(kin, rows, offsets, form="quaternion")
    np.testing.assert_array_equal(J_tan[..., 3:], J_quat[..., 4:])


def test_batch_matches_single(hand, random_states):
    rng = np.random.default_rng(30)
    Q = random_states(rng, 5)
    rows, offsets = hand_points(hand, rng)
    for form, n_cols in (("tangent", 27), ("quaternion", 28)):
        p_batch, J_batch = point_jacobian(forward_kinematics(hand, Q), rows, offsets, form=form)
        assert p_batch.shape == (5, len(rows), 3)
        assert J_batch.shape == (5, len(rows), 3, n_cols)
        for n, q in enumerate(Q):
            p, J = point_jacobian(forward_kinematics(hand, q), rows, offsets, form=form)
            np.testing.assert_allclose(p_batch[n], p, atol=1e-12)
            np.testing.assert_allclose(J_batch[n], J, atol=1e-12)


@pytest.mark.parametrize(
    ("row", "moving_states"),
    [
        (0, range(0, 7)),  # palm: only the palm pose
        (4, [*range(0, 7), 7, 8]),  # index proximal: palm, abduction, its own MCP
        (7, [*range(0, 7), 7, 8, 9, 10]),  # index tip
        (21, [*range(0, 7), 15, 16, 17, 18]),  # ring tip
        (34, [*range(0, 7), 23, 24, 25, 26]),  # thumb proximal link
    ],
)
def test_columns_of_unrelated_states_are_zero(hand, random_states, row, moving_states):
    q = random_states(np.random.default_rng(31), 1)[0]
    _, J = point_jacobian(forward_kinematics(hand, q), [row], [[5.0, 3.0, -2.0]],
                          form="quaternion")
    nonzero = set(np.flatnonzero(np.abs(J[0]).max(axis=0) > 0.0))
    assert nonzero == set(moving_states)


def test_revolute_column_is_axis_cross_arm(hand):
    """Thesis eq. 2.16 at the zero state, by hand: the index MCP axis is +x through
    (31, 38, 0), the index tip is at (31, 133, 0), so the column is x cross (0, 95, 0)."""
    q = np.zeros(28)
    q[0] = 1.0
    _, J = point_jacobian(forward_kinematics(hand, q), [7], [[0.0, 0.0, 0.0]])
    np.testing.assert_allclose(J[0, :, hand.q_to_v[8]], [0.0, 0.0, 95.0], atol=1e-12)
    # Palm rotation about world z through the palm origin: z cross (31, 133, 0).
    np.testing.assert_allclose(J[0, :, 2], [-133.0, 31.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(J[0, :, 3:6], np.eye(3), atol=1e-12)


def test_unknown_form_is_rejected(hand):
    """A misspelt ``form`` must not silently give the quaternion form."""
    kin = forward_kinematics(hand, hand.neutral())
    with pytest.raises(ValueError, match="form"):
        point_jacobian(kin, [7], [[0.0, 0.0, 0.0]], form="tangential")
