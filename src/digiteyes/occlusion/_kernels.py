"""Compiled pair tests of the occlusion relations (numba): where two windows come
closest, for all candidate pairs at once."""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.occlusion.window_functions import polygon_distance, window_distance


@njit(cache=True)
def segment_closest(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):  # pragma: no cover
    """Closest points of two 2D segments: (distance, s on p, t on q), s, t in [0, 1]."""
    d1x, d1y, d2x, d2y = p1x - p0x, p1y - p0y, q1x - q0x, q1y - q0y
    l1, l2 = max(d1x * d1x + d1y * d1y, 1e-12), max(d2x * d2x + d2y * d2y, 1e-12)
    best, bs, bt = 1e300, 0.0, 0.0
    for case in range(5):
        if case < 2:
            t = float(case)
            s = min(1.0, max(0.0, ((q0x + t * d2x - p0x) * d1x + (q0y + t * d2y - p0y) * d1y)
                             / l1))
        elif case < 4:
            s = float(case - 2)
            t = min(1.0, max(0.0, ((p0x + s * d1x - q0x) * d2x + (p0y + s * d1y - q0y) * d2y)
                             / l2))
        else:
            denom = d1x * d2y - d1y * d2x
            if abs(denom) < 1e-12:
                continue
            ex, ey = q0x - p0x, q0y - p0y
            s = (ex * d2y - ey * d2x) / denom
            t = (ex * d1y - ey * d1x) / denom
            if not (0.0 <= s <= 1.0 and 0.0 <= t <= 1.0):
                continue
        dx = p0x + s * d1x - q0x - t * d2x
        dy = p0y + s * d1y - q0y - t * d2y
        dist = np.sqrt(dx * dx + dy * dy)
        if dist < best:
            best, bs, bt = dist, s, t
    return best, bs, bt


@njit(cache=True)
def pair_overlap_kernel(kind, points, radius, margin, pairs, overlap, s_out,
                        t_out):  # pragma: no cover - compiled
    """For each candidate pair ``(j, k)``: whether the windows overlap (outlines within
    ``margin`` px) and where: capsule-capsule, the parameters ``s``, ``t`` of the closest
    axis points; capsule-polygon, the parameter ``s`` of the capsule axis point deepest
    inside the polygon (9 samples; ``t`` unused)."""
    gw = np.empty(2)
    gp = np.empty((4, 2))
    for n in range(pairs.shape[0]):
        j, k = pairs[n, 0], pairs[n, 1]
        overlap[n] = False
        if kind[j] == 0 and kind[k] == 0:
            dist, s, t = segment_closest(points[j, 0, 0], points[j, 0, 1], points[j, 1, 0],
                                         points[j, 1, 1], points[k, 0, 0], points[k, 0, 1],
                                         points[k, 1, 0], points[k, 1, 1])
            overlap[n] = dist < radius[j] + radius[k] + margin
            s_out[n], t_out[n] = s, t
        elif kind[j] != kind[k]:
            cap, poly = (j, k) if kind[j] == 0 else (k, j)
            best = -1e300
            for i in range(9):
                s = i / 8.0
                wx = (1 - s) * points[cap, 0, 0] + s * points[cap, 1, 0]
                wy = (1 - s) * points[cap, 0, 1] + s * points[cap, 1, 1]
                inside = polygon_distance(points[poly], wx, wy, gw, gp) + radius[cap] + margin
                if inside > 0 and inside > best:
                    best = inside
                    s_out[n] = s
                    overlap[n] = True


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
