"""Compiled ray casting of primitives into a z-buffer (numba).

Why compiled: the first, numpy version cast each primitive's pixel block with array
operations. For the hand (25 primitives: 15 capsules, 5 balls, the palm slab as a box and
four capsules) at 640x480 it reached about 15 frames/s, and the profile showed the time
spread over some hundred small array operations per primitive (bounds, rays, quadratic
roots, normals, masked writes), each paying numpy's call overhead on a few thousand
pixels. One compiled loop over primitives and their pixel blocks does the same
arithmetic with no temporaries (docs/rendering.md gives the figures).

Conventions: everything is in the camera frame (OpenCV: x right, y down, z forward, mm).
A pixel's ray has direction (x, y, 1) from the origin (perspective) or direction (0, 0, 1)
from (x / scale, y / scale, 0) (orthographic, scaled orthographic), where
``y = (v - cy) / fy`` and ``x = (u - cx - s y) / fx``; so the ray parameter of a hit is
its camera depth z. Primitive parameters, one row of 15 numbers each:

* ball (kind 0): centre (3), radius;
* capsule (kind 1): start (3), end (3), radius;
* box (kind 2): centre (3), the three unit axes (3 x 3, axis after axis), half extents (3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

BALL, CAPSULE, BOX = 0, 1, 2
N_PARAMS = 15
_NEAR = 1e-6
_TIE = 1.0 - 1e-6  # a later primitive must be nearer by this factor to win a pixel


@njit(cache=True, error_model="numpy", inline="always")
def _hit_ball(ox, oy, oz, dx, dy, dz, cx, cy, cz, r):  # pragma: no cover - compiled
    """Smallest root t > near of |o + t d - c| = r, or inf."""
    px, py, pz = ox - cx, oy - cy, oz - cz
    dd = dx * dx + dy * dy + dz * dz
    b = dx * px + dy * py + dz * pz
    h = b * b - dd * (px * px + py * py + pz * pz - r * r)
    if h < 0.0:
        return np.inf
    t = (-b - math.sqrt(h)) / dd
    return t if t > _NEAR else np.inf


@njit(cache=True, error_model="numpy", inline="always")
def _hit_capsule(ox, oy, oz, dx, dy, dz, P):  # pragma: no cover - compiled
    """Nearest hit with a capsule: the lateral cylinder surface between the end planes,
    or the end ball on the side where the ray meets the infinite cylinder. Both balls lie
    inside that cylinder, so a ray that misses it misses the capsule, and a ray that
    enters it between the end planes hits nothing nearer."""
    ax, ay, az, bx, by, bz, r = P[0], P[1], P[2], P[3], P[4], P[5], P[6]
    ex, ey, ez = bx - ax, by - ay, bz - az
    px, py, pz = ox - ax, oy - ay, oz - az
    ee = ex * ex + ey * ey + ez * ez
    ed = ex * dx + ey * dy + ez * dz
    ep = ex * px + ey * py + ez * pz
    qa = ee * (dx * dx + dy * dy + dz * dz) - ed * ed
    qb = ee * (dx * px + dy * py + dz * pz) - ep * ed
    qc = ee * (px * px + py * py + pz * pz) - ep * ep - r * r * ee
    h = qb * qb - qa * qc
    if qa > 1e-12 * ee:
        if h < 0.0:
            return np.inf
        tb = (-qb - math.sqrt(h)) / qa
        y = ep + tb * ed
        if 0.0 < y < ee and tb > _NEAR:
            return tb
        if y <= 0.0:
            return _hit_ball(ox, oy, oz, dx, dy, dz, ax, ay, az, r)
        if y >= ee:
            return _hit_ball(ox, oy, oz, dx, dy, dz, bx, by, bz, r)
    t = _hit_ball(ox, oy, oz, dx, dy, dz, ax, ay, az, r)
    return min(t, _hit_ball(ox, oy, oz, dx, dy, dz, bx, by, bz, r))


@njit(cache=True, error_model="numpy", inline="always")
def _hit_box(ox, oy, oz, dx, dy, dz, P):  # pragma: no cover - compiled
    """Nearest hit with an oriented box (slab method), or inf."""
    t_near = -np.inf
    t_far = np.inf
    for i in range(3):
        wx, wy, wz = P[3 + 3 * i], P[4 + 3 * i], P[5 + 3 * i]
        o = wx * (ox - P[0]) + wy * (oy - P[1]) + wz * (oz - P[2])
        d = wx * dx + wy * dy + wz * dz
        if abs(d) < 1e-12:
            if abs(o) > P[12 + i]:
                return np.inf
            continue
        t1 = (-P[12 + i] - o) / d
        t2 = (P[12 + i] - o) / d
        t_near = max(t_near, min(t1, t2))
        t_far = min(t_far, max(t1, t2))
    if t_near <= t_far and t_near > _NEAR:
        return t_near
    return np.inf


@njit(cache=True, error_model="numpy", inline="always")
def _shade(kind, P, x, y, z, light):  # pragma: no cover - compiled
    """Cosine between the outward unit normal at surface point (x, y, z) and ``light``."""
    if kind == BALL:
        return ((x - P[0]) * light[0] + (y - P[1]) * light[1] + (z - P[2]) * light[2]) / P[3]
    if kind == CAPSULE:
        ex, ey, ez = P[3] - P[0], P[4] - P[1], P[5] - P[2]
        s = ((x - P[0]) * ex + (y - P[1]) * ey + (z - P[2]) * ez) / (ex * ex + ey * ey + ez * ez)
        s = min(max(s, 0.0), 1.0)
        return ((x - P[0] - s * ex) * light[0] + (y - P[1] - s * ey) * light[1]
                + (z - P[2] - s * ez) * light[2]) / P[6]
    best = -1.0
    cosine = 0.0
    for i in range(3):
        wx, wy, wz = P[3 + 3 * i], P[4 + 3 * i], P[5 + 3 * i]
        local = wx * (x - P[0]) + wy * (y - P[1]) + wz * (z - P[2])
        rel = abs(local) / P[12 + i]
        if rel > best:
            best = rel
            cosine = wx * light[0] + wy * light[1] + wz * light[2]
            if local < 0.0:
                cosine = -cosine
    return cosine


@njit(cache=True, error_model="numpy", inline="always")
def _beyond_end(P, x, y, z):  # pragma: no cover - compiled
    """Whether surface point (x, y, z) of a capsule lies beyond its end plane (far cap)."""
    ex, ey, ez = P[3] - P[0], P[4] - P[1], P[5] - P[2]
    return (x - P[3]) * ex + (y - P[4]) * ey + (z - P[5]) * ez > 0.0


@njit(cache=True, error_model="numpy")
def _extend(bounds, x, y, z, perspective, scale):  # pragma: no cover - compiled
    """Grow normalised-coordinate bounds by point (x, y, z); False if behind the camera."""
    if perspective:
        if z <= _NEAR:
            return False
        x, y = x / z, y / z
    else:
        x, y = x * scale, y * scale
    bounds[0] = min(bounds[0], x)
    bounds[1] = max(bounds[1], x)
    bounds[2] = min(bounds[2], y)
    bounds[3] = max(bounds[3], y)
    return True


@njit(cache=True, error_model="numpy")
def _extend_ball(bounds, cx, cy, cz, r, perspective, scale):  # pragma: no cover - compiled
    """Grow bounds by a ball's projection; perspective uses the tangent slopes
    (c_x c_z +- r sqrt(c_x^2 + c_z^2 - r^2)) / (c_z^2 - r^2) (likewise for y)."""
    if not perspective:
        bounds[0] = min(bounds[0], (cx - r) * scale)
        bounds[1] = max(bounds[1], (cx + r) * scale)
        bounds[2] = min(bounds[2], (cy - r) * scale)
        bounds[3] = max(bounds[3], (cy + r) * scale)
        return True
    if cz - r <= _NEAR:
        return False
    denom = cz * cz - r * r
    sx = r * math.sqrt(cx * cx + denom)
    sy = r * math.sqrt(cy * cy + denom)
    bounds[0] = min(bounds[0], (cx * cz - sx) / denom)
    bounds[1] = max(bounds[1], (cx * cz + sx) / denom)
    bounds[2] = min(bounds[2], (cy * cz - sy) / denom)
    bounds[3] = max(bounds[3], (cy * cz + sy) / denom)
    return True


@njit(cache=True, error_model="numpy")
def _block(kind, P, intrinsics, perspective, scale, width, height, block):  # pragma: no cover
    """Inclusive pixel block (u0, u1, v0, v1) into ``block`` that holds the primitive's
    projection, clipped to the image; False if empty. The whole image if the primitive
    reaches behind a perspective camera."""
    fx, s, cx, fy, cy = intrinsics
    bounds = np.array([np.inf, -np.inf, np.inf, -np.inf])
    ok = True
    if kind == BALL:
        ok = _extend_ball(bounds, P[0], P[1], P[2], P[3], perspective, scale)
    elif kind == CAPSULE:
        ok = _extend_ball(bounds, P[0], P[1], P[2], P[6], perspective, scale) and \
            _extend_ball(bounds, P[3], P[4], P[5], P[6], perspective, scale)
    else:
        for corner in range(8):
            x, y, z = P[0], P[1], P[2]
            for i in range(3):
                sign = 1.0 if (corner >> i) & 1 else -1.0
                x += sign * P[12 + i] * P[3 + 3 * i]
                y += sign * P[12 + i] * P[4 + 3 * i]
                z += sign * P[12 + i] * P[5 + 3 * i]
            ok = ok and _extend(bounds, x, y, z, perspective, scale)
    if not ok:
        block[0], block[1], block[2], block[3] = 0, width - 1, 0, height - 1
        return True
    skew_lo = min(s * bounds[2], s * bounds[3])
    skew_hi = max(s * bounds[2], s * bounds[3])
    block[0] = max(0, math.ceil(fx * bounds[0] + skew_lo + cx - 1e-9))
    block[1] = min(width - 1, math.floor(fx * bounds[1] + skew_hi + cx + 1e-9))
    block[2] = max(0, math.ceil(fy * bounds[2] + cy - 1e-9))
    block[3] = min(height - 1, math.floor(fy * bounds[3] + cy + 1e-9))
    return block[0] <= block[1] and block[2] <= block[3]


@njit(cache=True, error_model="numpy", inline="always")
def _ray(u, yn, intrinsics, perspective, scale):  # pragma: no cover - compiled
    """Origin (x, y; z = 0) and direction of the ray through column ``u`` of the row whose
    normalised coordinate is ``yn`` (module docstring)."""
    fx, s, cx = intrinsics[0], intrinsics[1], intrinsics[2]
    xn = (u - cx - s * yn) / fx
    if perspective:
        return 0.0, 0.0, xn, yn, 1.0
    return xn / scale, yn / scale, 0.0, 0.0, 1.0


@njit(cache=True, error_model="numpy", inline="always")
def _reach(kind, P, u, yn, intrinsics, perspective, scale):  # pragma: no cover - compiled
    """Discriminant of the ray through (u, yn) with a ball, or with the infinite cylinder
    around a capsule's axis: >= 0 exactly when the ray's line meets it."""
    ox, oy, dx, dy, dz = _ray(u, yn, intrinsics, perspective, scale)
    if kind == BALL:
        px, py, pz = ox - P[0], oy - P[1], -P[2]
        b = dx * px + dy * py + dz * pz
        return b * b - (dx * dx + dy * dy + dz * dz) * (px * px + py * py + pz * pz - P[3] * P[3])
    ex, ey, ez = P[3] - P[0], P[4] - P[1], P[5] - P[2]
    px, py, pz = ox - P[0], oy - P[1], -P[2]
    ee = ex * ex + ey * ey + ez * ez
    ed = ex * dx + ey * dy + ez * dz
    ep = ex * px + ey * py + ez * pz
    qa = ee * (dx * dx + dy * dy + dz * dz) - ed * ed
    qb = ee * (dx * px + dy * py + dz * pz) - ep * ed
    qc = ee * (px * px + py * py + pz * pz) - ep * ep - P[6] * P[6] * ee
    return qb * qb - qa * qc


@njit(cache=True, error_model="numpy")
def _row_span(kind, P, yn, u_first, u_last, intrinsics, perspective, scale):  # pragma: no cover
    """The columns of ``u_first..u_last`` in one row whose rays can meet a ball or
    capsule, as an inclusive range (empty when first > last).

    Along a row the ray is affine in u (its direction for perspective, its origin for
    orthographic projections), so the discriminant of :func:`_reach` is a quadratic in u,
    fixed by three samples. A capsule's end balls lie inside its infinite cylinder, so
    every ray that hits the capsule has a non-negative cylinder discriminant. Where the
    quadratic opens downwards its non-negative part is the interval between its roots
    (widened by a pixel against rounding); otherwise the whole range is kept."""
    if u_last <= u_first:
        return u_first, u_last
    x0, x2 = float(u_first), float(u_last)
    mid, half = 0.5 * (x0 + x2), 0.5 * (x2 - x0)
    h0 = _reach(kind, P, x0, yn, intrinsics, perspective, scale)
    h1 = _reach(kind, P, mid, yn, intrinsics, perspective, scale)
    h2 = _reach(kind, P, x2, yn, intrinsics, perspective, scale)
    a = 0.5 * (h0 + h2) - h1  # h(mid + half t) = a t^2 + b t + h1
    b = 0.5 * (h2 - h0)
    if not a < -1e-12 * (abs(h0) + abs(h1) + abs(h2)):
        return u_first, u_last
    disc = b * b - 4.0 * a * h1
    if disc < 0.0:
        return 1, 0
    root = math.sqrt(disc)
    t_low = max((-b + root) / (2.0 * a), -2.0)
    t_high = min((-b - root) / (2.0 * a), 2.0)
    if t_low > t_high:
        return 1, 0
    return (max(u_first, math.floor(mid + half * t_low) - 1),
            min(u_last, math.ceil(mid + half * t_high) + 1))


@njit(cache=True, error_model="numpy")
def cast_kernel(kinds, params, labels, far_labels, intrinsics, perspective, scale, light,
                base, gain, depth, label_image, shade):  # pragma: no cover - compiled
    """Ray cast primitives into the z-buffer ``depth`` (H, W) float32 (start at inf),
    writing the nearest surface's label into ``label_image`` (H, W) int16 and its Lambert
    shade ``base + gain max(0, n . light)`` into ``shade`` (H, W) float32; pixels no
    primitive covers keep what the three images held.

    ``intrinsics`` = (fx, s, cx, fy, cy); ``scale`` = 1 / Z0 for scaled orthographic,
    1 otherwise; ``light`` (3,) unit vector towards the light. Surfaces that coincide (the
    end ball of a link and the start ball of the next) go to the earlier primitive: a
    later one must be nearer by a relative 1e-6 (float32 depth resolution is 6e-8), so
    ties never speckle the label image.

    One thread: a frame is about 1-3 ms of work (the hand covers a small part of the
    image), too little for numba's ``parallel=True`` to pay for its thread start-up and
    its barrier per call (slower on shared cores), and its compile time was three times
    the serial kernel's (docs/architecture.md, "The first run").
    """
    fy, cy = intrinsics[3], intrinsics[4]
    height, width = depth.shape
    n = kinds.shape[0]
    blocks = np.empty((n, 4), dtype=np.int64)
    present = np.zeros(n, dtype=np.bool_)
    v_first, v_last = height, -1
    for k in range(n):
        present[k] = _block(kinds[k], params[k], intrinsics, perspective, scale, width,
                            height, blocks[k])
        if present[k]:
            v_first = min(v_first, blocks[k, 2])
            v_last = max(v_last, blocks[k, 3])
    for v in range(v_first, v_last + 1):
        yn = (v - cy) / fy
        for k in range(n):
            if not present[k] or v < blocks[k, 2] or v > blocks[k, 3]:
                continue
            kind = kinds[k]
            P = params[k]
            u_first, u_last = blocks[k, 0], blocks[k, 1]
            if kind != BOX:
                u_first, u_last = _row_span(kind, P, yn, u_first, u_last, intrinsics,
                                            perspective, scale)
            for u in range(u_first, u_last + 1):
                ox, oy, dx, dy, dz = _ray(u, yn, intrinsics, perspective, scale)
                if kind == BALL:
                    t = _hit_ball(ox, oy, 0.0, dx, dy, dz, P[0], P[1], P[2], P[3])
                elif kind == CAPSULE:
                    t = _hit_capsule(ox, oy, 0.0, dx, dy, dz, P)
                else:
                    t = _hit_box(ox, oy, 0.0, dx, dy, dz, P)
                if t < depth[v, u] * _TIE:
                    x, y, z = ox + t * dx, oy + t * dy, t * dz
                    depth[v, u] = t
                    label_image[v, u] = far_labels[k] if kind == CAPSULE and \
                        _beyond_end(P, x, y, z) else labels[k]
                    cosine = _shade(kind, P, x, y, z, light)
                    shade[v, u] = base + gain * max(cosine, 0.0)
