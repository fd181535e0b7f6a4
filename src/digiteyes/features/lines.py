"""Robust line fits to edge points, for many point sets at once.

Lines are ``a x + b y = rho`` with ``a^2 + b^2 = 1`` (report Sec. 3.2, thesis Sec. 2.5.1),
stored as (..., 3) arrays ``(a, b, rho)``; ``a x + b y - rho`` is the signed distance in
pixels.

Each fit is total least squares (the line minimising the sum of squared perpendicular
distances: through the weighted centroid, along the major axis of the weighted 2x2
scatter matrix, in closed form) inside iteratively reweighted least squares (IRLS):

1. fit with equal weights; unless every point lies within ``4.685 min_scale`` of that
   line (no outliers), restart from the least-median-of-squares line: of the lines
   through every pair of points, the one with the smallest median distance to all points
   (exhaustive, so deterministic: 45 pairs for 10 points);
2. residuals ``r``, robust scale ``sigma = max(1.4826 median|r|, min_scale)``;
3. weights from Tukey's biweight (``(1 - (r / 4.685 sigma)^2)^2``, zero beyond) or
   Huber's (``min(1, 1.345 sigma / |r|)``); weighted refit; repeat a fixed number of
   times.

Inliers are the points closer than Tukey's rejection distance ``4.685 sigma`` to the
final line.

Why this and not RANSAC: a link gives only 8-12 edge points per side, so trying every
pair is cheaper than drawing random samples and needs no random numbers; the median
criterion needs no inlier threshold; and the IRLS refinement uses all inliers with smooth
weights, so the line moves smoothly with the data. An equal-weight start is not enough:
outliers that cluster at one end of a link (a neighbouring finger's edge along part of
it) tilt the first fit into a local minimum that reweighting cannot leave; the median
start tolerates up to half the points being outliers. Tukey's weights redescend to zero,
so the refinement ignores those outliers; Huber's do not, and a few high-leverage
outliers pull a Huber fit back towards least squares (use it for mild, central outliers).

The fits run in one compiled loop over all point sets (numba): with ~10 points per set
the numpy version's cost was almost all call overhead of ~100 small array operations.
With ``robust="none"`` the result is the plain total-least-squares line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

TUKEY_C = 4.685
HUBER_K = 1.345
MAD_TO_SIGMA = 1.4826
ROBUST_LOSSES = ("none", "tukey", "huber")


@dataclass(frozen=True)
class LineFit:
    """Result of :func:`fit_lines` for point sets (..., P, 2).

    Attributes
    ----------
    line : (..., 3) ``(a, b, rho)``; NaN where fewer than two points were usable.
    inlier : (..., P) bool, points within ``4.685 sigma`` of the line.
    count : (...,) number of inliers.
    rms : (...,) root mean square distance of the inliers from the line, px.
    """

    line: np.ndarray
    inlier: np.ndarray
    count: np.ndarray
    rms: np.ndarray


@njit(cache=True)
def _tls(points, weights, line):  # pragma: no cover - compiled
    """Weighted total-least-squares line of one point set into ``line``; False if
    degenerate."""
    total = 0.0
    mx = 0.0
    my = 0.0
    for i in range(points.shape[0]):
        w = weights[i]
        if w > 0.0:
            total += w
            mx += w * points[i, 0]
            my += w * points[i, 1]
    if total <= 0.0:
        return False
    mx /= total
    my /= total
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(points.shape[0]):
        w = weights[i]
        if w > 0.0:
            dx = points[i, 0] - mx
            dy = points[i, 1] - my
            sxx += w * dx * dx
            syy += w * dy * dy
            sxy += w * dx * dy
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    line[0] = -np.sin(angle)
    line[1] = np.cos(angle)
    line[2] = line[0] * mx + line[1] * my
    return True


@njit(cache=True)
def _median(values, n):  # pragma: no cover - compiled
    """Median of ``values[:n]`` (sorted in place by insertion: n is about 10)."""
    for i in range(1, n):
        v = values[i]
        j = i - 1
        while j >= 0 and values[j] > v:
            values[j + 1] = values[j]
            j -= 1
        values[j + 1] = v
    return 0.5 * (values[(n - 1) // 2] + values[n // 2])


@njit(cache=True)
def _robust_scale(residual, mask, min_scale, values):  # pragma: no cover - compiled
    n = np.int64(0)  # typed, not a literal 0: _median is compiled once
    for i in range(residual.shape[0]):
        if mask[i]:
            values[n] = abs(residual[i])
            n += 1
    if n == 0:
        return min_scale
    return max(MAD_TO_SIGMA * _median(values, n), min_scale)


@njit(cache=True)
def _lmeds(points, mask, line, values):  # pragma: no cover - compiled
    """Least-median-of-squares line over all pairs of masked points, into ``line``.

    A pair can only improve on the best median so far if more than half of the distances
    are below it, so the median is computed (by sorting) only for such pairs.
    """
    n_points = points.shape[0]
    best = np.inf
    for i in range(n_points):
        if not mask[i]:
            continue
        for j in range(i + 1, n_points):
            if not mask[j]:
                continue
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            length = np.sqrt(dx * dx + dy * dy)
            if length == 0.0:
                continue
            a = -dy / length
            b = dx / length
            rho = a * points[i, 0] + b * points[i, 1]
            n = np.int64(0)
            below = 0
            for k in range(n_points):
                if mask[k]:
                    values[n] = abs(a * points[k, 0] + b * points[k, 1] - rho)
                    below += values[n] < best
                    n += 1
            if 2 * below <= n:
                continue
            median = _median(values, n)
            if median < best:
                best = median
                line[0] = a
                line[1] = b
                line[2] = rho
    return np.isfinite(best)


@njit(cache=True)
def fit_one(pts, mask, normal, loss, iterations, min_scale, line, inlier, weights, residual,
            scratch):  # pragma: no cover - compiled
    """Robust line (module docstring) through the masked points (P, 2) of one set into
    ``line`` (3,) and ``inlier`` (P,); ``loss`` 0 none, 1 Tukey, 2 Huber. ``weights``,
    ``residual`` and ``scratch`` are (P,) work arrays. Returns the inlier count and RMS."""
    n_points = mask.shape[0]
    n_used = 0
    for i in range(n_points):
        weights[i] = 1.0 if mask[i] else 0.0
        n_used += mask[i]
    ok = n_used >= 2 and _tls(pts, weights, line)
    if ok and loss != 0 and n_used >= 3:
        worst = 0.0
        for i in range(n_points):
            if mask[i]:
                worst = max(worst, abs(line[0] * pts[i, 0] + line[1] * pts[i, 1] - line[2]))
        if worst > TUKEY_C * min_scale:  # outliers may have tilted the fit
            ok = _lmeds(pts, mask, line, scratch)
    for _ in range(iterations if ok and loss != 0 else 0):
        for i in range(n_points):
            residual[i] = line[0] * pts[i, 0] + line[1] * pts[i, 1] - line[2]
        scale = _robust_scale(residual, mask, min_scale, scratch)
        for i in range(n_points):
            if not mask[i]:
                weights[i] = 0.0
                continue
            u = abs(residual[i]) / scale
            if loss == 1:
                weights[i] = (1.0 - (u / TUKEY_C) ** 2) ** 2 if u < TUKEY_C else 0.0
            else:
                weights[i] = min(1.0, HUBER_K / u) if u > 0.0 else 1.0
        ok = _tls(pts, weights, line)
    if not ok:
        line[:] = np.nan
        inlier[:] = False
        return 0, np.nan
    if line[0] * normal[0] + line[1] * normal[1] < 0.0:
        # element by element: an array assignment would compile numba's shape-mismatch
        # error message (string formatting, 2 s of the first run)
        for c in range(3):
            line[c] = -line[c]
    for i in range(n_points):
        residual[i] = line[0] * pts[i, 0] + line[1] * pts[i, 1] - line[2]
    cut = np.inf
    if loss != 0:
        cut = TUKEY_C * _robust_scale(residual, mask, min_scale, scratch)
    count = 0
    total = 0.0
    for i in range(n_points):
        inlier[i] = mask[i] and abs(residual[i]) < cut
        if inlier[i]:
            count += 1
            total += residual[i] ** 2
    return count, np.sqrt(total / count) if count > 0 else np.nan


@njit(cache=True)
def _fit_kernel(points, mask, normal, loss, iterations, min_scale, line, inlier, count,
                rms):  # pragma: no cover - compiled
    n_points = mask.shape[1]
    weights = np.empty(n_points)
    residual = np.empty(n_points)
    scratch = np.empty(n_points)
    for b in range(mask.shape[0]):
        count[b], rms[b] = fit_one(points[b], mask[b], normal[b], loss, iterations, min_scale,
                                   line[b], inlier[b], weights, residual, scratch)


def fit_lines(
    points: np.ndarray,
    mask: np.ndarray,
    *,
    robust: str = "tukey",
    iterations: int = 4,
    min_scale: float = 0.3,
    normal: np.ndarray | None = None,
) -> LineFit:
    """Robust lines through many point sets at once.

    Parameters
    ----------
    points : (..., P, 2) points in px; entries outside ``mask`` may be NaN.
    mask : (..., P) bool, points to use.
    robust : ``"tukey"`` (default), ``"huber"`` or ``"none"`` (plain total least squares,
        every masked point an inlier).
    iterations : reweighting passes after the first fit.
    min_scale : floor of the robust scale ``sigma``, px; keeps the weights finite on
        noise-free data (the rejection distance is at least ``4.685 min_scale``).
    normal : (..., 2) optional reference directions; the returned normals point the same
        way (non-negative dot product). Default: arbitrary sign.

    Returns
    -------
    LineFit
    """
    if robust not in ROBUST_LOSSES:
        raise ValueError(f"robust must be one of {', '.join(ROBUST_LOSSES)}, got {robust!r}")
    points = np.asarray(points, dtype=np.float64)
    mask = np.asarray(mask, dtype=np.bool_)
    lead, n_points = mask.shape[:-1], mask.shape[-1]
    flat_points = np.ascontiguousarray(points.reshape(-1, n_points, 2))
    flat_mask = np.ascontiguousarray(mask.reshape(-1, n_points))
    n_sets = flat_mask.shape[0]
    if normal is None:
        flat_normal = np.zeros((n_sets, 2))
    else:
        flat_normal = np.ascontiguousarray(
            np.broadcast_to(normal, (*lead, 2)).reshape(-1, 2), dtype=np.float64)
    line = np.empty((n_sets, 3))
    inlier = np.empty((n_sets, n_points), dtype=np.bool_)
    count = np.empty(n_sets, dtype=np.int64)
    rms = np.empty(n_sets)
    _fit_kernel(flat_points, flat_mask, flat_normal, ROBUST_LOSSES.index(robust),
                int(iterations), float(min_scale), line, inlier, count, rms)
    return LineFit(line.reshape(*lead, 3), inlier.reshape(*lead, n_points),
                   count.reshape(lead), rms.reshape(lead))


def bisector(line_a: np.ndarray, line_b: np.ndarray) -> np.ndarray:
    """Bisector (..., 3) of two lines whose normals point the same way.

    The points between the lines at equal distance from both satisfy
    ``(m_a + m_b) . x = rho_a + rho_b``; normalising ``m_a + m_b`` gives the line.
    """
    m = line_a[..., :2] + line_b[..., :2]
    norm = np.linalg.norm(m, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.concatenate([m, line_a[..., 2:] + line_b[..., 2:]], axis=-1) / norm
