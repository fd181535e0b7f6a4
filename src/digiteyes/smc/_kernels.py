"""Compiled inner loop of the edge likelihood (Huang Sec. 5.2): per particle, a pass over
the sample points of every finger patch that keeps the points no other patch or the palm
hides (the occlusion test), then a pass that searches along the normal at each of them
(two loops: the occlusion test's unpredictable branches stay out of the search loop)."""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.camera.camera import project_point


@njit(cache=True, inline="always")
def _inside_triangle(px, py, ax, ay, bx, by, cx, cy):  # pragma: no cover - compiled
    """Barycentric weights of (px, py) in triangle abc (any with a negative: outside)."""
    det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    if det == 0.0:
        return -1.0, -1.0, -1.0
    wa = ((by - cy) * (px - cx) + (cx - bx) * (py - cy)) / det
    wb = ((cy - ay) * (px - cx) + (ax - cx) * (py - cy)) / det
    return wa, wb, 1.0 - wa - wb


@njit(cache=True, inline="always")
def _palm_depth(px, py, pu, pv, pz):  # pragma: no cover - compiled
    """Depth (mm) of the palm quad at pixel (px, py), ``inf`` outside it (affine in each
    of the two triangles 0-1-2 and 0-2-3)."""
    for tri in range(2):
        b, c = (1, 2) if tri == 0 else (2, 3)
        wa, wb, wc = _inside_triangle(px, py, pu[0], pv[0], pu[b], pv[b], pu[c], pv[c])
        if wa >= 0.0 and wb >= 0.0 and wc >= 0.0:
            return wa * pz[0] + wb * pz[b] + wc * pz[c]
    return np.inf


@njit(cache=True, fastmath=True)
def edge_likelihood_kernel(shapes, link_rows, lengths, radii, ts, skip, palm_row, palm_outline,
                           params, edges, half_window, sigma, inv_c, margin, score, distance,
                           use_lookup, skip_far, log_l, stats,
                           link_l):  # pragma: no cover - compiled
    """Huang Sec. 5.2 for N particles.

    ``shapes`` (N, S, 4, 4) ``T_world_shape`` of every shape row (forward kinematics),
    ``link_rows`` (L,) the rows of the finger patches, whose axes run along their shape
    frame's x from the origin for ``lengths`` (L,) mm, ``radii`` (L,) patch half-widths
    (mm), ``ts`` (K,) positions along each axis, ``skip`` (L, L) pairs never tested for
    occlusion (a link and its neighbours in the chain), ``palm_row`` the palm's shape row
    and ``palm_outline`` (4, 3) its outline in that frame (mm), ``params`` the camera
    (:attr:`Camera.projection_params`), ``edges`` (H, W) uint8 edge map. With
    ``use_lookup``, each visible point reads its factor from ``score`` (H, W) and the
    nearest-edge distance from ``distance`` (H, W) (:func:`edge_lookup`) instead of
    searching along the normal; a search whose pixels all lie inside the image reads
    ``edges`` without per-pixel bounds checks. With ``skip_far`` (and not
    ``use_lookup``), a point whose pixel lies farther than ``half_window + 1.5`` px from
    every edge (``distance``) skips the search: every pixel the search reads lies within
    ``half_window + sqrt(2)`` of it, so the search would find nothing (the same result,
    sooner). Writes ``log_l`` (N,) and ``stats`` (N, 3): visible points, points with an
    edge, sum of squared offset of the nearest edge (px^2); and, when ``link_l`` has N
    rows (else it has none), adds each patch's share of ``log_l`` to ``link_l`` (N, L).
    """
    n_particles, n_links = shapes.shape[0], link_rows.shape[0]
    n_t = ts.shape[0]
    per_link = link_l.shape[0] == n_particles
    height, width = edges.shape
    fx = params[12]
    scale = 1.0 if params[22] != 2.0 else 1.0 / params[23]
    au = np.empty(n_links)
    av = np.empty(n_links)
    az = np.empty(n_links)
    bu = np.empty(n_links)
    bv = np.empty(n_links)
    bz = np.empty(n_links)
    lo_u = np.empty(n_links)
    hi_u = np.empty(n_links)
    lo_v = np.empty(n_links)
    hi_v = np.empty(n_links)
    near_z = np.empty(n_links)
    vis_u = np.empty(n_links * n_t * 2)  # the visible lateral points and their normals
    vis_v = np.empty(n_links * n_t * 2)
    vis_nx = np.empty(n_links * n_t * 2)
    vis_ny = np.empty(n_links * n_t * 2)
    vis_link = np.empty(n_links * n_t * 2, dtype=np.int64)
    cands = np.empty((n_links, n_links), dtype=np.int64)
    n_cands = np.empty(n_links, dtype=np.int64)
    pu = np.empty(4)
    pv = np.empty(4)
    pz = np.empty(4)
    far = half_window + 1.5
    gauss = np.exp(-np.arange(half_window + 1) ** 2 / (2.0 * sigma * sigma))
    for n in range(n_particles):
        for li in range(n_links):
            T = shapes[n, link_rows[li]]
            sx, sy, sz = T[0, 3], T[1, 3], T[2, 3]
            u, v, _x, _y, z = project_point(params, sx, sy, sz)
            au[li], av[li], az[li] = u, v, z
            length = lengths[li]
            u, v, _x, _y, z = project_point(params, sx + T[0, 0] * length,
                                          sy + T[1, 0] * length, sz + T[2, 0] * length)
            bu[li], bv[li], bz[li] = u, v, z
        P = shapes[n, palm_row]
        for c in range(4):
            ox, oy, oz = palm_outline[c, 0], palm_outline[c, 1], palm_outline[c, 2]
            u, v, _x, _y, z = project_point(
                params, P[0, 0] * ox + P[0, 1] * oy + P[0, 2] * oz + P[0, 3],
                P[1, 0] * ox + P[1, 1] * oy + P[1, 2] * oz + P[1, 3],
                P[2, 0] * ox + P[2, 1] * oy + P[2, 2] * oz + P[2, 3])
            pu[c], pv[c], pz[c] = u, v, z
        pzmin = min(min(pz[0], pz[1]), min(pz[2], pz[3]))
        for li in range(n_links):  # image boxes of the patches, for a quick occlusion reject
            zmin = min(az[li], bz[li])
            reach = radii[li] * fx * (scale if params[22] != 0.0 else 1.0 / max(zmin, 1e-6))
            lo_u[li] = min(au[li], bu[li]) - reach
            hi_u[li] = max(au[li], bu[li]) + reach
            lo_v[li] = min(av[li], bv[li]) - reach
            hi_v[li] = max(av[li], bv[li]) + reach
            near_z[li] = zmin
        for li in range(n_links):  # the patches that may hide a point of patch li
            far_z = max(az[li], bz[li])
            count = 0
            for m in range(n_links):
                if not skip[li, m] and lo_u[m] <= hi_u[li] and lo_u[li] <= hi_u[m] and \
                        lo_v[m] <= hi_v[li] and lo_v[li] <= hi_v[m] and \
                        near_z[m] < far_z - margin:
                    cands[li, count] = m
                    count += 1
            n_cands[li] = count
        total = 0.0
        n_vis_i = 0
        n_hit = 0.0
        sq = 0.0
        for li in range(n_links):
            dx, dy = bu[li] - au[li], bv[li] - av[li]
            length = np.sqrt(dx * dx + dy * dy)
            if length < 1e-6:
                continue
            nx, ny = -dy / length, dx / length
            for k in range(n_t):
                t = ts[k]
                cu, cv, cz = au[li] + t * dx, av[li] + t * dy, az[li] + t * (bz[li] - az[li])
                if cz <= 0.0:
                    continue
                r_px = radii[li] * fx * (scale if params[22] != 0.0 else 1.0 / cz)
                for side in range(2):
                    sgn = 1.0 if side == 0 else -1.0
                    px, py = cu + sgn * r_px * nx, cv + sgn * r_px * ny
                    if not (0.0 <= px <= width - 1 and 0.0 <= py <= height - 1):
                        continue
                    hidden = pzmin < cz - margin and _palm_depth(px, py, pu, pv, pz) < cz - margin
                    j = 0
                    while not hidden and j < n_cands[li]:
                        m = cands[li, j]
                        if lo_u[m] <= px <= hi_u[m] and lo_v[m] <= py <= hi_v[m] and \
                                near_z[m] < cz - margin:
                            ex, ey = bu[m] - au[m], bv[m] - av[m]
                            ee = ex * ex + ey * ey
                            tau = 0.0
                            if ee > 0.0:
                                tau = min(1.0, max(0.0, ((px - au[m]) * ex + (py - av[m]) * ey)
                                                   / ee))
                            qx, qy = au[m] + tau * ex - px, av[m] + tau * ey - py
                            mz = az[m] + tau * (bz[m] - az[m])
                            if mz > 0.0 and mz < cz - margin:
                                rm = radii[m] * fx * (scale if params[22] != 0.0 else 1.0 / mz)
                                if qx * qx + qy * qy < rm * rm:
                                    hidden = True
                        j += 1
                    if hidden:
                        continue
                    vis_u[n_vis_i] = px
                    vis_v[n_vis_i] = py
                    vis_nx[n_vis_i] = nx
                    vis_ny[n_vis_i] = ny
                    vis_link[n_vis_i] = li
                    n_vis_i += 1
        n_vis = float(n_vis_i)
        for i in range(n_vis_i):
            px, py, nx, ny = vis_u[i], vis_v[i], vis_nx[i], vis_ny[i]
            if use_lookup:
                ix = int(px + 0.5)
                iy = int(py + 0.5)
                d = distance[iy, ix]
                if d <= half_window:
                    n_hit += 1.0
                    sq += d * d
                total += score[iy, ix]
                if per_link:
                    link_l[n, vis_link[i]] += score[iy, ix]
                continue
            if skip_far and distance[int(py + 0.5), int(px + 0.5)] > far:
                continue
            acc = 0.0
            best = 1e30
            reach_x, reach_y = half_window * abs(nx), half_window * abs(ny)
            if px - reach_x >= 0.0 and px + reach_x + 0.5 < width and \
                    py - reach_y >= 0.0 and py + reach_y + 0.5 < height:
                for o in range(-half_window, half_window + 1):  # all inside
                    hit = edges[np.uint64(py + o * ny + 0.5),
                                np.uint64(px + o * nx + 0.5)] != 0
                    acc += gauss[abs(o)] * hit  # branch-free: edges are rare
                    best = min(best, o * o if hit else 1e30)
            else:
                for o in range(-half_window, half_window + 1):
                    ix = int(px + o * nx + 0.5)
                    iy = int(py + o * ny + 0.5)
                    if ix < 0 or iy < 0 or ix >= width or iy >= height:
                        continue
                    hit = edges[iy, ix] != 0
                    acc += gauss[abs(o)] * hit
                    best = min(best, o * o if hit else 1e30)
            if best < 1e30:  # an edge in the window (acc > 0; log(1 + 0) = 0 else)
                n_hit += 1.0
                sq += best
                term = np.log(1.0 + acc * inv_c)
                total += term
                if per_link:
                    link_l[n, vis_link[i]] += term
        log_l[n] = total
        stats[n, 0] = n_vis
        stats[n, 1] = n_hit
        stats[n, 2] = sq


@njit(cache=True, fastmath=True)
def nearest_segment_kernel(X, bi, d, pair, t_out, dist_out):  # pragma: no cover - compiled
    """For each row of ``X`` (N, D): the nearest segment ``bi + t d`` (P segments), its
    index into ``pair``, ``t`` in [0, 1] into ``t_out`` and the distance into ``dist_out``."""
    n_points, n_dims = X.shape
    n_segments = bi.shape[0]
    lengths_sq = np.zeros(n_segments)
    for p in range(n_segments):
        for k in range(n_dims):
            lengths_sq[p] += d[p, k] * d[p, k]
    for n in range(n_points):
        best, best_p, best_t = np.inf, 0, 0.0
        for p in range(n_segments):
            num = 0.0
            for k in range(n_dims):
                num += (X[n, k] - bi[p, k]) * d[p, k]
            dd = lengths_sq[p]
            t = min(1.0, max(0.0, num / dd)) if dd > 0.0 else 0.0
            sq = 0.0
            for k in range(n_dims):
                r = X[n, k] - bi[p, k] - t * d[p, k]
                sq += r * r
            if sq < best:
                best, best_p, best_t = sq, p, t
        pair[n] = best_p
        t_out[n] = best_t
        dist_out[n] = np.sqrt(best)
