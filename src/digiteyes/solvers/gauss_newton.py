"""Stabilised Gauss-Newton (thesis eq. 2.22, report eq. 5) and Levenberg-Marquardt.

Each iteration linearises the residuals at ``x_k`` and takes the step

    dv = -(J^T W J + S + lambda D)^-1 J^T W r,        x_{k+1} = project(retract(x_k, dv))

with ``J`` the (M, n_v) residual Jacobian, ``W`` the IRLS weights of a robust loss (the
identity without one), ``S`` the constant diagonal conditioning matrix of thesis eq. 2.22
and, for Levenberg-Marquardt only, ``D = diag(J^T W J)`` scaled by an adaptive ``lambda``.
With ``damping="fixed"`` every step is taken, as in the thesis; with
``"levenberg-marquardt"`` the cost is evaluated at the candidate and a step that raises it
is rejected and retried with a larger ``lambda`` (Nielsen's update of ``lambda``).

The linear system is Jacobi-scaled and solved by Cholesky; when the scaled matrix is
(numerically) singular, a symmetric eigendecomposition drops eigenvalues below ``1e-10``
of the largest, so an exactly singular system (a kinematic singularity without
conditioning, or the scale direction of the raw quaternion form) gets the minimum-norm
pseudo-inverse step of thesis Sec. 4.3.2 step 6.

A problem with bounds (``project``) may name, at each iterate, the step columns held at a
bound (``held``, :class:`~digiteyes.solvers.problem.LeastSquaresProblem`): they are fixed
at zero in that step's system and the free columns are solved for (projected Newton with
an active set).
"""

from __future__ import annotations

import math
import time

import numpy as np

from digiteyes.solvers._kernels import damped_system, scaled_cholesky_solve
from digiteyes.solvers.options import GaussNewtonOptions
from digiteyes.solvers.problem import (
    LeastSquaresProblem,
    SolverSummary,
    held_if_defined,
    project_if_defined,
)
from digiteyes.solvers.robust import robust_cost, robust_weights

RELATIVE_EIGENVALUE_FLOOR = 1e-10


def evaluate(
    problem: LeastSquaresProblem, x: np.ndarray, jacobian: bool, summary: SolverSummary
) -> tuple[np.ndarray, np.ndarray | None]:
    """Call ``problem.residuals``, time it into ``summary`` and check the shapes."""
    start = time.perf_counter()
    r, J = problem.residuals(x, jacobian)
    summary.timings["residuals"] += time.perf_counter() - start
    r = np.asarray(r, dtype=float)
    if r.ndim != 1:
        raise ValueError(f"problem.residuals must return r of shape (M,), got {r.shape}")
    if not np.isfinite(r).all():
        raise ValueError("problem.residuals returned non-finite residuals")
    if jacobian:
        J = np.asarray(J, dtype=float)
        if J.shape != (len(r), problem.n_v):
            raise ValueError(
                f"problem.residuals must return J of shape (M, n_v) = ({len(r)}, "
                f"{problem.n_v}), got {J.shape}"
            )
    return r, J


def solve_normal_equations(A: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, bool]:
    """Solve ``A x = g`` for symmetric positive semi-definite ``A`` (n, n).

    Returns the solution and whether eigenvalues were dropped (pseudo-inverse). The system
    is Jacobi-scaled first so that mixed units (rad, mm) do not decide the rank. A Cholesky
    factorisation serves well-conditioned systems; when a pivot of the scaled matrix falls
    below the eigenvalue floor, a symmetric eigendecomposition gives the pseudo-inverse.
    """
    A = np.ascontiguousarray(A, dtype=float)
    g = np.ascontiguousarray(g, dtype=float)
    x = np.empty(len(g))
    if scaled_cholesky_solve(A, g, RELATIVE_EIGENVALUE_FLOOR, x):
        return x, False
    diag = np.diag(A)
    d = np.where(diag > 0, 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0)), 0.0)
    A_scaled = A * d[:, None] * d[None, :]
    g_scaled = d * g
    eigenvalues, V = np.linalg.eigh(A_scaled)
    floor = RELATIVE_EIGENVALUE_FLOOR * max(float(eigenvalues[-1]), 0.0)
    keep = eigenvalues > floor
    inverse = np.zeros_like(eigenvalues)
    inverse[keep] = 1.0 / eigenvalues[keep]
    x_scaled = V @ (inverse * (V.T @ g_scaled))
    return d * x_scaled, bool((~keep).any())


def _check_conditioning(options: GaussNewtonOptions, n_v: int) -> np.ndarray | None:
    if options.conditioning is None:
        return None
    S = np.asarray(options.conditioning, dtype=float)
    if S.shape != (n_v,):
        raise ValueError(
            f"conditioning has {S.size} weights but the problem's step has n_v = {n_v}"
        )
    return S


def gauss_newton(
    problem: LeastSquaresProblem,
    x0: np.ndarray,
    options: GaussNewtonOptions | None = None,
) -> tuple[np.ndarray, SolverSummary]:
    """Minimise ``E(x) = sum_i rho(r_i(x))`` by stabilised Gauss-Newton (thesis eq. 2.22).

    Parameters
    ----------
    problem : any :class:`~digiteyes.solvers.LeastSquaresProblem`.
    x0 : starting parameters (projected with ``problem.project`` if defined).
    options : :class:`GaussNewtonOptions`; defaults to 10 plain Gauss-Newton steps.

    Returns
    -------
    x : the final parameters.
    summary : :class:`SolverSummary` (costs, steps, why it stopped, timings).

    Examples
    --------
    >>> x, summary = gauss_newton(problem, x0, GaussNewtonOptions(          # doctest: +SKIP
    ...     conditioning=hand_conditioning(model), max_iterations=5))
    >>> summary.termination                                                  # doctest: +SKIP
    'max_iterations'
    """
    options = GaussNewtonOptions() if options is None else options
    n_v = int(problem.n_v)
    S = _check_conditioning(options, n_v)
    loss, scale = options.robust_loss, options.scale_px
    levenberg = options.damping == "levenberg-marquardt"
    summary = SolverSummary()
    x = project_if_defined(problem, np.array(x0, dtype=float))
    r, J = evaluate(problem, x, options.max_iterations > 0, summary)
    cost = float(robust_cost(r, loss, scale).sum())
    summary.cost_initial = summary.cost_final = cost
    summary.cost_history.append(cost)
    summary.n_residuals = len(r)
    if len(r) == 0:
        summary.termination = "no residuals"
        return x, summary
    lam, nu = options.initial_lambda, 2.0
    S_diagonal = np.zeros(n_v) if S is None else S
    A, b, no_hold = np.empty((n_v, n_v)), np.empty(n_v), np.zeros(n_v, dtype=bool)
    summary.termination = "max_iterations"
    while summary.iterations < options.max_iterations:
        start = time.perf_counter()
        JW = J if loss is None else J * robust_weights(r, loss, scale)[:, None]
        H = JW.T @ J
        g = JW.T @ r
        held = held_if_defined(problem, x, g)
        damped_system(np.ascontiguousarray(H), np.ascontiguousarray(g), S_diagonal,
                      lam if levenberg else 0.0, no_hold if held is None else held, A, b)
        dv, truncated = solve_normal_equations(A, b)
        dv = -dv
        summary.n_pseudo_inverse += truncated
        finite = bool(np.isfinite(dv).all())
        x_new = project_if_defined(problem, problem.retract(x, dv)) if finite else x
        summary.timings["linear_solve"] += time.perf_counter() - start
        if not finite:
            summary.termination = "singular"
            break
        step = math.sqrt(float(dv @ dv))
        last = summary.iterations + 1 >= options.max_iterations or step <= options.step_tolerance
        r_new, J_new = evaluate(problem, x_new, levenberg or not last, summary)
        cost_new = float(robust_cost(r_new, loss, scale).sum()) if len(r_new) else np.inf
        if levenberg:
            predicted = -(g @ dv + 0.5 * dv @ H @ dv)
            if not cost_new < cost:
                summary.n_rejected += 1
                lam *= nu
                nu *= 2.0
                if lam > options.max_lambda:
                    summary.termination = "converged: no decrease"
                    break
                continue
            ratio = (cost - cost_new) / max(predicted, 1e-300)
            lam *= max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3)
            nu = 2.0
        elif len(r_new) == 0:
            summary.termination = "no residuals"
            break
        cost_prev = cost
        x, r, J, cost = x_new, r_new, J_new, cost_new
        summary.iterations += 1
        summary.cost_history.append(cost)
        summary.step_norms.append(step)
        if step <= options.step_tolerance:
            summary.termination = "converged: step"
            break
        if cost_prev - cost <= options.cost_tolerance * cost_prev and cost <= cost_prev:
            summary.termination = "converged: cost"
            break
    summary.cost_final = cost
    summary.n_residuals = len(r)
    return x, summary
