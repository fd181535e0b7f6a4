"""What a solver needs from a problem, and what it reports back.

Solvers know protocols, not hands (STYLE.md practice 6): anything with a step size
``n_v``, a residual function and a retraction can be minimised. The hand trackers wrap
forward kinematics, feature measurement and cameras into such an object; the tests use
plain point-alignment problems.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class LeastSquaresProblem(Protocol):
    """A nonlinear least-squares problem ``min_x E(x) = sum_i rho(r_i(x))``.

    ``x`` is the problem's own parameter vector (a hand state of ``n_q`` numbers); steps
    live in a vector space of ``n_v`` numbers and are applied with :meth:`retract`.

    An optional method ``project(x) -> x`` (for example clipping joint limits) is applied
    after every retraction when the problem defines it. A problem with such bounds may
    also define ``held(x, gradient) -> bool (n_v,)``: the step columns at a bound whose
    descent direction ``-gradient`` points out of it, which the solver then holds for
    that step (the active set of Bertsekas' projected Newton method): without it a
    Gauss-Newton step that leans on a bound is clipped back, can raise the cost, and
    Levenberg-Marquardt spends its evaluations shrinking the step (docs/solvers.md).
    """

    n_v: int

    def residuals(self, x: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Residuals ``r`` (M,) at ``x`` and, when ``jacobian`` is true, ``J = dr/dv``
        (M, n_v) for a step ``v`` applied through :meth:`retract`; otherwise ``None``."""
        ...

    def retract(self, x: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """The parameters reached from ``x`` by the step ``dv`` (n_v,)."""
        ...


def project_if_defined(problem: LeastSquaresProblem, x: np.ndarray) -> np.ndarray:
    """``problem.project(x)`` when the problem has one, else ``x``."""
    project = getattr(problem, "project", None)
    return x if project is None else project(x)


def held_if_defined(problem: LeastSquaresProblem, x: np.ndarray,
                    gradient: np.ndarray) -> np.ndarray | None:
    """``problem.held(x, gradient)`` when the problem has one and it holds a column,
    else None."""
    held = getattr(problem, "held", None)
    if held is None:
        return None
    mask = np.asarray(held(x, gradient), dtype=bool)
    return mask if mask.any() else None


@dataclass
class SolverSummary:
    """Why and how a solver stopped (Ceres' ``Solver::Summary``).

    Attributes
    ----------
    iterations : accepted steps taken.
    cost_initial, cost_final : ``E = sum_i rho(r_i)`` at the start and at the returned
        parameters (``0.5 ||r||^2`` without a robust loss; units of ``r`` squared).
    cost_history : cost at the start and after every accepted step.
    termination : ``"converged: step"``, ``"converged: cost"``, ``"max_iterations"``,
        ``"no residuals"``, ``"singular"`` or ``"converged: no decrease"`` (LM could not
        find a step that lowers the cost).
    n_residuals : residual count at the returned parameters.
    step_norms : Euclidean norm of every accepted step (mixed units: rad, mm).
    n_rejected : Levenberg-Marquardt steps rejected because the cost rose.
    n_pseudo_inverse : solves that fell back to the pseudo-inverse (singular normal matrix).
    timings : seconds spent in ``"residuals"`` (problem evaluations) and ``"linear_solve"``
        (normal equations, solve and retraction).
    """

    iterations: int = 0
    cost_initial: float = float("nan")
    cost_final: float = float("nan")
    cost_history: list[float] = field(default_factory=list)
    termination: str = ""
    n_residuals: int = 0
    step_norms: list[float] = field(default_factory=list)
    n_rejected: int = 0
    n_pseudo_inverse: int = 0
    timings: dict[str, float] = field(
        default_factory=lambda: {"residuals": 0.0, "linear_solve": 0.0}
    )

    @property
    def converged(self) -> bool:
        """True when the solver stopped on a convergence test."""
        return self.termination.startswith("converged")

    def report(self) -> str:
        """A short human-readable report."""
        return (
            f"{self.termination} after {self.iterations} iteration(s): cost "
            f"{self.cost_initial:.6g} -> {self.cost_final:.6g} over {self.n_residuals} "
            f"residual(s); {self.n_rejected} rejected step(s)"
        )
