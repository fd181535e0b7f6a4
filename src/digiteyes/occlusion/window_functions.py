"""Window functions of the occlusion model, compiled (numba): the signed distance of a
pixel to a part's image window (a capsule for a cylinder link, a convex quadrilateral for
a template plane) with its derivatives, and the window value ``M`` (unit or smooth) at
that distance (Rehg thesis Sec. 3.3: the windows ``M_k`` of the layered model).

Shared by the list-priority segmentation (:mod:`digiteyes.occlusion.segmentation`), the
overlap test of the visibility order and the layered template error
(:mod:`digiteyes.templates.layered`). Window kinds: capsule 0, polygon 1
(:mod:`digiteyes.occlusion.windows`).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def capsule_distance(pts, r, wx, wy, gw, gp):  # pragma: no cover - compiled
    """Signed distance (px, positive inside) of ``(wx, wy)`` to the capsule of segment
    ``pts[0]``-``pts[1]`` and radius ``r``; fills ``gw`` (2) and ``gp`` (4, 2) with its
    derivatives by the pixel and the points (the derivative by ``r`` is 1)."""
    ax, ay, bx, by = pts[0, 0], pts[0, 1], pts[1, 0], pts[1, 1]
    ex, ey = bx - ax, by - ay
    l2 = ex * ex + ey * ey
    t = 0.0
    if l2 > 1e-12:
        t = ((wx - ax) * ex + (wy - ay) * ey) / l2
        t = min(1.0, max(0.0, t))
    dx, dy = wx - (ax + t * ex), wy - (ay + t * ey)
    dist = np.sqrt(dx * dx + dy * dy)
    nx, ny = 0.0, 0.0
    if dist > 1e-9:
        nx, ny = dx / dist, dy / dist
    gw[0], gw[1] = -nx, -ny
    gp[:, :] = 0.0
    gp[0, 0], gp[0, 1] = (1.0 - t) * nx, (1.0 - t) * ny
    gp[1, 0], gp[1, 1] = t * nx, t * ny
    return r - dist


@njit(cache=True, inline="always")
def polygon_distance(pts, wx, wy, gw, gp):  # pragma: no cover - compiled
    """Signed distance (px, positive inside) of ``(wx, wy)`` to the convex quadrilateral
    ``pts`` (4, 2): the smallest distance inside any edge line; fills ``gw`` and ``gp``
    with its derivatives (of the edge that decides)."""
    area = 0.0
    for i in range(4):
        j = (i + 1) % 4
        area += pts[i, 0] * pts[j, 1] - pts[j, 0] * pts[i, 1]
    s = 1.0 if area >= 0.0 else -1.0
    best, best_i = 1e300, 0
    for i in range(4):
        j = (i + 1) % 4
        ex, ey = pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1]
        length = np.sqrt(ex * ex + ey * ey) + 1e-12
        d = s * (ex * (wy - pts[i, 1]) - ey * (wx - pts[i, 0])) / length
        if d < best:
            best, best_i = d, i
    i, j = best_i, (best_i + 1) % 4
    ax, ay, bx, by = pts[i, 0], pts[i, 1], pts[j, 0], pts[j, 1]
    ex, ey = bx - ax, by - ay
    length = np.sqrt(ex * ex + ey * ey) + 1e-12
    c = ex * (wy - ay) - ey * (wx - ax)
    k = s / length
    q = s * c / (length * length * length)
    gw[0], gw[1] = -ey * k, ex * k
    gp[:, :] = 0.0
    gp[i, 0] = (by - wy) * k + ex * q
    gp[i, 1] = (wx - bx) * k + ey * q
    gp[j, 0] = (wy - ay) * k - ex * q
    gp[j, 1] = -(wx - ax) * k - ey * q
    return best


@njit(cache=True, inline="always")
def window_distance(kind, pts, r, wx, wy, gw, gp):  # pragma: no cover - compiled
    if kind == 0:
        return capsule_distance(pts, r, wx, wy, gw, gp)
    return polygon_distance(pts, wx, wy, gw, gp)


@njit(cache=True, inline="always")
def window_value(d, tau):  # pragma: no cover - compiled
    """Window ``M`` and ``dM/dd`` at signed distance ``d``: unit (``tau == 0``) or
    logistic of width ``tau`` px."""
    if tau <= 0.0:
        return (1.0 if d >= 0.0 else 0.0), 0.0
    x = -d / tau
    if x > 40.0:
        return 0.0, 0.0
    m = 1.0 / (1.0 + np.exp(x))
    return m, m * (1.0 - m) / tau
