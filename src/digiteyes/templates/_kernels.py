"""Compiled loops of the layered template error (numba): the per-pixel residual with its
region and boundary derivatives, and the placing of template pixels.

See :mod:`digiteyes.templates.layered` for the maths; the window functions are
:mod:`digiteyes.occlusion.window_functions` (capsule 0, polygon 1).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.occlusion.window_functions import window_distance, window_value

BOUNDARY_REACH = 8.0
"""Beyond this many window widths from a boundary the smooth window's gradient is taken
as zero (it is below 1.4e-3 of its peak there)."""


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


@njit(cache=True, inline="always")
def _nearer_along_ray(e0, e1, e2, p0, p1, p2, axes, j, radius_front,
                      radius_back):  # pragma: no cover - compiled
    """How much nearer the eye ``(e0, e1, e2)`` (mm) the capsule of axis ``axes[j, 0]``-
    ``axes[j, 1]`` (world, mm) lies than the point ``(p0, p1, p2)`` along the ray from the
    eye through the point: the point's distance less ``radius_back`` minus that of the
    axis point closest to the ray less ``radius_front`` (both surfaces' fronts; the point
    lies on its part's axis plane). Scalars in, so that the per-pixel loop passes no
    arrays for the pixel (each array passed costs reference counting)."""
    ux, uy, uz = p0 - e0, p1 - e1, p2 - e2
    t_p = np.sqrt(ux * ux + uy * uy + uz * uz)
    if t_p <= 0.0:
        return 0.0
    ux, uy, uz = ux / t_p, uy / t_p, uz / t_p
    a0, a1, a2 = axes[j, 0, 0], axes[j, 0, 1], axes[j, 0, 2]
    ex, ey, ez = axes[j, 1, 0] - a0, axes[j, 1, 1] - a1, axes[j, 1, 2] - a2
    wx, wy, wz = e0 - a0, e1 - a1, e2 - a2
    ue = ux * ex + uy * ey + uz * ez
    ee = ex * ex + ey * ey + ez * ez
    uw = ux * wx + uy * wy + uz * wz
    ew = ex * wx + ey * wy + ez * wz
    den = ee - ue * ue
    v = 0.0 if den <= 1e-12 * max(ee, 1e-12) else (ew - ue * uw) / den
    v = min(max(v, 0.0), 1.0)
    # the ray parameter of the axis point at v
    t_axis = ux * (a0 + v * ex - e0) + uy * (a1 + v * ey - e1) + uz * (a2 + v * ez - e2)
    return (t_p - radius_back) - (t_axis - radius_front)


@njit(cache=True, inline="always")
def _window_at(kind, pts, r, wx, wy, margin, tau, gw, gp):  # pragma: no cover - compiled
    """Signed distance ``d`` (px) of pixel ``(wx, wy)`` to a window's outline grown by
    ``margin`` and the window's value ``M`` there (:mod:`~digiteyes.occlusion.
    window_functions`; ``gw``/``gp`` receive the distance's derivatives)."""
    d = window_distance(kind, pts, r, wx, wy, gw, gp) + margin
    M, _ = window_value(d, tau)
    return d, M


@njit(cache=True, inline="always")
def _through_others(Ms, count, o):  # pragma: no cover - compiled
    """``prod (1 - M)`` over the first ``count`` windows but window ``o``."""
    others = 1.0
    for o2 in range(count):
        if o2 != o:
            others *= 1.0 - Ms[o2]
    return others


@njit(cache=True, inline="always")
def _add_outline_terms(j, kind, c, gp, b_pts, b_r):  # pragma: no cover - compiled
    """Add ``c`` times window ``j``'s distance gradient ``gp`` (by its outline points) to
    ``b_pts[j]``, and ``c`` to ``b_r[j]`` for a capsule (the radius)."""
    for q in range(4):
        b_pts[j, q, 0] += c * gp[q, 0]
        b_pts[j, q, 1] += c * gp[q, 1]
    if kind == 0:
        b_r[j] += c


@njit(cache=True)
def layered_kernel(image, pix_part, p_world, w, Jp, values, weights, twists, occ_start,
                   occ_index, occ_tested, win_kind, win_pts, win_r, win_dpts, win_dr,
                   win_world, part_r, eye, tie_mm, tau, margin, hidden_cost, H6, g6, b6, b_pts,
                   b_r, r_out, v_out, rows_region, rows_dv, form_rows,
                   derivatives):  # pragma: no cover - compiled
    """One pass over the template pixels of one camera; returns the layered error
    ``E = sum_i weight_i [V_i r_i^2 + (1 - V_i) c] / 2``, ``c = hidden_cost`` (grey
    levels squared: what a hidden template pixel costs; 0 is the thesis's error).

    Per pixel i of part k at image point ``w_i``: ``r_i = I(w_i) - T_i`` (eq. 2.11),
    ``V_i = prod_j (1 - M_j(w_i))`` over the parts j that occlude k (window tree,
    eq. 3.7, 3.9), the occluders' outlines grown by ``margin`` px; an occluder flagged
    in ``occ_tested`` (1 or 2, :attr:`~digiteyes.occlusion.visibility.VisibilityOrder.
    pixel_depth`) counts only at the pixels where it lies nearer the ray's start ``eye[i]``
    (world, mm) by more than ``tie_mm``, or within ``tie_mm`` when flagged 1
    (``win_world`` its window's world points, ``part_r`` the parts' radii, mm). Adds
    ``V m m^T`` to ``H6[k]`` and ``V r m`` to ``g6[k]`` (region terms, eq. 3.10, in twist
    coordinates). The boundary terms ``(r^2 - c) / 2 dV`` (eq. 3.12 and the hidden
    cost's) are split by what moves: the pixel (part k's twist coordinates, ``b6[k]``),
    the occluder's outline points (``b_pts[j]``, px) and its radius (``b_r[j]``); the
    caller chains them with the twists and window Jacobians. With ``form_rows`` the
    per-pixel rows ``dr/dv`` and ``dV/dv`` are written out too (for tests and the generic
    solvers). Without ``derivatives`` only ``E``, ``r`` and ``V`` are computed (``Jp`` and
    ``twists`` are not read; the accumulators stay as given).
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
        # visibility through the occluders' windows, V = prod (1 - M_j); a tested
        # occluder counts only where it lies nearer along the pixel's ray (M = 0 and no
        # boundary elsewhere). Written out here: a call that takes the arrays costs more
        # than the work (reference counting per array and pixel)
        n_occ = occ_start[k + 1] - occ_start[k]
        V = 1.0
        boundary = False
        for o in range(n_occ):
            j = occ_index[occ_start[k] + o]
            flag = occ_tested[occ_start[k] + o]
            if flag > 0:
                nearer = _nearer_along_ray(eye[i, 0], eye[i, 1], eye[i, 2], p_world[i, 0],
                                           p_world[i, 1], p_world[i, 2], win_world, j,
                                           part_r[j], part_r[k])
                if nearer < (-tie_mm if flag == 1 else tie_mm):
                    Ms[o] = 0.0
                    ds[o] = -np.inf
                    continue
            d, M = _window_at(win_kind[j], win_pts[j], win_r[j], wx, wy, margin, tau, gw, gp)
            Ms[o] = M
            ds[o] = d
            V *= 1.0 - M
            boundary = boundary or (tau > 0.0 and abs(d) < reach)
        value, ix, iy = bilinear_gradient(image, wx, wy)
        r = value - values[i]
        r_out[i] = r
        v_out[i] = V
        wt = weights[i]
        energy += 0.5 * wt * (V * r * r + (1.0 - V) * hidden_cost)
        if not derivatives:
            continue
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
        half = 0.5 * wt * (r * r - hidden_cost)
        for o in range(n_occ):
            if abs(ds[o]) >= reach:
                continue
            j = occ_index[occ_start[k] + o]
            d = window_distance(win_kind[j], win_pts[j], win_r[j], wx, wy, gw, gp) + margin
            _, dM = window_value(d, tau)
            f = -dM * _through_others(Ms, n_occ, o)  # dV / dd_j
            e = half * f  # dE / dd_j
            bx = gw[0] * Jp[i, 0, 0] + gw[1] * Jp[i, 1, 0]
            by = gw[0] * Jp[i, 0, 1] + gw[1] * Jp[i, 1, 1]
            bz = gw[0] * Jp[i, 0, 2] + gw[1] * Jp[i, 1, 2]
            n = (py * bz - pz * by, pz * bx - px * bz, px * by - py * bx, bx, by, bz)
            for a in range(6):
                b6[k, a] += e * n[a]
            _add_outline_terms(j, win_kind[j], e, gp, b_pts, b_r)
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
def transform_kernel(frames, part_of, p_shape, out):  # pragma: no cover - compiled
    """World points ``out`` (P, 3) of shape-frame points ``p_shape`` (P, 3) on the parts
    posed by ``frames`` (K, 4, 4)."""
    for i in range(p_shape.shape[0]):
        T = frames[part_of[i]]
        x, y, z = p_shape[i, 0], p_shape[i, 1], p_shape[i, 2]
        for a in range(3):
            out[i, a] = T[a, 0] * x + T[a, 1] * y + T[a, 2] * z + T[a, 3]


@njit(cache=True)
def background_kernel(image, pixels, values, weights, win_kind, win_pts, win_r, tau, margin,
                      b_pts, b_r, r_out, v_out):  # pragma: no cover - compiled
    """One pass over fixed image pixels ``pixels`` (B, 2) int (column, row) for the
    background template (thesis Sec. 4.4.2): returns ``E = sum_u weight_u V_u r_u^2 / 2``
    with ``r_u = I(u) - B(u)`` and ``V_u = prod_j (1 - M_j(u))`` over every part's window
    (the background lies behind all of them; outlines grown by ``margin`` px). ``r`` does
    not depend on the state; ``V`` does, through the windows: the boundary terms
    ``r^2 / 2 dV`` go to ``b_pts[j]`` and ``b_r[j]`` as in :func:`layered_kernel`.
    """
    n_win = win_kind.shape[0]
    gw = np.empty(2)
    gp = np.empty((4, 2))
    Ms = np.empty(n_win)
    ds = np.empty(n_win)
    reach = BOUNDARY_REACH * tau
    energy = 0.0
    for i in range(pixels.shape[0]):
        x, y = pixels[i, 0], pixels[i, 1]
        r_out[i] = 0.0
        v_out[i] = 0.0
        wt = weights[i]
        if wt <= 0.0:
            continue
        V = 1.0
        boundary = False
        for j in range(n_win):  # the background lies behind every part
            d, M = _window_at(win_kind[j], win_pts[j], win_r[j], float(x), float(y), margin,
                              tau, gw, gp)
            Ms[j] = M
            ds[j] = d
            V *= 1.0 - M
            boundary = boundary or (tau > 0.0 and abs(d) < reach)
        r = float(image[y, x]) - values[i]
        r_out[i] = r
        v_out[i] = V
        energy += 0.5 * wt * V * r * r
        if not boundary:
            continue
        half = 0.5 * wt * r * r
        for j in range(n_win):
            if abs(ds[j]) >= reach:
                continue
            d = window_distance(win_kind[j], win_pts[j], win_r[j], float(x), float(y),
                                gw, gp) + margin
            _, dM = window_value(d, tau)
            _add_outline_terms(j, win_kind[j], -half * dM * _through_others(Ms, n_win, j), gp,
                               b_pts, b_r)
    return energy
