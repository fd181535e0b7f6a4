"""Solvers: stabilised Gauss-Newton / Levenberg-Marquardt (thesis eq. 2.22) and gradient
descent (thesis eq. 2.12) over any :class:`LeastSquaresProblem`, with robust losses."""

from digiteyes.solvers.conditioning import hand_conditioning
from digiteyes.solvers.gauss_newton import gauss_newton, solve_normal_equations
from digiteyes.solvers.gradient_descent import gradient_descent
from digiteyes.solvers.options import GaussNewtonOptions
from digiteyes.solvers.problem import LeastSquaresProblem, SolverSummary
from digiteyes.solvers.robust import robust_cost, robust_weights

__all__ = [
    "GaussNewtonOptions", "LeastSquaresProblem", "SolverSummary", "gauss_newton",
    "gradient_descent", "hand_conditioning", "robust_cost", "robust_weights",
    "solve_normal_equations",
]
