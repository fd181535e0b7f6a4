"""Compiled loops of the layered template error (numba): window functions, the per-pixel
residual with its region and boundary derivatives, and list-priority segmentation.

See :mod:`digiteyes.templates.layered` for the maths; the window geometry follows
:mod:`digiteyes.occlusion.windows` (capsule 0, polygon 1).
"""

from __future__ import annotations

import numpy as np
from numba import njit

BOUNDARY_REACH = 8.0
"""Beyond this many window widths from a boundary the smooth window's gradient is taken
as zero (it is below 1.4e-3 of its peak there)."""


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


@njit(cache=True, inline="always")
def bilinear_gradient(image, x, y):  # pragma: no cover - compiled
    """Bilinear value and its exact derivatives at ``(x, y)`` (inside the image)."""
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    i00, i01 = float(image[y0, x0]), float(image[y0, x0 + 1])
    i10, i11 = float(image[y0 + 1, x0]), float(image[y0 + 1, x0 + 1])
    top = i00 + fx * (i01 - i00)
    bottom = i10 + fx * (i11 - i10)
    value = top + fy * (bottom - top)
    gx = (1.0 - fy) * (i01 - i00) + fy * (i11 - i10)
    return value, gx, bottom - top


@njit(cache=True)
def layered_kernel(image, pix_part, p_world, w, Jp, values, weights, twists, occ_start,
                   occ_index, win_kind, win_pts, win_r, win_dpts, win_dr, tau, margin, H6,
                   g6, b6, b_pts, b_r, r_out, v_out, rows_region, rows_dv,
                   form_rows):  # pragma: no cover - compiled
    """One pass over the template pixels of one camera; returns the layered error
    ``E = sum_i weight_i V_i r_i^2 / 2``.

    Per pixel i of part k at image point ``w_i``: ``r_i = I(w_i) - T_i`` (eq. 2.11),
    ``V_i = prod_j (1 - M_j(w_i))`` over the parts j that occlude k (window tree,
    eq. 3.7, 3.9), the occluders' outlines grown by ``margin`` px. Adds ``V m m^T`` to
    ``H6[k]`` and ``V r m`` to ``g6[k]`` (region terms, eq. 3.10, in twist coordinates).
    The boundary terms ``r^2 / 2 dV`` (eq. 3.12) are split by what moves: the pixel
    (part k's twist coordinates, ``b6[k]``), the occluder's outline points
    (``b_pts[j]``, px) and its radius (``b_r[j]``); the caller chains them with the
    twists and window Jacobians. With ``form_rows`` the per-pixel rows ``dr/dv`` and
    ``dV/dv`` are written out too (for tests and the generic solvers).
    """
    height, width = image.shape
    n_v = twists.shape[2]
    gw = np.empty(2)
    gp = np.empty((4, 2))
    n_occ_max = 1
    for k in range(len(occ_start) - 1):
        n_occ_max = max(n_occ_max, occ_start[k + 1] - occ_start[k])
    Ms = np.empty(n_occ_max)
    ds = np.empty(n_occ_max)
    reach = BOUNDARY_REACH * tau
    energy = 0.0
    for i in range(pix_part.shape[0]):
        k = pix_part[i]
        wx, wy = w[i, 0], w[i, 1]
        r_out[i] = 0.0
        v_out[i] = 0.0
        if weights[i] <= 0.0 or not (0.0 <= wx < width - 1 and 0.0 <= wy < height - 1):
            continue
        # visibility through the occluders' windows
        V = 1.0
        boundary = False
        n_occ = occ_start[k + 1] - occ_start[k]
        for o in range(n_occ):
            j = occ_index[occ_start[k] + o]
            d = window_distance(win_kind[j], win_pts[j], win_r[j], wx, wy, gw, gp) + margin
            M, _ = window_value(d, tau)
            Ms[o] = M
            ds[o] = d
            V *= 1.0 - M
            if tau > 0.0 and abs(d) < reach:
                boundary = True
        value, ix, iy = bilinear_gradient(image, wx, wy)
        r = value - values[i]
        r_out[i] = r
        v_out[i] = V
        wt = weights[i]
        energy += 0.5 * wt * V * r * r
        px, py, pz = p_world[i, 0], p_world[i, 1], p_world[i, 2]
        ax = Jp[i, 0, 0] * ix + Jp[i, 1, 0] * iy
        ay = Jp[i, 0, 1] * ix + Jp[i, 1, 1] * iy
        az = Jp[i, 0, 2] * ix + Jp[i, 1, 2] * iy
        m0, m1, m2 = py * az - pz * ay, pz * ax - px * az, px * ay - py * ax
        s = wt * V
        if s > 0.0:
            m = (m0, m1, m2, ax, ay, az)
            for a in range(6):
                g6[k, a] += s * r * m[a]
                for b in range(a, 6):
                    H6[k, a, b] += s * m[a] * m[b]
        if form_rows:
            for c in range(n_v):
                rows_region[i, c] = (m0 * twists[k, 0, c] + m1 * twists[k, 1, c]
                                     + m2 * twists[k, 2, c] + ax * twists[k, 3, c]
                                     + ay * twists[k, 4, c] + az * twists[k, 5, c])
                rows_dv[i, c] = 0.0
        if not boundary:
            continue
        half = 0.5 * wt * r * r
        for o in range(n_occ):
            if abs(ds[o]) >= reach:
                continue
            j = occ_index[occ_start[k] + o]
            d = window_distance(win_kind[j], win_pts[j], win_r[j], wx, wy, gw, gp) + margin
            M, dM = window_value(d, tau)
            others = 1.0
            for o2 in range(n_occ):
                if o2 != o:
                    others *= 1.0 - Ms[o2]
            f = -dM * others  # dV / dd_j
            bx = gw[0] * Jp[i, 0, 0] + gw[1] * Jp[i, 1, 0]
            by = gw[0] * Jp[i, 0, 1] + gw[1] * Jp[i, 1, 1]
            bz = gw[0] * Jp[i, 0, 2] + gw[1] * Jp[i, 1, 2]
            n = (py * bz - pz * by, pz * bx - px * bz, px * by - py * bx, bx, by, bz)
            for a in range(6):
                b6[k, a] += half * f * n[a]
            for q in range(4):
                b_pts[j, q, 0] += half * f * gp[q, 0]
                b_pts[j, q, 1] += half * f * gp[q, 1]
            if win_kind[j] == 0:
                b_r[j] += half * f
            if form_rows:
                for c in range(n_v):
                    acc = 0.0
                    for a in range(6):
                        acc += n[a] * twists[k, a, c]
                    if win_kind[j] == 0:
                        acc += win_dr[j, c]
                    for q in range(4):
                        acc += gp[q, 0] * win_dpts[j, q, 0, c] + gp[q, 1] * win_dpts[j, q, 1, c]
                    rows_dv[i, c] += f * acc
    return energy


@njit(cache=True)
def segment_kernel(order, win_kind, win_pts, win_r, bounds, labels):  # pragma: no cover
    """List-priority segmentation (thesis Sec. 3.3.4): paint the unit windows from the
    back of the visibility ``order`` to its front into ``labels`` (H, W), int16, -1 where
    no window covers a pixel."""
    height, width = labels.shape
    gw = np.empty(2)
    gp = np.empty((4, 2))
    for n in range(len(order) - 1, -1, -1):
        k = order[n]
        u0 = max(0, int(np.floor(bounds[k, 0])))
        v0 = max(0, int(np.floor(bounds[k, 1])))
        u1 = min(width - 1, int(np.ceil(bounds[k, 2])))
        v1 = min(height - 1, int(np.ceil(bounds[k, 3])))
        for v in range(v0, v1 + 1):
            for u in range(u0, u1 + 1):
                if window_distance(win_kind[k], win_pts[k], win_r[k], float(u), float(v),
                                   gw, gp) >= 0.0:
                    labels[v, u] = k


@njit(cache=True)
def transform_kernel(frames, part_of, p_shape, out):  # pragma: no cover - compiled
    """World points ``out`` (P, 3) of shape-frame points ``p_shape`` (P, 3) on the parts
    posed by ``frames`` (K, 4, 4)."""
    for i in range(p_shape.shape[0]):
        T = frames[part_of[i]]
        x, y, z = p_shape[i, 0], p_shape[i, 1], p_shape[i, 2]
        for a in range(3):
            out[i, a] = T[a, 0] * x + T[a, 1] * y + T[a, 2] * z + T[a, 3]
