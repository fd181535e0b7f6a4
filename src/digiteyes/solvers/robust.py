"""Robust losses for least squares, used as iteratively reweighted least squares (IRLS).

A loss ``rho(r)`` replaces the squared residual ``r**2 / 2`` of thesis eq. 2.21, so the
total cost is ``E = sum_i rho(r_i)``. Gauss-Newton then solves a weighted system with the
IRLS weight ``w(r) = rho'(r) / r`` of each residual, evaluated at the current iterate
(the gradient of ``E`` is ``J^T W r`` exactly; ``J^T W J`` approximates its Hessian).

All three losses agree with ``r**2 / 2`` near zero. ``scale`` (pixels for image
residuals) is where a loss stops being quadratic:

* ``"none"``  ``rho = r^2 / 2``,                                   ``w = 1``;
* ``"huber"`` ``rho = r^2 / 2`` for ``|r| <= k``, ``k |r| - k^2 / 2`` beyond,
  ``w = min(1, k / |r|)``: an outlier's pull is capped at ``k``;
* ``"tukey"`` (biweight) ``rho = c^2 / 6 (1 - (1 - (r/c)^2)^3)`` for ``|r| <= c``,
  ``c^2 / 6`` beyond, ``w = (1 - (r/c)^2)^2`` inside and 0 outside: outliers beyond ``c``
  are ignored. Not convex: start close to the answer (tracking does).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

RobustLoss = Literal["huber", "tukey"]
ROBUST_LOSSES = ("huber", "tukey")


def _check(loss: str | None, scale: float) -> None:
    if loss is not None and loss not in ROBUST_LOSSES:
        raise ValueError(f"robust loss must be None, 'huber' or 'tukey', got {loss!r}")
    if loss is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"robust loss scale must be a positive number, got {scale!r}")


def robust_cost(r: np.ndarray, loss: RobustLoss | None = None, scale: float = 1.0) -> np.ndarray:
    """Per-residual cost ``rho(r)`` (same shape as ``r``; units of ``r`` squared).

    Parameters
    ----------
    r : residuals, any shape (pixels for image residuals).
    loss : ``None`` (plain least squares), ``"huber"`` or ``"tukey"``.
    scale : where the loss leaves the quadratic, in the units of ``r``.
    """
    _check(loss, scale)
    r = np.asarray(r, dtype=float)
    if loss is None:
        return 0.5 * r * r
    a = np.abs(r)
    if loss == "huber":
        return np.where(a <= scale, 0.5 * r * r, scale * a - 0.5 * scale * scale)
    u = np.minimum(a / scale, 1.0)
    return scale * scale / 6.0 * (1.0 - (1.0 - u * u) ** 3)


def robust_weights(r: np.ndarray, loss: RobustLoss | None = None, scale: float = 1.0) -> np.ndarray:
    """IRLS weights ``w(r) = rho'(r) / r`` (dimensionless, in [0, 1], same shape as ``r``)."""
    _check(loss, scale)
    r = np.asarray(r, dtype=float)
    if loss is None:
        return np.ones_like(r)
    a = np.abs(r)
    if loss == "huber":
        return np.where(a <= scale, 1.0, scale / np.maximum(a, scale))
    u = np.minimum(a / scale, 1.0)
    return (1.0 - u * u) ** 2
