"""Z-buffer ray casting of primitives on a pixel grid.

Each primitive is ray cast only inside the pixel block that bounds its projection (see
:meth:`~digiteyes.render.scene.Primitive.bounds`); where its hit is nearer than the
depth already stored, the pixel takes its depth, its label and the Lambert cosine
``max(0, n . l)`` of its surface normal with the light direction. All pixels of a block
are processed at once with numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from digiteyes.render.pixels import PixelGrid
from digiteyes.render.scene import Primitive


@dataclass
class Raster:
    """Per-pixel result of ray casting on a grid of (H, W) pixels.

    ``depth`` float32, camera z (mm) of the nearest surface, ``np.inf`` on background;
    ``labels`` int16, link index of that surface, -1 on background; ``shade`` float32,
    Lambert cosine ``max(0, n . l)`` in [0, 1], 0 on background.
    """

    depth: np.ndarray
    labels: np.ndarray
    shade: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """Boolean mask of the pixels that see the model."""
        return self.labels >= 0


def rasterise(prims: Sequence[Primitive], grid: PixelGrid, light_cam: np.ndarray) -> Raster:
    """Ray cast camera-frame primitives on ``grid``; ``light_cam`` is the unit direction
    towards the light in the camera frame."""
    depth = np.full((grid.height, grid.width), np.inf, dtype=np.float32)
    labels = np.full((grid.height, grid.width), -1, dtype=np.int16)
    shade = np.zeros((grid.height, grid.width), dtype=np.float32)
    for prim in prims:
        block = grid.pixel_block(prim.bounds(grid))
        if block is None:
            continue
        u0, u1, v0, v1 = block
        o, d = grid.rays(u0, u1, v0, v1)
        t = prim.hit(o, d)
        z_view = depth[v0:v1 + 1, u0:u1 + 1]
        nearer = t < z_view
        if not nearer.any():
            continue
        t_hit = t[nearer]
        z_view[nearer] = t_hit
        p = np.stack([_pick(o[k], nearer) + t_hit * _pick(d[k], nearer) for k in range(3)],
                     axis=1)
        labels[v0:v1 + 1, u0:u1 + 1][nearer] = prim.labels(p)
        cosine = prim.normals(p) @ light_cam
        shade[v0:v1 + 1, u0:u1 + 1][nearer] = np.maximum(cosine, 0.0)
    return Raster(depth, labels, shade)


def _pick(component, mask: np.ndarray) -> np.ndarray | float:
    """The entries of a ray component (float or broadcastable array) at ``mask``."""
    if np.ndim(component) == 0:
        return component
    return np.broadcast_to(component, mask.shape)[mask]
