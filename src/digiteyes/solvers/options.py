"""Settings of the Gauss-Newton solver, validated on construction (Ceres' ``Solver::Options``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from digiteyes.solvers.robust import ROBUST_LOSSES, RobustLoss

Damping = Literal["fixed", "levenberg-marquardt"]
DAMPINGS = ("fixed", "levenberg-marquardt")


@dataclass(frozen=True)
class GaussNewtonOptions:
    """Options of :func:`~digiteyes.solvers.gauss_newton`.

    Attributes
    ----------
    max_iterations : steps at most (the thesis runs a fixed number per frame).
    conditioning : diagonal of the conditioning matrix ``S`` of thesis eq. 2.22, one
        non-negative weight per step component (length ``n_v`` of the problem), or
        ``None`` for plain Gauss-Newton. Stored as a tuple of floats. See
        :func:`~digiteyes.solvers.hand_conditioning` for the thesis weights.
    damping : ``"fixed"`` takes every step ``-(J^T W J + S)^-1 J^T W r`` (thesis);
        ``"levenberg-marquardt"`` adds ``lambda diag(J^T W J)`` with an adaptive
        ``lambda``, evaluates the cost at the candidate and rejects steps that raise it.
    robust_loss : ``None``, ``"huber"`` or ``"tukey"`` (IRLS weights ``W``; see
        :mod:`digiteyes.solvers.robust`).
    scale_px : scale of the robust loss, in the residual's units (pixels for images).
    step_tolerance : stop when the step norm falls to this (mixed units, rad and mm).
    cost_tolerance : stop when an accepted step lowers the cost by at most this fraction.
    initial_lambda : starting LM damping (dimensionless, multiplies ``diag(J^T W J)``).
    max_lambda : LM gives up (``"converged: no decrease"``) when ``lambda`` exceeds this.
    """

    max_iterations: int = 10
    conditioning: tuple[float, ...] | np.ndarray | None = None
    damping: Damping = "fixed"
    robust_loss: RobustLoss | None = None
    scale_px: float = 5.0
    step_tolerance: float = 1e-8
    cost_tolerance: float = 1e-10
    initial_lambda: float = 1e-3
    max_lambda: float = 1e10

    def __post_init__(self) -> None:
        if isinstance(self.max_iterations, bool) or not isinstance(
                self.max_iterations, int | np.integer) or self.max_iterations < 0:
            raise ValueError(
                f"max_iterations must be a non-negative integer, got {self.max_iterations!r}"
            )
        if self.conditioning is not None:
            s = np.asarray(self.conditioning, dtype=float)
            if s.ndim != 1 or not np.isfinite(s).all() or (s < 0).any():
                raise ValueError(
                    "conditioning must be a 1-D vector of finite non-negative weights (the "
                    f"diagonal of S), got {np.array2string(s, threshold=10)}"
                )
            object.__setattr__(self, "conditioning", tuple(float(v) for v in s))
        if self.damping not in DAMPINGS:
            raise ValueError(
                f"damping must be 'fixed' or 'levenberg-marquardt', got {self.damping!r}"
            )
        if self.robust_loss is not None and self.robust_loss not in ROBUST_LOSSES:
            raise ValueError(
                f"robust_loss must be None, 'huber' or 'tukey', got {self.robust_loss!r}"
            )
        for name in ("scale_px", "initial_lambda", "max_lambda"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name in ("step_tolerance", "cost_tolerance"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
