"""Constant-velocity prediction in the tangent space."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import difference, integrate, load_model
from digiteyes.trackers.prediction import StatePredictor

HAND = load_model("hand")


def moving_states():
    """Three states moving at constant tangent velocity (rotation, translation, joints)."""
    q0 = HAND.neutral()
    q0[HAND.state_index("index.mcp")] = 0.3
    v = np.zeros(HAND.n_v)
    v[0:3] = (0.02, -0.01, 0.03)
    v[3:6] = (1.0, -2.0, 0.5)
    v[HAND.tangent_names.index("index.mcp")] = 0.05
    q1 = integrate(HAND, q0, v)
    return q0, q1, integrate(HAND, q1, v), v


def test_constant_velocity_extrapolates_a_constant_motion():
    q0, q1, q2, v = moving_states()
    predictor = StatePredictor(HAND, "constant-velocity")
    predictor.reset(q0)
    np.testing.assert_array_equal(predictor.predict(), q0)  # at rest after reset
    predictor.update(q1)
    np.testing.assert_allclose(predictor.velocity, v, atol=1e-12)
    np.testing.assert_allclose(difference(HAND, q2, predictor.predict()), 0.0, atol=1e-12)


def test_no_prediction_and_unreliable_updates_hold_still():
    q0, q1, _, _ = moving_states()
    none = StatePredictor(HAND, "none")
    none.reset(q0)
    none.update(q1)
    np.testing.assert_array_equal(none.predict(), q1)
    cv = StatePredictor(HAND, "constant-velocity")
    cv.reset(q0)
    cv.update(q1, reliable=False)
    np.testing.assert_array_equal(cv.predict(), q1)


def test_prediction_is_clipped_into_limits():
    q0 = HAND.neutral()
    pip = HAND.state_index("index.pip")
    q1 = q0.copy()
    q1[pip] = HAND.upper[pip] - 0.01
    q0[pip] = q1[pip] - 0.5
    predictor = StatePredictor(HAND, clip=True)
    predictor.reset(q0)
    predictor.update(q1)
    assert predictor.predict()[pip] == HAND.upper[pip]


def test_errors():
    with pytest.raises(ValueError, match="prediction"):
        StatePredictor(HAND, "kalman")
    with pytest.raises(ValueError, match="reset"):
        StatePredictor(HAND).predict()
