"""digiteyes against pinocchio on the Appendix A hand: every frame and the point Jacobians.

The pinocchio model comes from :mod:`digiteyes.benchmarks.pinocchio_hand`, which transcribes
thesis Table A.1 itself and builds the tree with pinocchio's own joints; nothing of
digiteyes' parser or kinematics is used on that side.
"""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import forward_kinematics, point_jacobian
from digiteyes.kinematics.rotations import matrix_from_quaternion

pin = pytest.importorskip("pinocchio")
pinocchio_hand = pytest.importorskip("digiteyes.benchmarks.pinocchio_hand")


@pytest.fixture(scope="module")
def points() -> tuple[np.ndarray, np.ndarray]:
    """Link axis ends, tip centres and off-axis points, as (rows, offsets in mm)."""
    rng = np.random.default_rng(60)
    links = [(4, 45), (5, 26), (6, 24), (11, 56), (12, 27), (13, 22), (18, 53), (19, 25),
             (20, 20), (25, 38), (26, 19), (27, 17), (32, 46), (34, 34), (35, 25)]
    rows = [r for r, _ in links for _ in range(2)] + [7, 14, 21, 28, 36] + list(range(37))
    offsets = [(a * end, 0.0, 0.0) for _, a in links for end in (0, 1)] + [(0.0, 0.0, 0.0)] * 5
    offsets += list(rng.uniform(-15.0, 15.0, size=(37, 3)))
    return np.array(rows), np.array(offsets)


@pytest.fixture(scope="module")
def reference(points):
    return pinocchio_hand.build_pinocchio_hand(*points)


def test_reference_layout(reference):
    assert reference.model.nq == 28
    assert reference.model.nv == 27
    assert len(reference.frame_ids) == len(reference.shape_ids) == 37
    assert sorted(reference.joint_v_index[7:]) == list(range(6, 27))


@pytest.mark.parametrize("seed", [61, 62, 63, 64])
def test_all_frames_match_pinocchio(hand, random_states, reference, seed):
    Q = random_states(np.random.default_rng(seed), 3)
    kin = forward_kinematics(hand, Q)
    data = reference.model.createData()
    for n, q in enumerate(Q):
        pin.framesForwardKinematics(reference.model, data, reference.configuration(q))
        for r in range(37):
            np.testing.assert_allclose(
                kin.T_world_frame[n, r], data.oMf[reference.frame_ids[r]].homogeneous,
                rtol=0, atol=1e-9,
            )
            np.testing.assert_allclose(
                kin.T_world_shape[n, r], data.oMf[reference.shape_ids[r]].homogeneous,
                rtol=0, atol=1e-9,
            )


def test_non_unit_quaternion_matches_normalised_pinocchio(hand, random_states, reference):
    q = random_states(np.random.default_rng(65), 1, quat_norm=3.0)[0]
    kin = forward_kinematics(hand, q)
    data = reference.model.createData()
    pin.framesForwardKinematics(reference.model, data, reference.configuration(q))
    for r in range(37):
        np.testing.assert_allclose(
            kin.T_world_shape[0, r], data.oMf[reference.shape_ids[r]].homogeneous,
            rtol=0, atol=1e-9,
        )


def tangent_jacobian_from_pinocchio(reference, data, q: np.ndarray) -> np.ndarray:
    """Point Jacobians in our tangent layout, (P, 3, 27), from pinocchio frame Jacobians.

    ``LOCAL_WORLD_ALIGNED`` rows 0..2 give the point's world velocity. pinocchio's
    free-flyer velocity is LOCAL: linear ``v`` and angular ``w`` in palm axes, with
    ``M <- M exp(v, w)``. Ours is a world rotation step ``delta`` about the palm origin
    and a world translation step ``dt``: ``R <- exp([delta]x) R``, ``t <- t + dt``. To first
    order ``M exp(v, w) = (R exp([w]x), t + R v)``, so ``w = R^T delta`` and ``v = R^T dt``
    and our columns are pinocchio's times ``R^T``. Joint columns map one to one.
    """
    R = matrix_from_quaternion(q[0:4])
    J = np.empty((len(reference.point_ids), 3, 27))
    for i, frame in enumerate(reference.point_ids):
        J_pin = pin.getFrameJacobian(reference.model, data, frame,
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        J[i, :, 0:3] = J_pin[:, 3:6] @ R.T
        J[i, :, 3:6] = J_pin[:, 0:3] @ R.T
        for s in range(7, 28):
            J[i, :, s - 1] = J_pin[:, reference.joint_v_index[s]]
    return J


@pytest.mark.parametrize("seed", [66, 67, 68])
def test_point_jacobians_match_pinocchio(hand, random_states, reference, points, seed):
    q = random_states(np.random.default_rng(seed), 1)[0]
    p, J = point_jacobian(forward_kinematics(hand, q), *points)
    data = reference.model.createData()
    pin.computeJointJacobians(reference.model, data, reference.configuration(q))
    pin.updateFramePlacements(reference.model, data)
    p_pin = np.array([data.oMf[f].translation for f in reference.point_ids])
    np.testing.assert_allclose(p, p_pin, rtol=0, atol=1e-9)
    J_pin = tangent_jacobian_from_pinocchio(reference, data, q)
    np.testing.assert_allclose(J, J_pin, rtol=0, atol=1e-9 * np.abs(J_pin).max())


def test_jacobian_conversion_against_pinocchio_integrate(hand, random_states, reference,
                                                         points):
    """Check the LOCAL-to-ours conversion itself: stepping pinocchio by the converted
    velocity moves the points as our Jacobian predicts (first order)."""
    q = random_states(np.random.default_rng(69), 1)[0]
    dv = np.random.default_rng(70).normal(size=27)
    R = matrix_from_quaternion(q[0:4])
    v_pin = np.empty(27)
    v_pin[0:3] = R.T @ dv[3:6]
    v_pin[3:6] = R.T @ dv[0:3]
    for s in range(7, 28):
        v_pin[reference.joint_v_index[s]] = dv[s - 1]
    model, data = reference.model, reference.model.createData()
    h = 1e-6
    moved = []
    for sign in (1.0, -1.0):
        q_pin = pin.integrate(model, reference.configuration(q), sign * h * v_pin)
        pin.framesForwardKinematics(model, data, q_pin)
        moved.append(np.array([data.oMf[f].translation for f in reference.point_ids]))
    velocity = (moved[0] - moved[1]) / (2 * h)
    _, J = point_jacobian(forward_kinematics(hand, q), *points)
    np.testing.assert_allclose(J @ dv, velocity, rtol=0, atol=1e-6 * np.abs(velocity).max())
