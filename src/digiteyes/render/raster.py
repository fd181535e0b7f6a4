"""Z-buffer ray casting of a scene on a pixel grid.

Each primitive is ray cast only inside the pixel block that bounds its projection (exact
tangent bounds for balls and capsule ends, vertex bounds for boxes, the whole image for a
primitive reaching behind a perspective camera); where its hit is nearer than the depth
already stored, the pixel takes its depth, its label and its Lambert shading
``ambient + (1 - ambient) max(0, n . l)`` (n the outward normal, l the direction towards
a distant light). The loop is compiled
(:mod:`digiteyes.render._kernels` says why).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.render._kernels import cast_kernel
from digiteyes.render.pixels import PixelGrid
from digiteyes.render.scene import Scene


@dataclass
class Raster:
    """Per-pixel result of ray casting on a grid of (H, W) pixels.

    ``depth`` float32, camera z (mm) of the nearest surface, ``np.inf`` on background;
    ``labels`` int16, link index of that surface, -1 on background; ``shade`` float32,
    Lambert factor ``ambient + (1 - ambient) max(0, n . l)`` in [0, 1], 0 on background.
    """

    depth: np.ndarray
    labels: np.ndarray
    shade: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """Boolean mask of the pixels that see the model."""
        return self.labels >= 0


def rasterise(scene: Scene, grid: PixelGrid, light_cam: np.ndarray,
              ambient: float = 0.0) -> Raster:
    """Ray cast a camera-frame scene on ``grid``; ``light_cam`` is the unit direction
    towards the light in the camera frame, ``ambient`` the ambient fraction in [0, 1]."""
    depth = np.full((grid.height, grid.width), np.inf, dtype=np.float32)
    labels = np.full((grid.height, grid.width), -1, dtype=np.int16)
    shade = np.zeros((grid.height, grid.width), dtype=np.float32)
    cast_kernel(scene.kinds, scene.params, scene.labels, scene.far_labels, grid.intrinsics,
                grid.perspective, grid.scale, np.asarray(light_cam, dtype=float), float(ambient),
                depth,
                labels, shade)
    return Raster(depth, labels, shade)
