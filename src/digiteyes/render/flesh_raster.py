"""Sphere tracing of a camera-frame :class:`~digiteyes.render.flesh.FleshScene`.

Each primitive's bounding sphere is projected into a pixel block (exact tangent bounds,
as for the balls of :mod:`digiteyes.render._kernels`); every row keeps the primitives
whose block covers it, every pixel those whose block holds its column and whose sphere
its ray meets, and only those are marched (:mod:`digiteyes.render._flesh_kernels` says
why that is exact). The result is a depth image, a label image (nearest primitive's link)
and an RGB radiance image: Blinn-Phong shading of textured skin with nails, optionally
with cast shadows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from digiteyes.render._flesh_kernels import ROUND_CONE, distances_at, first_hits, flesh_kernel
from digiteyes.render.flesh import FleshScene
from digiteyes.render.pixels import PixelGrid


@dataclass(frozen=True)
class FleshMaterial:
    """Skin and light of the flesh appearance.

    ``albedo`` and ``nail_albedo`` RGB in [0, 1]; ``ambient`` fraction in [0, 1];
    ``specular``, ``shininess``: Blinn-Phong weight and exponent of skin (``nail_*`` of
    the nails); ``texture`` relative depth of the skin's albedo texture; ``seed`` of the
    texture; ``shadows`` casts the hand's shadows on itself.
    """

    albedo: tuple[float, float, float] = (0.90, 0.70, 0.58)
    nail_albedo: tuple[float, float, float] = (0.95, 0.80, 0.76)
    ambient: float = 0.25
    specular: float = 0.12
    shininess: float = 24.0
    nail_specular: float = 0.45
    nail_shininess: float = 60.0
    texture: float = 0.08
    seed: int = 0
    shadows: bool = False


@dataclass
class FleshRaster:
    """``depth`` float32 (H, W) camera z (mm), inf on background; ``labels`` int16 (H, W),
    -1 on background; ``rgb`` float32 (H, W, 3) radiance (0 on background)."""

    depth: np.ndarray
    labels: np.ndarray
    rgb: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.labels >= 0


def core_blocks(cores: np.ndarray, grid: PixelGrid) -> np.ndarray:
    """(P, 4) pixel blocks of camera-frame capsules (P, 7): the union of the blocks of
    their two end balls, which holds the projection of their convex hull."""
    a = sphere_blocks(np.concatenate([cores[:, 0:3], cores[:, 6:7]], axis=1), grid)
    b = sphere_blocks(np.concatenate([cores[:, 3:6], cores[:, 6:7]], axis=1), grid)
    out = np.empty_like(a)
    out[:, 0::2] = np.minimum(a[:, 0::2], b[:, 0::2])
    out[:, 1::2] = np.maximum(a[:, 1::2], b[:, 1::2])
    return out


def sphere_blocks(spheres: np.ndarray, grid: PixelGrid) -> np.ndarray:
    """(P, 4) int64 pixel blocks (u0, u1, v0, v1) of camera-frame spheres (P, 4); a block
    with u0 > u1 is empty. A sphere reaching behind a perspective camera gets the whole
    grid."""
    fx, s, cx, fy, cy = grid.intrinsics
    out = np.empty((len(spheres), 4), dtype=np.int64)
    for k, (x, y, z, r) in enumerate(spheres):
        if grid.perspective:
            if z - r <= 1e-6:
                out[k] = (0, grid.width - 1, 0, grid.height - 1)
                continue
            xs = _tangent_range(x, z, r)
            ys = _tangent_range(y, z, r)
        else:
            xs = ((x - r) * grid.scale, (x + r) * grid.scale)
            ys = ((y - r) * grid.scale, (y + r) * grid.scale)
        us = [fx * a + s * b + cx for a in xs for b in ys]
        out[k] = (max(0, math.floor(min(us))), min(grid.width - 1, math.ceil(max(us))),
                  max(0, math.floor(fy * ys[0] + cy)),
                  min(grid.height - 1, math.ceil(fy * ys[1] + cy)))
    return out


def _tangent_range(c: float, z: float, r: float) -> tuple[float, float]:
    """Range of x / z over a ball of radius r at (c, z) (its tangent lines' slopes)."""
    root = r * math.sqrt(max(c * c + z * z - r * r, 0.0))
    den = z * z - r * r
    return (c * z - root) / den, (c * z + root) / den


def rasterise_flesh(scene: FleshScene, grid: PixelGrid, light_cam: np.ndarray,
                    material: FleshMaterial = FleshMaterial()) -> FleshRaster:
    """Sphere trace a camera-frame flesh scene on ``grid``; ``light_cam`` is the unit
    direction towards a distant light in the camera frame."""
    depth = np.full((grid.height, grid.width), np.inf, dtype=np.float32)
    labels = np.full((grid.height, grid.width), -1, dtype=np.int16)
    rgb = np.zeros((grid.height, grid.width, 3), dtype=np.float32)
    spheres, cores = scene.bounding_spheres(), scene.bounding_cores()
    m = material
    flesh_kernel(scene.kinds, scene.params, scene.blend, scene.labels, scene.far_labels,
                 spheres, cores, core_blocks(cores, grid), scene.frames, scene.nails,
                 grid.intrinsics, grid.perspective, grid.scale,
                 np.asarray(light_cam, dtype=float),
                 np.array([m.ambient, m.specular, m.shininess, m.nail_specular,
                           m.nail_shininess, m.texture]),
                 np.asarray(m.albedo, dtype=float), np.asarray(m.nail_albedo, dtype=float),
                 int(m.seed), bool(m.shadows), depth, labels, rgb)
    return FleshRaster(depth, labels, rgb)


def keypoint_visibility(scene: FleshScene, points_cam: np.ndarray, links: np.ndarray,
                        perspective: bool, tol_mm: float = 5.0) -> np.ndarray:
    """(K,) bool: nothing but the keypoint's own flesh lies in front of each camera-frame
    point ``points_cam`` (K, 3) of link ``links`` (K,) (a depth test).

    The keypoint's own flesh is the union of the primitives that contain it and either
    carry its link's label (or far label) or end at it (the two phalanges of a joint).
    Along the camera ray through the point, the point is stepped back towards the camera
    by that union's distance until it leaves it (sphere tracing from inside); the first
    surface of the whole hand along the ray (sphere traced) must not lie more than
    ``tol_mm`` in front of that exit. The blended field alone would not do: a fingertip
    curled against the palm is one solid with it. A point behind a perspective camera is
    not visible."""
    p = np.asarray(points_cam, dtype=float)
    if perspective:
        ok = p[:, 2] > 1e-6
        dirs = p / np.where(ok, p[:, 2], 1.0)[:, None]
        origins = np.zeros_like(p)
        t_point = np.where(ok, p[:, 2], 0.0)
    else:
        ok = np.ones(len(p), dtype=bool)
        dirs = np.tile([0.0, 0.0, 1.0], (len(p), 1))
        origins = p * np.array([1.0, 1.0, 0.0])
        t_point = p[:, 2]
    own = _own_primitives(scene, p, np.asarray(links))
    norms = np.linalg.norm(dirs, axis=1)
    t_exit = t_point.copy()
    for _ in range(100):
        d = distances_at(origins + t_exit[:, None] * dirs, scene.kinds, scene.params)
        inside = np.where(own, d, np.inf).min(axis=1)
        step = inside < -0.01
        if not step.any():
            break
        t_exit = np.where(step, t_exit + inside / norms, t_exit)
    first = first_hits(np.ascontiguousarray(origins), np.ascontiguousarray(dirs),
                       np.full(len(p), 1e-6), scene.kinds, scene.params, scene.blend,
                       scene.bounding_spheres(), scene.bounding_cores())
    return ok & (first >= t_exit - tol_mm / np.maximum(norms, 1e-12))


def _own_primitives(scene: FleshScene, points: np.ndarray, links: np.ndarray) -> np.ndarray:
    """(K, P) bool: primitive p contains point k and belongs to its link or ends at it."""
    inside = distances_at(np.ascontiguousarray(points), scene.kinds, scene.params) < 0.0
    mine = (scene.labels[None, :] == links[:, None]) | \
        (scene.far_labels[None, :] == links[:, None])
    cone = scene.kinds == ROUND_CONE
    ends = np.zeros_like(mine)
    for j in (0, 3):
        near = np.linalg.norm(points[:, None, :] - scene.params[None, :, j:j + 3], axis=2)
        ends |= cone[None, :] & (near < 1e-6)
    return inside & (mine | ends)
