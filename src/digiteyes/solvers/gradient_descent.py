"""Gradient descent with a fixed step size (thesis eq. 2.12), for comparison and ablation.

    x_{k+1} = project(retract(x_k, -rho * dE/dv(x_k))),     dE/dv = J^T W r

``rho`` is the step size: a scalar, or one value per step component (a diagonal
preconditioner, useful because rotations, translations and joint angles differ in units).
There is no line search, as in the thesis; too large a ``rho`` diverges.
"""

from __future__ import annotations

import time

import numpy as np

from digiteyes.solvers.gauss_newton import evaluate
from digiteyes.solvers.problem import LeastSquaresProblem, SolverSummary, project_if_defined
from digiteyes.solvers.robust import RobustLoss, robust_cost, robust_weights


def gradient_descent(
    problem: LeastSquaresProblem,
    x0: np.ndarray,
    step_size: float | np.ndarray,
    max_iterations: int = 100,
    *,
    robust_loss: RobustLoss | None = None,
    scale_px: float = 5.0,
    step_tolerance: float = 0.0,
    cost_tolerance: float = 0.0,
) -> tuple[np.ndarray, SolverSummary]:
    """Minimise ``E(x) = sum_i rho(r_i(x))`` by fixed-step gradient descent (thesis eq. 2.12).

    Parameters
    ----------
    problem : any :class:`~digiteyes.solvers.LeastSquaresProblem`.
    x0 : starting parameters.
    step_size : ``rho``, scalar or (n_v,), in step units per unit of gradient
        (for pixel residuals: rad / px^2 for joint angles, mm / px^2 for translations).
    max_iterations : steps to take at most.
    robust_loss, scale_px : as in :class:`~digiteyes.solvers.GaussNewtonOptions`.
    step_tolerance : stop when the step norm falls to this.
    cost_tolerance : stop when a step lowers the cost by at most this fraction.

    Returns
    -------
    x, summary : final parameters and a :class:`SolverSummary` (``linear_solve`` timing
        holds the gradient and update).
    """
    n_v = int(problem.n_v)
    rho = np.asarray(step_size, dtype=float)
    if rho.shape not in ((), (n_v,)) or not np.isfinite(rho).all() or (rho <= 0).any():
        raise ValueError(
            f"step_size must be a positive scalar or a positive vector of length n_v = {n_v}"
        )
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int | np.integer) \
            or max_iterations < 0:
        raise ValueError(f"max_iterations must be a non-negative integer, got {max_iterations!r}")
    for name, value in (("step_tolerance", step_tolerance), ("cost_tolerance", cost_tolerance)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    summary = SolverSummary()
    x = project_if_defined(problem, np.array(x0, dtype=float))
    r, J = evaluate(problem, x, max_iterations > 0, summary)
    cost = float(robust_cost(r, robust_loss, scale_px).sum())
    summary.cost_initial = cost
    summary.cost_history.append(cost)
    summary.n_residuals = len(r)
    summary.termination = "no residuals" if len(r) == 0 else "max_iterations"
    while len(r) and summary.iterations < max_iterations:
        start = time.perf_counter()
        gradient = J.T @ (robust_weights(r, robust_loss, scale_px) * r)
        dv = -rho * gradient
        x_new = project_if_defined(problem, problem.retract(x, dv))
        summary.timings["linear_solve"] += time.perf_counter() - start
        step = float(np.linalg.norm(dv))
        last = summary.iterations + 1 >= max_iterations or step <= step_tolerance
        r_new, J_new = evaluate(problem, x_new, not last, summary)
        if len(r_new) == 0:
            summary.termination = "no residuals"
            break
        cost_prev = cost
        x, r, J = x_new, r_new, J_new
        cost = float(robust_cost(r, robust_loss, scale_px).sum())
        summary.iterations += 1
        summary.cost_history.append(cost)
        summary.step_norms.append(step)
        if step <= step_tolerance:
            summary.termination = "converged: step"
            break
        if 0 <= cost_prev - cost <= cost_tolerance * cost_prev:
            summary.termination = "converged: cost"
            break
    summary.cost_final = cost
    summary.n_residuals = len(r)
    return x, summary
