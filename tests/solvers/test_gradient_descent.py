"""Fixed-step gradient descent (thesis eq. 2.12)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.solvers import GaussNewtonOptions, gauss_newton, gradient_descent


class LinearProblem:
    """r = A x - b: the minimum is the least-squares solution."""

    def __init__(self, A, b):
        self.A, self.b, self.n_v = A, b, A.shape[1]

    def residuals(self, x, jacobian):
        return self.A @ x - self.b, self.A if jacobian else None

    def retract(self, x, dv):
        return x + dv


def test_linear_problem_converges_to_least_squares_solution():
    rng = np.random.default_rng(0)
    A, b = rng.normal(size=(20, 3)), rng.normal(size=20)
    L = np.linalg.eigvalsh(A.T @ A).max()
    x, summary = gradient_descent(LinearProblem(A, b), np.zeros(3), 1.0 / L, 2000,
                                  step_tolerance=1e-12)
    np.testing.assert_allclose(x, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-9)
    assert summary.converged and summary.iterations < 2000
    assert np.all(np.diff(summary.cost_history) <= 1e-12 * summary.cost_initial)


def test_too_large_a_step_diverges():
    A = np.diag([1.0, 2.0])
    _, summary = gradient_descent(LinearProblem(A, np.zeros(2)), np.ones(2), 1.1, 20)
    assert summary.cost_final > summary.cost_initial


def test_hand_problem_descends_but_needs_far_more_iterations_than_gauss_newton(
        hand, cameras, q_true, point_problem, perturb,
):
    problem = point_problem(hand, cameras, q_true)
    x0 = perturb(hand, q_true, np.random.default_rng(1), joint=0.05)
    _, J = problem.residuals(x0, True)
    step = 0.5 / np.maximum((J * J).sum(axis=0), 1e-9) / 10.0  # Jacobi-preconditioned
    _, gd = gradient_descent(problem, x0, step, 40)
    assert gd.termination == "max_iterations" and gd.iterations == 40
    assert np.all(np.diff(gd.cost_history) < 0)
    assert gd.cost_final < 0.5 * gd.cost_initial
    _, gn = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=3))
    assert gn.cost_final < 1e-6 * gd.cost_final


def test_no_residuals_and_validation(hand, cameras, q_true, point_problem):
    empty = point_problem(hand, cameras, q_true, rows=np.zeros(0, dtype=int),
                                  points=np.zeros((0, 3)))
    x, summary = gradient_descent(empty, q_true, 1e-3, 5)
    assert summary.termination == "no residuals" and summary.iterations == 0
    np.testing.assert_array_equal(x, q_true)
    with pytest.raises(ValueError, match="step_size"):
        gradient_descent(empty, q_true, np.ones(3), 5)
    with pytest.raises(ValueError, match="step_size"):
        gradient_descent(empty, q_true, -1.0, 5)
    with pytest.raises(ValueError, match="max_iterations"):
        gradient_descent(empty, q_true, 1.0, -2)
