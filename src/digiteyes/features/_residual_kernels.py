"""Compiled residual assembly of :func:`~digiteyes.features.feature_residuals` (numba).

:func:`feature_residuals_kernel` does the whole job for one measurement: it picks the
model points of the valid features (axis points of the links, tip centres, the contour
points of each width link, :func:`contour_points_kernel`), computes their world positions
and point Jacobians (:func:`~digiteyes.kinematics.jacobian.jacobian_kernel`), projects
them (:func:`~digiteyes.camera.camera.project_kernel`) and writes the residual rows
(:func:`residual_rows_kernel`) with their labels. A profile of the numpy version showed
about 40 small array operations per call whose overhead (about 120 us) outweighed the
arithmetic (docs/features.md, "Performance").

Row kinds are coded as positions in :data:`RESIDUAL_KINDS`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.camera.camera import project_kernel, project_point
from digiteyes.features.slices import tangent_pair
from digiteyes.kinematics.jacobian import jacobian_kernel

RESIDUAL_KINDS = ("link", "tip", "width")
LINK_ROW, TIP_ROW, WIDTH_ROW = range(len(RESIDUAL_KINDS))  # row kind codes


@njit(cache=True)
def feature_residuals_kernel(shapes, q, jacobian_tables, camera, features, link_table,
                             axis_points, width_weight, max_width_error, jacobian, r, J,
                             points_px, kind, feature, link_index,
                             component):  # pragma: no cover - compiled
    """Residual rows of one measurement at the state of ``shapes`` (1, F, 4, 4) and ``q``
    (1, n_q); returns the number of rows M written to the (M_max, ...) outputs.

    ``jacobian_tables`` is :func:`~digiteyes.kinematics.jacobian.jacobian_tables`;
    ``camera`` is ``(projection_params, view, perspective)``; ``features`` is
    ``(link_ids, link_valid, line, side_lines, slice_normal, middle_px, middle_fraction,
    tip_ids, tip_valid, measured_tip)`` from the measurement, with ``middle_px`` (L, 2) the
    middle slice centres and ``middle_fraction`` where that slice crosses the links;
    ``link_table`` is ``(is_cylinder, rows, lengths, radii)`` per model link. Outputs: ``r``
    (M_max,), ``J`` (M_max, n) (unused without ``jacobian``), ``points_px`` (M_max, 2) and the
    row labels of :class:`~digiteyes.features.residuals.ResidualLayout`. Width rows are
    made only when ``width_weight > 0``.
    """
    params, view, perspective = camera
    (link_ids, link_valid, line, side_lines, slice_normal, middle_px, middle_fraction,
     tip_ids, tip_valid, measured_tip) = features
    is_cylinder, model_rows, lengths, radii = link_table
    links = np.flatnonzero(link_valid)
    tips = np.flatnonzero(tip_valid)
    n_width = 0
    width = np.empty(links.shape[0], dtype=np.int64)
    for i in links:
        both_sides = True
        for side in range(2):
            for c in range(3):
                both_sides &= np.isfinite(side_lines[i, side, c])
        if width_weight > 0.0 and is_cylinder[link_ids[i]] and both_sides:
            width[n_width] = i
            n_width += 1
    width = width[:n_width]

    # Model points: axis points of the links, tip centres, two contour points per width.
    n_link_points = links.shape[0] * axis_points
    n_points = n_link_points + tips.shape[0] + 2 * n_width
    rows = np.empty(n_points, dtype=np.int64)
    p_shape = np.zeros((n_points, 3))
    for k in range(links.shape[0]):
        link = link_ids[links[k]]
        for j in range(axis_points):
            rows[k * axis_points + j] = model_rows[link]
            if axis_points > 1:
                p_shape[k * axis_points + j, 0] = lengths[link] * j / (axis_points - 1)
    for k in range(tips.shape[0]):
        rows[n_link_points + k] = model_rows[tip_ids[tips[k]]]
    width_ids = link_ids[width]
    first_width = n_link_points + tips.shape[0]
    local = np.empty((n_width, 2, 3))
    contour_points_kernel(shapes[0], model_rows[width_ids], middle_fraction * lengths[width_ids],
                          radii[width_ids], view, perspective, params, slice_normal[width],
                          local)
    for k in range(n_width):
        for j in range(2):
            rows[first_width + 2 * k + j] = model_rows[width_ids[k]]
            # element by element: an array assignment would compile numba's
            # shape-mismatch error message (string formatting, 2 s of the first run)
            for c in range(3):
                p_shape[first_width + 2 * k + j, c] = local[k, j, c]

    # World points and their Jacobians, pixels and the projection Jacobians.
    p_world = np.empty((1, n_points, 3))
    J_point = np.zeros((1, n_points, 3, J.shape[1] if jacobian else 0))
    if jacobian:
        jacobian_kernel(shapes, q, rows, p_shape, *jacobian_tables, p_world, J_point)
    else:
        T = shapes[0]
        for p in range(n_points):
            for i in range(3):
                p_world[0, p, i] = (T[rows[p], i, 0] * p_shape[p, 0]
                                    + T[rows[p], i, 1] * p_shape[p, 1]
                                    + T[rows[p], i, 2] * p_shape[p, 2] + T[rows[p], i, 3])
    w = np.empty((n_points, 2))
    dw = np.empty((n_points if jacobian else 0, 2, 3))
    project_kernel(params, p_world[0], w, dw, jacobian)

    keep = np.empty(n_width, dtype=np.bool_)
    m = residual_rows_kernel(w, dw, J_point[0], jacobian, axis_points, n_link_points,
                             line[links], measured_tip[tips], slice_normal[width],
                             side_lines[width], middle_px[width], width_weight,
                             max_width_error, r, J, points_px, keep)
    row = 0
    for k in range(links.shape[0]):
        for j in range(axis_points):
            kind[row], feature[row], component[row] = LINK_ROW, links[k], j
            link_index[row] = link_ids[links[k]]
            row += 1
    for k in range(tips.shape[0]):
        for j in range(2):
            kind[row], feature[row], component[row] = TIP_ROW, tips[k], j
            link_index[row] = tip_ids[tips[k]]
            row += 1
    for k in range(n_width):
        if keep[k]:
            kind[row], feature[row], component[row] = WIDTH_ROW, width[k], 0
            link_index[row] = width_ids[k]
            row += 1
    return m


@njit(cache=True)
def _across(params, cx, cy, cz, ux, uy, uz, wx, wy, wz, r, phi, nx, ny):  # pragma: no cover
    """Image coordinate along ``(nx, ny)`` of the circle point at angle ``phi``."""
    c, s = r * np.cos(phi), r * np.sin(phi)
    u, v, _, _, _ = project_point(params, cx + c * ux + s * wx, cy + c * uy + s * wy,
                                  cz + c * uz + s * wz)
    return nx * u + ny * v


@njit(cache=True)
def contour_points_kernel(shapes, rows, at, radii, view, perspective, params, normal,
                          local):  # pragma: no cover - compiled
    """Extreme points along the image direction ``normal[k]`` of the projected cross-section
    circle ``at[k]`` mm along the axis of ``rows[k]``, into ``local`` (K, 2, 3) in the link's
    shape frame, mm (docs/features.md, "Width residual").

    The search starts at the contour points where viewing rays graze the cylinder
    (:func:`~digiteyes.features.slices.tangent_pair`) and refines their angle on the circle
    by Newton steps on central differences of the image coordinate."""
    tangent = np.empty((2, 3))
    h = 1e-4
    for k in range(rows.shape[0]):
        T = shapes[rows[k]]
        ox, oy, oz = T[0, 3], T[1, 3], T[2, 3]
        ex, ey, ez = T[0, 0], T[1, 0], T[2, 0]
        cx, cy, cz = ox + at[k] * ex, oy + at[k] * ey, oz + at[k] * ez
        tangent_pair(cx, cy, cz, ex, ey, ez, radii[k], view, perspective, np.bool_(False),
                     tangent)
        # circle basis: u towards the first contour point, w = e x u
        ux, uy, uz = tangent[0, 0] - cx, tangent[0, 1] - cy, tangent[0, 2] - cz
        norm = np.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        wx, wy, wz = ey * uz - ez * uy, ez * ux - ex * uz, ex * uy - ey * ux
        dx, dy, dz = tangent[1, 0] - cx, tangent[1, 1] - cy, tangent[1, 2] - cz
        nx, ny = normal[k, 0], normal[k, 1]
        for j in range(2):
            phi = 0.0 if j == 0 else np.arctan2(dx * wx + dy * wy + dz * wz,
                                                dx * ux + dy * uy + dz * uz)
            for _ in range(2):  # close start: two steps (checked in test_residuals.py)
                g0 = _across(params, cx, cy, cz, ux, uy, uz, wx, wy, wz, radii[k], phi, nx, ny)
                gp = _across(params, cx, cy, cz, ux, uy, uz, wx, wy, wz, radii[k], phi + h,
                             nx, ny)
                gm = _across(params, cx, cy, cz, ux, uy, uz, wx, wy, wz, radii[k], phi - h,
                             nx, ny)
                curvature = gp - 2.0 * g0 + gm
                if curvature == 0.0:
                    break
                phi -= 0.5 * h * (gp - gm) / curvature
            c, s = radii[k] * np.cos(phi), radii[k] * np.sin(phi)
            px = cx + c * ux + s * wx - ox
            py = cy + c * uy + s * wy - oy
            pz = cz + c * uz + s * wz - oz
            for i in range(3):
                local[k, j, i] = T[0, i] * px + T[1, i] * py + T[2, i] * pz


@njit(cache=True)
def residual_rows_kernel(w, dw, J_point, jacobian, axis_points, n_link_rows, line, tip,
                         normal, side, middle, width_weight, max_width_error, r, J, points_px,
                         keep):  # pragma: no cover - compiled
    """Residual rows and their Jacobian (docs/features.md Sec. 3) from the projected model
    points; returns the number of rows M written to ``r`` (M,), ``J`` (M, n) and
    ``points_px`` (M, 2).

    The P points are, in order: ``axis_points`` per link line ``line`` (L, 3), one per tip
    ``tip`` (T, 2) and the two contour points of each of the K width links. ``w`` (P, 2)
    are their pixels, ``dw`` (P, 2, 3) the projection Jacobians and ``J_point`` (P, 3, n)
    the point Jacobians (read only if ``jacobian``). Width rows (module docstring of
    ``residuals.py``) use the slice normals ``normal`` (K, 2), side lines ``side``
    (K, 2, 3) and the image points ``middle`` (K, 2) where the measured width is taken;
    ``keep`` (K,) tells which pass the ``max_width_error`` check (only those are written).
    """
    n_cols = J.shape[1]
    n_tips = tip.shape[0]
    first_width = n_link_rows + n_tips
    dwq = np.zeros((2, 2, n_cols))  # d pixel / d state of (up to) two points
    m = 0
    for p in range(first_width):
        if jacobian:
            for i in range(2):
                for c in range(n_cols):
                    dwq[0, i, c] = (dw[p, i, 0] * J_point[p, 0, c] + dw[p, i, 1] * J_point[p, 1, c]
                                    + dw[p, i, 2] * J_point[p, 2, c])
        if p < n_link_rows:
            a, b, rho = line[p // axis_points, 0], line[p // axis_points, 1], line[
                p // axis_points, 2]
            r[m] = a * w[p, 0] + b * w[p, 1] - rho
            for c in range(n_cols if jacobian else 0):
                J[m, c] = a * dwq[0, 0, c] + b * dwq[0, 1, c]
            points_px[m, 0], points_px[m, 1] = w[p, 0], w[p, 1]
            m += 1
            continue
        t = p - n_link_rows
        for i in range(2):
            r[m] = w[p, i] - tip[t, i]
            for c in range(n_cols if jacobian else 0):
                J[m, c] = dwq[0, i, c]
            points_px[m, 0], points_px[m, 1] = w[p, 0], w[p, 1]
            m += 1
    for k in range(keep.shape[0]):
        a, b = first_width + 2 * k, first_width + 2 * k + 1
        nx, ny = normal[k, 0], normal[k, 1]
        across = (w[b, 0] - w[a, 0]) * nx + (w[b, 1] - w[a, 1]) * ny
        sign = -1.0 if across < 0.0 else 1.0
        mx, my = side[k, 0, 0] - side[k, 1, 0], side[k, 0, 1] - side[k, 1, 1]
        measured = mx * middle[k, 0] + my * middle[k, 1] - (side[k, 0, 2] - side[k, 1, 2])
        residual = sign * across - measured
        keep[k] = abs(residual) <= max_width_error * sign * across
        if not keep[k]:
            continue
        r[m] = width_weight * residual
        if jacobian:
            for j in range(2):
                for i in range(2):
                    for c in range(n_cols):
                        q = a + j
                        dwq[j, i, c] = (dw[q, i, 0] * J_point[q, 0, c]
                                        + dw[q, i, 1] * J_point[q, 1, c]
                                        + dw[q, i, 2] * J_point[q, 2, c])
            for c in range(n_cols):
                J[m, c] = width_weight * sign * (nx * (dwq[1, 0, c] - dwq[0, 0, c])
                                                 + ny * (dwq[1, 1, c] - dwq[0, 1, c]))
        points_px[m, 0] = 0.5 * (w[a, 0] + w[b, 0])
        points_px[m, 1] = 0.5 * (w[a, 1] + w[b, 1])
        m += 1
    return m
