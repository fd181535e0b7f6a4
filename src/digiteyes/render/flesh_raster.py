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

from digiteyes.render._flesh_kernels import first_hits, flesh_kernel
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


def keypoint_visibility(scene: FleshScene, points_cam: np.ndarray, perspective: bool,
                        tol_mm: float = 0.1) -> np.ndarray:
    """(K,) bool: nothing lies in front of each camera-frame point but the flesh it sits
    in. Along the camera ray through the point, the first surface (sphere traced) must be
    where the ray enters the flesh around the point (found by stepping back from the point
    by the field's magnitude until it leaves the flesh), within ``tol_mm``. A point
    behind a perspective camera is not visible."""
    p = np.asarray(points_cam, dtype=float)
    if perspective:
        z = p[:, 2]
        ok = z > 1e-6
        dirs = p / np.where(ok, z, 1.0)[:, None]
        origins = np.zeros_like(p)
        t_point = np.where(ok, z, 0.0)
    else:
        ok = np.ones(len(p), dtype=bool)
        dirs = np.tile([0.0, 0.0, 1.0], (len(p), 1))
        origins = p * np.array([1.0, 1.0, 0.0])
        t_point = p[:, 2]
    norms = np.linalg.norm(dirs, axis=1)
    t_entry = t_point.copy()
    for _ in range(200):
        f, _ = scene.field(origins + t_entry[:, None] * dirs)
        inside = f < -0.01
        if not inside.any():
            break
        t_entry = np.where(inside, t_entry + f / norms, t_entry)
    first = first_hits(np.ascontiguousarray(origins), np.ascontiguousarray(dirs),
                       np.full(len(p), 1e-6), scene.kinds, scene.params, scene.blend,
                       scene.bounding_spheres(), scene.bounding_cores())
    return ok & (first >= t_entry - tol_mm / np.maximum(norms, 1e-12))
