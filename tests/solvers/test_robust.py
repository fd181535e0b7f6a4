"""Robust losses: IRLS weights are rho'(r)/r, values and continuity."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.solvers import robust_cost, robust_weights

R = np.linspace(-12.0, 12.0, 241) + 0.0123  # avoid landing exactly on the kinks


@pytest.mark.parametrize("loss", [None, "huber", "tukey"])
def test_weights_are_derivative_over_residual(loss):
    h = 1e-6
    derivative = (robust_cost(R + h, loss, 3.0) - robust_cost(R - h, loss, 3.0)) / (2 * h)
    np.testing.assert_allclose(robust_weights(R, loss, 3.0) * R, derivative, atol=1e-6)


@pytest.mark.parametrize("loss", [None, "huber", "tukey"])
def test_quadratic_near_zero_and_continuous(loss):
    small = np.array([-1e-3, 2e-3])
    np.testing.assert_allclose(robust_cost(small, loss, 3.0), 0.5 * small**2, rtol=1e-5)
    at = np.array([3.0 - 1e-9, 3.0 + 1e-9])
    assert abs(np.diff(robust_cost(at, loss, 3.0))[0]) < 1e-6


def test_known_values():
    assert robust_cost(10.0, "huber", 2.0) == pytest.approx(2.0 * 10.0 - 2.0)
    assert robust_weights(10.0, "huber", 2.0) == pytest.approx(0.2)
    assert robust_cost(10.0, "tukey", 2.0) == pytest.approx(4.0 / 6.0)
    assert robust_weights(10.0, "tukey", 2.0) == 0.0
    assert robust_weights(1.0, "tukey", 2.0) == pytest.approx(0.75**2)
    np.testing.assert_array_equal(robust_weights(R), np.ones_like(R))
    assert robust_weights(R, "huber").shape == R.shape


@pytest.mark.parametrize(("loss", "scale", "match"), [
    ("cauchy", 1.0, "robust loss"), ("huber", 0.0, "scale"), ("tukey", np.inf, "scale"),
])
def test_bad_arguments(loss, scale, match):
    with pytest.raises(ValueError, match=match):
        robust_weights(R, loss, scale)
