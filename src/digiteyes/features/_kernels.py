"""Compiled inner loops of :func:`~digiteyes.features.measure_features` (numba).

One loop measures every link tracker of a camera and one every tip tracker, following
docs/features.md Sec. 1-2 step by step: projected axis and slice centres, exact contour
offsets from the cylinder tangent points (:func:`~digiteyes.features.slices.tangent_pair`),
bilinear profiles (:func:`~digiteyes.features.slices.bilinear`), signed edge peaks
(:func:`~digiteyes.features.edges.peak_in_range`), robust side lines
(:func:`~digiteyes.features.lines.fit_one`), the bisector or one-edge fallback and the
validity checks. Profiling the vectorised numpy version showed ~150 small array operations
per image, whose call overhead (about 1.5 ms) dwarfed the arithmetic (docs/features.md,
"Performance").

Link reason codes index ``LINK_REASONS`` and tip codes ``TIP_REASONS`` (measure.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.camera.camera import project_point
from digiteyes.features.edges import peak_in_range, smoothed_derivative
from digiteyes.features.lines import fit_one
from digiteyes.features.slices import bilinear, tangent_pair

TIP_LATERAL = (-0.5, 0.0, 0.5)  # tip slice offsets, fractions of the tip radius
MIN_TIP_SIN = 0.2


@njit(cache=True, inline="always")
def _in_image(gray, u, v):  # pragma: no cover - compiled
    return (-0.5 <= u <= gray.shape[1] - 0.5) and (-0.5 <= v <= gray.shape[0] - 0.5)


@njit(cache=True, inline="always")
def _profile(gray, ox, oy, dx, dy, j_first, step, prof, inside, response):  # pragma: no cover
    """Samples ``j_first + j`` (at ``(j_first + j) step`` px along ``d`` from ``o``)."""
    for j in range(prof.shape[0]):
        t = (j_first + j) * step
        prof[j] = bilinear(gray, ox + t * dx, oy + t * dy)
        inside[j] = not np.isnan(prof[j])
    smoothed_derivative(prof, response)


@njit(cache=True)
def links_kernel(gray, params, view, perspective, shapes, rows, lengths, radii, fractions,
                 min_axis_px, min_edge_points, half, step, min_contrast, side_sign, loss,
                 max_fit_rms, cos_max_angle, max_width_error, side_samples,
                 w_ends, w_slices, normal, contour, line, code, n_edges, side_lines,
                 edge_points, edge_inlier, slice_ends):  # pragma: no cover - compiled
    """Measure every link (docs/features.md Sec. 1); fills the (L, ...) output arrays.
    ``side_sign`` (L, 2): the sign of the edge response each link side looks for (+1 a
    rise along the slice, -1 a fall; a hand brighter than its backdrop is +1, -1).

    One thread, links one after the other with shared scratch arrays: a link is a few
    microseconds of work, too little for numba's ``parallel=True`` to pay for its thread
    start-up, its barrier per call (costly when the cores are shared) and its compile time
    (about 30 s of a first run; docs/architecture.md, "The first run")."""
    n_slices = w_slices.shape[1]
    margin = max(side_samples, 3) + 1
    tangent = np.empty((2, 3))
    w_tan = np.empty((n_slices, 2, 2))
    position = np.empty((2, n_slices))
    before = np.empty((2, n_slices))
    after = np.empty((2, n_slices))
    window = np.empty((2, n_slices))
    moved = np.empty((n_slices, 2))
    fit_line = np.empty((2, 3))
    shifted = np.empty(3)
    work = np.empty((3, n_slices))
    unused = np.empty(n_slices, dtype=np.bool_)
    count = np.empty(2, dtype=np.int64)
    rms = np.empty(2)
    prof_buf, inside_buf, response_buf = (np.empty(128), np.empty(128, np.bool_),
                                          np.empty(128))
    for i in range(rows.shape[0]):
        T = shapes[rows[i]]
        behind = False
        # Axis ends, slice centres and contour tangent points, projected.
        for k in range(2 + n_slices):
            t = fractions[k] * lengths[i]
            px, py, pz = T[0, 3] + t * T[0, 0], T[1, 3] + t * T[1, 0], T[2, 3] + t * T[2, 0]
            u, v, _, _, z = project_point(params, px, py, pz)
            if k < 2:
                w_ends[i, k, 0], w_ends[i, k, 1] = u, v
                behind |= perspective and z <= radii[i]
                continue
            w_slices[i, k - 2, 0], w_slices[i, k - 2, 1] = u, v
            tangent_pair(px, py, pz, T[0, 0], T[1, 0], T[2, 0], radii[i], view, perspective,
                         np.bool_(False), tangent)
            for side in range(2):
                w_tan[k - 2, side, 0], w_tan[k - 2, side, 1], _, _, _ = project_point(
                    params, tangent[side, 0], tangent[side, 1], tangent[side, 2])
        ax, ay = w_ends[i, 1, 0] - w_ends[i, 0, 0], w_ends[i, 1, 1] - w_ends[i, 0, 1]
        length_px = np.sqrt(ax * ax + ay * ay)
        if length_px > 0.0:
            ax, ay = ax / length_px, ay / length_px
        else:
            ax, ay = 1.0, 0.0
        nx, ny = -ay, ax
        normal[i, 0], normal[i, 1] = nx, ny
        n_in = 0
        for s in range(n_slices):
            cx, cy = w_slices[i, s, 0], w_slices[i, s, 1]
            a = (w_tan[s, 0, 0] - cx) * nx + (w_tan[s, 0, 1] - cy) * ny
            b = (w_tan[s, 1, 0] - cx) * nx + (w_tan[s, 1, 1] - cy) * ny
            contour[i, s, 0], contour[i, s, 1] = min(a, b), max(a, b)
            behind |= not (np.isfinite(a) and np.isfinite(b))
            n_in += _in_image(gray, w_slices[i, s, 0], w_slices[i, s, 1])
        short = length_px < min_axis_px
        off_image = n_in < min_edge_points
        usable = not (behind or short or off_image)

        # Edges on every slice: side 0 rises (for a bright finger), side 1 falls.
        for s in range(n_slices):
            if not usable:
                contour[i, s, 0] = contour[i, s, 1] = np.nan
                for side in range(2):
                    position[side, s] = before[side, s] = after[side, s] = np.nan
                    window[side, s] = np.nan
                continue
            j_first = int(np.ceil((contour[i, s, 0] - half) / step)) - margin
            n = int(np.floor((contour[i, s, 1] + half) / step)) + margin - j_first + 1
            if n > prof_buf.shape[0]:
                prof_buf, inside_buf, response_buf = (np.empty(n), np.empty(n, np.bool_),
                                                      np.empty(n))
            prof, inside, response = prof_buf[:n], inside_buf[:n], response_buf[:n]
            _profile(gray, w_slices[i, s, 0], w_slices[i, s, 1], nx, ny, j_first, step, prof,
                     inside, response)
            for side in range(2):
                sign = side_sign[i, side]
                (position[side, s], _, before[side, s], after[side, s],
                 window[side, s]) = peak_in_range(prof, inside, response, contour[i, s, side],
                                                  sign, half, j_first * step, step,
                                                  min_contrast, side_samples)

        # A robust line per side (docs/features.md Sec. 1, "Line fits").
        side_ok = np.zeros(2, dtype=np.bool_)
        for side in range(2):
            pts = edge_points[i, side]
            for s in range(n_slices):
                pts[s, 0] = w_slices[i, s, 0] + position[side, s] * nx
                pts[s, 1] = w_slices[i, s, 1] + position[side, s] * ny
                unused[s] = np.isfinite(position[side, s])
            count[side], rms[side] = fit_one(pts, unused, normal[i], loss, np.int64(4), 0.3,
                                             fit_line[side], edge_inlier[i, side], work[0],
                                             work[1], work[2])
            n_edges[i, side] = count[side]
            side_ok[side] = count[side] >= min_edge_points and rms[side] <= max_fit_rms
            for c in range(3):
                side_lines[i, side, c] = fit_line[side, c] if side_ok[side] else np.nan
        both = side_ok[0] and side_ok[1]
        one = side_ok[0] != side_ok[1]
        enough = count[0] >= min_edge_points or count[1] >= min_edge_points

        # Both sides: their bisector, if they agree in angle and width.
        mid = n_slices // 2
        mx, my = w_slices[i, mid, 0], w_slices[i, mid, 1]
        width = (fit_line[0, 0] * mx + fit_line[0, 1] * my - fit_line[0, 2]) - (
            fit_line[1, 0] * mx + fit_line[1, 1] * my - fit_line[1, 2])
        predicted_width = contour[i, mid, 1] - contour[i, mid, 0]
        cos_sides = abs(fit_line[0, 0] * fit_line[1, 0] + fit_line[0, 1] * fit_line[1, 1])
        agree = (cos_sides >= cos_max_angle
                 and abs(width - predicted_width) <= max_width_error * predicted_width)
        bx, by = fit_line[0, 0] + fit_line[1, 0], fit_line[0, 1] + fit_line[1, 1]
        norm = np.sqrt(bx * bx + by * by)
        la, lb, lr = bx / norm, by / norm, (fit_line[0, 2] + fit_line[1, 2]) / norm
        merged = False
        if one:
            # One-edge fallback: inliers moved onto the axis by their contour offsets.
            side = 0 if side_ok[0] else 1
            for s in range(n_slices):
                shift = position[side, s] - contour[i, s, side]
                moved[s, 0] = w_slices[i, s, 0] + shift * nx
                moved[s, 1] = w_slices[i, s, 1] + shift * ny
            fit_one(moved, edge_inlier[i, side], normal[i], np.int64(0), np.int64(0), 0.3,
                    shifted, unused, work[0], work[1], work[2])
            la, lb, lr = shifted[0], shifted[1], shifted[2]
            # ... accepted if the missing side's ranges show the finger, not background.
            finger = background = seen = 0.0
            n_found = n_seen = 0
            for s in range(n_slices):
                if edge_inlier[i, side, s]:
                    n_found += 1
                    finger += after[0, s] if side == 0 else before[1, s]
                    background += before[0, s] if side == 0 else after[1, s]
                if np.isfinite(window[1 - side, s]):
                    n_seen += 1
                    seen += window[1 - side, s]
            finger /= max(n_found, 1)
            background /= max(n_found, 1)
            seen /= max(n_seen, 1)
            brighter = side_sign[i, 0] if side == 0 else -side_sign[i, 1]  # hand > backdrop
            merged = brighter * (seen - 0.5 * (finger + background)) > 0.0

        # The measured axis must stay within the window at the first and last slices.
        outside = False
        for s in (0, n_slices - 1):
            distance = abs(la * w_slices[i, s, 0] + lb * w_slices[i, s, 1] - lr)
            outside |= not distance <= half

        reasons = (behind, short, off_image, not enough, not (both or one), both and not agree,
                   one and not merged, outside)
        code[i] = 0
        for k in range(len(reasons)):
            if reasons[k]:
                code[i] = k + 1
                break
        valid = code[i] == 0
        line[i, 0] = la if valid else np.nan
        line[i, 1] = lb if valid else np.nan
        line[i, 2] = lr if valid else np.nan
        for s in range(n_slices):
            for side in range(2):
                offset = contour[i, s, side] + (half if side else -half)
                slice_ends[i, s, side, 0] = w_slices[i, s, 0] + offset * nx
                slice_ends[i, s, side, 1] = w_slices[i, s, 1] + offset * ny


@njit(cache=True)
def tips_kernel(gray, params, view, perspective, shapes, rows, axis_rows, radii, parent,
                link_line, link_code, half, step, min_contrast, polarity, min_tip_edges,
                max_spread, side_samples, predicted, measured, code, direction, slice_ends,
                edge_points):  # pragma: no cover - compiled
    """Measure every tip (docs/features.md Sec. 2); fills the (T, ...) output arrays."""
    n_half = int(np.ceil(half / step)) + 3
    n = 2 * n_half + 1
    prof, inside, response = np.empty(n), np.empty(n, np.bool_), np.empty(n)
    tangent = np.empty((2, 3))
    shift = np.empty(3)
    for i in range(rows.shape[0]):
        T, A = shapes[rows[i]], shapes[axis_rows[i]]
        cx, cy, cz = T[0, 3], T[1, 3], T[2, 3]
        sin_view = tangent_pair(cx, cy, cz, A[0, 0], A[1, 0], A[2, 0], radii[i], view,
                                perspective, np.bool_(True), tangent)
        wx, wy, _, _, z = project_point(params, cx, cy, cz)
        predicted[i, 0], predicted[i, 1] = wx, wy
        u1, v1, _, _, _ = project_point(params, tangent[0, 0], tangent[0, 1], tangent[0, 2])
        u2, v2, _, _, _ = project_point(params, tangent[1, 0], tangent[1, 1], tangent[1, 2])
        ux, uy = u1 - wx, v1 - wy
        along = np.sqrt(ux * ux + uy * uy)
        if along > 0.0:
            ux, uy = ux / along, uy / along
        else:
            ux, uy = 1.0, 0.0
        across = np.sqrt((u2 - wx) ** 2 + (v2 - wy) ** 2)
        behind = ((perspective and z <= radii[i])
                  or not (np.isfinite(along) and np.isfinite(across)))
        short = not behind and not sin_view >= MIN_TIP_SIN
        usable = not (behind or short)

        # Lateral position and direction from the measured axis of the parent link.
        k = parent[i]
        bx, by, dx, dy = wx, wy, ux, uy
        if usable and k >= 0 and link_code[k] == 0:
            ma, mb, rho = link_line[k, 0], link_line[k, 1], link_line[k, 2]
            off = ma * wx + mb * wy - rho
            bx, by = wx - off * ma, wy - off * mb
            dx, dy = (mb, -ma) if mb * ux - ma * uy >= 0.0 else (-mb, ma)
        direction[i, 0], direction[i, 1] = dx, dy

        found = 0
        total = 0.0
        low, high = np.inf, -np.inf
        for j in range(3):
            f = TIP_LATERAL[j]
            expected_end = along * np.sqrt(1.0 - f * f)
            ox = bx + f * across * -dy + expected_end * dx
            oy = by + f * across * dx + expected_end * dy
            if not usable:
                ox = oy = -1e4
            shift[j] = np.nan
            if usable:
                _profile(gray, ox, oy, dx, dy, -n_half, step, prof, inside, response)
                shift[j] = peak_in_range(prof, inside, response, 0.0, -polarity, half,
                                         -n_half * step, step, min_contrast, side_samples)[0]
            if np.isfinite(shift[j]):
                found += 1
                total += shift[j]
                low, high = min(low, shift[j]), max(high, shift[j])
            edge_points[i, j, 0], edge_points[i, j, 1] = ox + shift[j] * dx, oy + shift[j] * dy
            slice_ends[i, j, 0, 0], slice_ends[i, j, 0, 1] = ox - half * dx, oy - half * dy
            slice_ends[i, j, 1, 0], slice_ends[i, j, 1, 1] = ox + half * dx, oy + half * dy
        reasons = (behind, short, found < min_tip_edges, high - low > max_spread)
        code[i] = 0
        for r in range(len(reasons)):
            if reasons[r]:
                code[i] = r + 1
                break
        mean_shift = total / found if found > 0 else np.nan
        measured[i, 0] = bx + mean_shift * dx if code[i] == 0 else np.nan
        measured[i, 1] = by + mean_shift * dy if code[i] == 0 else np.nan
