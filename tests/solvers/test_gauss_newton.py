"""Gauss-Newton / Levenberg-Marquardt on synthetic point-alignment problems (no images)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import difference
from digiteyes.solvers import (
    GaussNewtonOptions,
    LeastSquaresProblem,
    gauss_newton,
    hand_conditioning,
    robust_cost,
    solve_normal_equations,
)
from digiteyes.solvers._kernels import damped_system


def state_error(model, q, q_ref) -> float:
    """Largest tangent-space difference (rad or mm)."""
    return float(np.abs(difference(model, q_ref, q)).max())


class ArctanProblem:
    """One residual ``atan(x)``: Gauss-Newton overshoots and diverges for |x0| > 1.39."""

    n_v = 1

    def residuals(self, x, jacobian):
        r = np.arctan(x)
        return r, (1.0 / (1.0 + x * x))[:, None] if jacobian else None

    def retract(self, x, dv):
        return x + dv


def test_point_problem_fits_the_protocol(hand, cameras, q_true, point_problem):
    assert isinstance(point_problem(hand, cameras, q_true), LeastSquaresProblem)


@pytest.mark.parametrize("form", ["tangent", "quaternion"])
@pytest.mark.parametrize("damping", ["fixed", "levenberg-marquardt"])
def test_converges_to_truth_without_conditioning(
        hand, cameras, q_true, form, damping, point_problem, perturb,
):
    problem = point_problem(hand, cameras, q_true, form=form)
    x0 = perturb(hand, q_true, np.random.default_rng(1))
    x, summary = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=20,
                                                              damping=damping))
    assert state_error(hand, x, q_true) < 1e-8
    assert summary.converged
    assert summary.iterations <= 10
    assert abs(np.linalg.norm(x[0:4]) - 1.0) < 1e-12
    r, _ = problem.residuals(x, False)
    assert summary.n_residuals == len(r) == sum(t.size for t in problem.targets)
    assert summary.cost_final == pytest.approx(0.5 * r @ r, abs=1e-12)
    assert summary.cost_history[0] == summary.cost_initial > 1.0
    assert summary.cost_history[-1] == summary.cost_final
    assert len(summary.cost_history) == summary.iterations + 1
    assert len(summary.step_norms) == summary.iterations
    assert summary.timings["residuals"] > 0 and summary.timings["linear_solve"] > 0
    # the raw quaternion's scale direction makes plain Gauss-Newton singular in that form
    singular = form == "quaternion" and damping == "fixed"
    assert (summary.n_pseudo_inverse > 0) == singular


@pytest.mark.parametrize("form", ["tangent", "quaternion"])
def test_thesis_conditioning_converges_monotonically(
        hand, cameras, q_true, form, point_problem, perturb,
):
    problem = point_problem(hand, cameras, q_true, form=form)
    x0 = perturb(hand, q_true, np.random.default_rng(2))
    options = GaussNewtonOptions(max_iterations=60, conditioning=hand_conditioning(hand, form=form))
    x, summary = gauss_newton(problem, x0, options)
    assert state_error(hand, x, q_true) < 0.01
    assert summary.cost_final < 1e-6 * summary.cost_initial
    assert np.all(np.diff(summary.cost_history) <= 0)


def test_conditioning_shrinks_the_step(hand, cameras, q_true, point_problem, perturb):
    """With S the step minimises the model plus dv^T S dv / 2, so its S-norm cannot exceed
    the plain Gauss-Newton step's; with the thesis weights the step is also shorter."""
    problem = point_problem(hand, cameras, q_true)
    x0 = perturb(hand, q_true, np.random.default_rng(3), joint=0.2)
    S = hand_conditioning(hand)
    steps = {}
    for name, conditioning in (("plain", None), ("conditioned", S)):
        x1, summary = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=1,
                                                                   conditioning=conditioning))
        steps[name] = difference(hand, x0, x1)
        assert summary.step_norms[0] == pytest.approx(np.linalg.norm(steps[name]), rel=1e-9)
    s_norm = {k: v @ (S * v) for k, v in steps.items()}
    assert s_norm["conditioned"] < s_norm["plain"]
    assert np.linalg.norm(steps["conditioned"]) < np.linalg.norm(steps["plain"])


def test_quaternion_form_equals_tangent_form_with_quarter_weight(
        hand, cameras, q_true, point_problem, perturb,
):
    """Thesis quaternion form with weight w and the tangent form with w/4 solve the same
    linear system (|dq| = |dtheta|/2): the first steps agree to first order in rotation and
    exactly in the joints and translation."""
    x0 = perturb(hand, q_true, np.random.default_rng(4))
    results = {}
    for form, quaternion_weight in (("quaternion", 1.0), ("tangent", 0.25)):
        problem = point_problem(hand, cameras, q_true, form=form)
        S = hand_conditioning(hand, quaternion=quaternion_weight, form=form)
        results[form], _ = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=1,
                                                                        conditioning=S))
    dq, dt = (difference(hand, x0, results[f]) for f in ("quaternion", "tangent"))
    np.testing.assert_allclose(dq[3:], dt[3:], atol=1e-9)
    rotation = np.linalg.norm(dt[:3])
    assert rotation > 1e-3
    assert np.linalg.norm(dq[:3] - dt[:3]) < rotation**2


def test_singular_problem_uses_pseudo_inverse_and_conditioning_holds_unseen_states(
        hand, cameras, q_true, point_problem, perturb,
):
    """Only the index tip is observed (4 residuals, 27 unknowns): plain Gauss-Newton needs
    the pseudo-inverse; with S every state that does not move the tip stays put."""
    tip = hand.link("index.tip")
    problem = point_problem(hand, cameras, q_true, rows=np.array([tip.row]),
                                    points=np.zeros((1, 3)))
    x0 = perturb(hand, q_true, np.random.default_rng(5), joint=0.05)
    _, plain_summary = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=3))
    assert plain_summary.n_pseudo_inverse > 0
    assert plain_summary.cost_final < 1e-6 * plain_summary.cost_initial
    x, summary = gauss_newton(problem, x0, GaussNewtonOptions(
        max_iterations=3, conditioning=hand_conditioning(hand)))
    assert summary.n_pseudo_inverse == 0
    assert summary.cost_final < 0.5 * summary.cost_initial
    unseen = [hand.state_index(n) for n in hand.state_names
              if n.split(".")[0] in ("middle", "ring", "little", "thumb")]
    np.testing.assert_array_equal(x[unseen], x0[unseen])


class BoundedLinearProblem:
    """``r = A x - b`` with ``x1 <= 0``: the unconstrained minimum is (1, 1), the bounded
    one (3, 0). A full step from the bound goes to (1, 1) and is clipped back to (1, 0)
    every time, so projection alone does not reach (3, 0): Gauss-Newton stays at (1, 0),
    Levenberg-Marquardt creeps along with shortened steps."""

    n_v = 2
    A = np.array([[1.0, 2.0], [0.0, 1.0]])
    b = np.array([3.0, 1.0])

    def residuals(self, x, jacobian):
        return self.A @ x - self.b, self.A if jacobian else None

    def retract(self, x, dv):
        return x + dv

    def project(self, x):
        return np.array([x[0], min(x[1], 0.0)])


class HeldBoundedLinearProblem(BoundedLinearProblem):
    def held(self, x, gradient):
        return np.array([False, x[1] >= 0.0 and gradient[1] < 0.0])


@pytest.mark.parametrize("damping", ["fixed", "levenberg-marquardt"])
def test_a_step_column_held_at_its_bound_lets_the_others_reach_the_bounded_minimum(damping):
    options = GaussNewtonOptions(max_iterations=20, damping=damping)
    x, summary = gauss_newton(HeldBoundedLinearProblem(), np.zeros(2), options)
    np.testing.assert_allclose(x, [3.0, 0.0], atol=1e-9)
    assert summary.cost_final == pytest.approx(0.5)  # 0.5 |r|^2 with r = (0, -1)
    stalled, _ = gauss_newton(BoundedLinearProblem(), np.zeros(2), options)
    assert abs(stalled[0] - 3.0) > 0.3  # projection alone: stuck at (1, 0), or creeping


def test_levenberg_marquardt_rejects_steps_where_gauss_newton_diverges():
    x0 = np.array([3.0])
    _, fixed = gauss_newton(ArctanProblem(), x0, GaussNewtonOptions(max_iterations=5))
    assert fixed.cost_history[-1] > fixed.cost_history[0]
    x, lm = gauss_newton(ArctanProblem(), x0, GaussNewtonOptions(
        max_iterations=50, damping="levenberg-marquardt"))
    assert abs(x[0]) < 1e-6
    assert lm.n_rejected > 0
    assert np.all(np.diff(lm.cost_history) < 0)
    assert lm.converged


@pytest.mark.parametrize("loss", ["huber", "tukey"])
def test_robust_loss_downweights_an_outlier(hand, cameras, q_true, loss, point_problem, perturb):
    problem = point_problem(hand, cameras, q_true)
    problem.targets[0][5] += (40.0, -25.0)
    x0 = perturb(hand, q_true, np.random.default_rng(6), joint=0.05)
    plain, _ = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=20))
    x, summary = gauss_newton(problem, x0, GaussNewtonOptions(
        max_iterations=30, robust_loss=loss, scale_px=3.0))
    error_plain, error = state_error(hand, plain, q_true), state_error(hand, x, q_true)
    assert error < 0.5 * error_plain
    if loss == "tukey":
        assert error < 1e-6
    r, _ = problem.residuals(x, False)
    assert summary.cost_final == pytest.approx(robust_cost(r, loss, 3.0).sum(), rel=1e-9)


def test_clipping_keeps_states_in_limits(hand, cameras, q_true, point_problem):
    q_limit = q_true.copy()
    pip = hand.state_index("index.pip")
    q_limit[pip] = hand.lower[pip]
    problem = point_problem(hand, cameras, q_limit, clip=True)
    x0 = q_limit.copy()
    x0[pip] += 0.2
    x, _ = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=10))
    assert np.all(x >= hand.lower) and np.all(x <= hand.upper)
    assert x[pip] == pytest.approx(hand.lower[pip], abs=1e-9)


def test_no_residuals_and_zero_iterations(hand, cameras, q_true, point_problem, perturb):
    empty = point_problem(hand, cameras, q_true, rows=np.zeros(0, dtype=int),
                                  points=np.zeros((0, 3)))
    x0 = perturb(hand, q_true, np.random.default_rng(7))
    x, summary = gauss_newton(empty, x0)
    np.testing.assert_array_equal(x, x0)
    assert summary.termination == "no residuals"
    assert summary.n_residuals == 0 and summary.iterations == 0
    problem = point_problem(hand, cameras, q_true)
    x, summary = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=0))
    np.testing.assert_array_equal(x, x0)
    assert summary.termination == "max_iterations"
    assert summary.cost_final == summary.cost_initial > 0


def test_step_and_cost_tolerances(hand, cameras, q_true, point_problem, perturb):
    problem = point_problem(hand, cameras, q_true)
    x0 = perturb(hand, q_true, np.random.default_rng(8))
    _, summary = gauss_newton(problem, x0, GaussNewtonOptions(max_iterations=50,
                                                              step_tolerance=1e-3))
    assert summary.termination == "converged: step"
    assert summary.step_norms[-1] <= 1e-3 < min(summary.step_norms[:-1])
    _, summary = gauss_newton(problem, x0, GaussNewtonOptions(
        max_iterations=50, step_tolerance=0.0, cost_tolerance=0.5))
    assert summary.termination == "converged: cost"
    assert summary.cost_history[-2] - summary.cost_history[-1] <= 0.5 * summary.cost_history[-2]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"max_iterations": -1}, "max_iterations"),
    ({"max_iterations": 2.5}, "max_iterations"),
    ({"conditioning": [1.0, -1.0]}, "non-negative"),
    ({"conditioning": [[1.0]]}, "1-D"),
    ({"damping": "dogleg"}, "damping"),
    ({"robust_loss": "cauchy"}, "robust_loss"),
    ({"scale_px": 0.0}, "scale_px"),
    ({"step_tolerance": -1.0}, "step_tolerance"),
    ({"cost_tolerance": np.nan}, "cost_tolerance"),
    ({"initial_lambda": 0.0}, "initial_lambda"),
])
def test_options_are_validated(kwargs, match):
    with pytest.raises(ValueError, match=match):
        GaussNewtonOptions(**kwargs)


def test_options_are_frozen_and_comparable():
    a = GaussNewtonOptions(conditioning=np.array([1.0, 2.0]))
    assert a == GaussNewtonOptions(conditioning=(1.0, 2.0))
    assert a.conditioning == (1.0, 2.0)
    with pytest.raises(AttributeError):
        a.max_iterations = 3


def test_bad_conditioning_length_and_bad_problem_shapes(hand, cameras, q_true, point_problem):
    problem = point_problem(hand, cameras, q_true)
    with pytest.raises(ValueError, match="n_v = 27"):
        gauss_newton(problem, q_true, GaussNewtonOptions(conditioning=np.ones(28)))

    class WrongJacobian(ArctanProblem):
        def residuals(self, x, jacobian):
            return np.arctan(x), np.ones((1, 2)) if jacobian else None

    with pytest.raises(ValueError, match="shape"):
        gauss_newton(WrongJacobian(), np.array([1.0]))


def test_solve_normal_equations_matches_numpy_and_pseudo_inverse():
    rng = np.random.default_rng(9)
    J = rng.normal(size=(10, 4)) * [1.0, 100.0, 0.01, 3.0]
    A, g = J.T @ J, rng.normal(size=4)
    x, truncated = solve_normal_equations(A, g)
    np.testing.assert_allclose(x, np.linalg.solve(A, g), rtol=1e-8)
    assert not truncated
    J[:, 3] = 0.0
    A = J.T @ J
    x, truncated = solve_normal_equations(A, g)
    assert truncated
    np.testing.assert_allclose(x, np.linalg.pinv(A) @ g, rtol=1e-7)


@pytest.mark.parametrize("conditioned", [False, True])
@pytest.mark.parametrize("lam", [0.0, 0.37])
def test_the_compiled_step_system_is_numpys_to_the_bit(conditioned, lam):
    """``damped_system`` makes the additions of eq. 2.22 with Levenberg-Marquardt damping
    in numpy's order, and holds columns as the identity's, so every track stays the same."""
    rng = np.random.default_rng(3)
    J = rng.normal(size=(40, 9)) * np.logspace(-3, 3, 9)
    r = rng.normal(size=40)
    H, g = J.T @ J, J.T @ r
    S = rng.uniform(0.0, 5.0, 9) if conditioned else np.zeros(9)
    held = np.zeros(9, dtype=bool)
    held[[2, 7]] = True
    h = np.diag(H)
    A_want = (H + np.diag(S) if conditioned else H) + lam * np.diag(
        np.maximum(h, 1e-6 * max(float(h.max()), 1e-300)))
    A_want[held, :] = 0.0
    A_want[:, held] = 0.0
    A_want[held, held] = 1.0
    b_want = np.where(held, 0.0, g)
    A, b = np.empty((9, 9)), np.empty(9)
    damped_system(H, g, S, lam, held, A, b)
    np.testing.assert_array_equal(A, A_want)
    np.testing.assert_array_equal(b, b_want)
