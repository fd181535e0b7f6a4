"""Similarity alignment of point sets (Procrustes / Kabsch with scale).

Used to place a model's palm on measured points before an iterative fit: the palm joints
are fixed in the palm frame, so one rotation, translation and scale align them.
"""

from __future__ import annotations

import numpy as np

from digiteyes.errors import DigitEyesError


def kabsch(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Rotation ``R`` (3, 3), translation ``t`` (3,) and scale ``c`` minimising
    ``sum_i |c R x_i + t - y_i|^2`` over matched points ``x_i`` (source) and ``y_i``
    (target), both (P, 3) in the same units (mm).

    Umeyama's closed form: the SVD ``U S V^T`` of the cross-covariance ``Y^T X`` of the
    centred sets gives ``R = U D V^T`` with ``D = diag(1, 1, det(U V^T))`` (keeps
    ``det R = +1``, no reflection), and ``c = trace(S D) / sum |x_i - mean x|^2``.
    Raises :class:`DigitEyesError` for fewer than three points or mismatched shapes.
    """
    source = np.asarray(source, dtype=float)
    target = np.asarray(target, dtype=float)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3 \
            or len(source) < 3:
        raise DigitEyesError(f"kabsch needs two (P, 3) point sets with P >= 3, got "
                             f"{source.shape} and {target.shape}")
    mu_x, mu_y = source.mean(0), target.mean(0)
    X, Y = source - mu_x, target - mu_y
    U, sigma, Vt = np.linalg.svd(Y.T @ X)
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    R = U @ flip @ Vt
    spread = float((X ** 2).sum())
    c = float(np.trace(np.diag(sigma) @ flip) / spread) if spread > 0 else 1.0
    return R, mu_y - c * R @ mu_x, c
