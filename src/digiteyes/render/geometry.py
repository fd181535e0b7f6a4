"""Ray intersections with the model's primitives: spheres, capsules and boxes.

Rays live in the camera frame (OpenCV: x right, y down, z forward, mm) and are given as
component triples ``o = (ox, oy, oz)``, ``d = (dx, dy, dz)`` whose entries are floats or
arrays that broadcast together (one entry per pixel). The renderer always passes
directions with ``dz = 1`` and origins with ``oz = 0``, so the ray parameter ``t`` of a
hit *is* its camera depth z in mm; the functions themselves accept any direction and
return the parameter ``t`` of the nearest hit in front of the origin (``np.inf`` for a
miss). The origin must lie outside the body.

A capsule (the report's finger link: a cylinder with hemispherical ends) is the union of
a finite cylinder and two balls, so its nearest hit is the nearest of the lateral-surface
hit (kept where it falls between the end planes) and the two ball hits; the end discs lie
inside the balls and never come first.
"""

from __future__ import annotations

import numpy as np

NEAR_MM = 1e-6
"""Hits closer to the ray origin than this (mm along z for renderer rays) are ignored."""

Triple = tuple  # three floats or broadcastable arrays


def dot3(u: Triple, v: Triple):
    """Component-wise dot product of two triples (floats or broadcastable arrays)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def hit_sphere(o: Triple, d: Triple, centre: np.ndarray, radius: float) -> np.ndarray:
    """Ray parameter of the nearest hit with a ball, ``np.inf`` where the ray misses.

    Solves ``|o + t d - c|^2 = r^2`` for its smaller root.
    """
    oc = (o[0] - centre[0], o[1] - centre[1], o[2] - centre[2])
    dd = dot3(d, d)
    b = dot3(d, oc)
    c = dot3(oc, oc) - radius * radius
    h = b * b - dd * c
    t = (-b - np.sqrt(np.maximum(h, 0.0))) / dd
    return np.where((h >= 0.0) & (t > NEAR_MM), t, np.inf)


def hit_capsule(o: Triple, d: Triple, a: np.ndarray, b: np.ndarray,
                radius: float) -> np.ndarray:
    """Ray parameter of the nearest hit with the capsule of axis ``a``-``b`` and radius
    ``radius`` (mm), ``np.inf`` where the ray misses."""
    ba = b - a
    oa = (o[0] - a[0], o[1] - a[1], o[2] - a[2])
    baba = float(ba @ ba)
    bard = dot3(ba, d)
    baoa = dot3(ba, oa)
    qa = baba * dot3(d, d) - bard * bard
    qb = baba * dot3(d, oa) - baoa * bard
    qc = baba * dot3(oa, oa) - baoa * baoa - radius * radius * baba
    h = qb * qb - qa * qc
    parallel = qa <= 1e-12 * baba
    t_body = (-qb - np.sqrt(np.maximum(h, 0.0))) / np.where(parallel, 1.0, qa)
    y = baoa + t_body * bard
    body = (h >= 0.0) & ~parallel & (y > 0.0) & (y < baba) & (t_body > NEAR_MM)
    t = np.where(body, t_body, np.inf)
    t = np.minimum(t, hit_sphere(o, d, a, radius))
    return np.minimum(t, hit_sphere(o, d, b, radius))


def hit_box(o: Triple, d: Triple, centre: np.ndarray, axes: np.ndarray,
            half: np.ndarray) -> np.ndarray:
    """Ray parameter of the nearest hit with an oriented box (slab method).

    ``axes`` (3, 3) holds the box axes as columns (camera frame), ``half`` the half
    extents along them (mm), ``centre`` the box centre.
    """
    oc = (o[0] - centre[0], o[1] - centre[1], o[2] - centre[2])
    t_near = -np.inf
    t_far = np.inf
    for i in range(3):
        axis = axes[:, i]
        ob = dot3(axis, oc)
        db = dot3(axis, d)
        db = np.where(np.abs(db) < 1e-12, 1e-12, db)
        t1 = (-half[i] - ob) / db
        t2 = (half[i] - ob) / db
        t_near = np.maximum(t_near, np.minimum(t1, t2))
        t_far = np.minimum(t_far, np.maximum(t1, t2))
    return np.where((t_near <= t_far) & (t_near > NEAR_MM), t_near, np.inf)


def segment_parameter(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unclamped parameter s of the point of line a-b closest to points p (M, 3):
    0 at ``a``, 1 at ``b``."""
    ba = b - a
    return (p - a) @ ba / float(ba @ ba)


def capsule_normals(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Outward unit normals (M, 3) at surface points p (M, 3) of the capsule a-b."""
    s = np.clip(segment_parameter(p, a, b), 0.0, 1.0)
    n = p - (a + s[:, None] * (b - a))
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def sphere_normals(p: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Outward unit normals (M, 3) at surface points p (M, 3) of a ball."""
    n = p - centre
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def box_normals(p: np.ndarray, centre: np.ndarray, axes: np.ndarray,
                half: np.ndarray) -> np.ndarray:
    """Outward unit normals (M, 3) at surface points p (M, 3) of an oriented box: the axis
    of the face the point lies on (largest relative coordinate)."""
    local = (p - centre) @ axes
    face = np.argmax(np.abs(local) / half, axis=1)
    sign = np.sign(local[np.arange(len(p)), face])
    return axes[:, face].T * sign[:, None]
