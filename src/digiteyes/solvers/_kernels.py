"""Compiled small dense solve for the normal equations (numba).

A profile of one tracker iteration showed ``scipy.linalg.cho_factor``/``cho_solve`` plus
the Jacobi scaling costing ~95 us for a 27x27 system, almost all of it call overhead; this
kernel does the same arithmetic in ~3 us.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def scaled_cholesky_solve(A, g, pivot_floor, x):  # pragma: no cover - compiled
    """Solve ``A x = g`` (A symmetric, n x n) by Jacobi scaling and Cholesky.

    ``A`` is scaled to unit diagonal, ``A_s = D A D`` with ``D = diag(A)^-1/2``; returns
    False (leaving ``x`` undefined) when a diagonal entry is not positive or a squared
    pivot of the scaled factor falls to ``pivot_floor`` or below, so the caller can fall
    back to a pseudo-inverse.
    """
    n = A.shape[0]
    d = np.empty(n)
    for i in range(n):
        if not A[i, i] > 0.0:
            return False
        d[i] = 1.0 / np.sqrt(A[i, i])
    L = np.zeros((n, n))
    for j in range(n):
        s = A[j, j] * d[j] * d[j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > pivot_floor:
            return False
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            t = A[i, j] * d[i] * d[j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    y = np.empty(n)
    for i in range(n):
        t = g[i] * d[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, n):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]
    for i in range(n):
        x[i] *= d[i]
    return True


@njit(cache=True)
def damped_system(H, g, S, lam, held, A, b):  # pragma: no cover - compiled
    """Fill the step's system ``A dv = b`` from ``H = J^T W J`` and ``g = J^T W r``:
    ``A = (H + diag(S)) + lam diag(max(h, 1e-6 max(h)))`` with ``h = diag(H)`` (thesis eq.
    2.22 with Levenberg-Marquardt damping; ``lam = 0``: none) and ``b = g``, except that
    the rows and columns of the ``held`` step columns are the identity's and their ``b``
    is 0 (they stay at zero in the step). The additions are those numpy would make, in
    its order, so the step is the same to the bit."""
    n = H.shape[0]
    h_max = H[0, 0]
    for i in range(1, n):
        h_max = max(h_max, H[i, i])
    floor = 1e-6 * max(h_max, 1e-300)
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.0 if held[i] or held[j] else H[i, j]
        if held[i]:
            A[i, i] = 1.0
            b[i] = 0.0
        else:
            A[i, i] = (H[i, i] + S[i]) + lam * max(H[i, i], floor)
            b[i] = g[i]
