"""Z-buffer ray casting of a scene on a pixel grid.

Each primitive is ray cast only inside the pixel block that bounds its projection (exact
tangent bounds for balls and capsule ends, vertex bounds for boxes, the whole image for a
primitive reaching behind a perspective camera), and a ball or capsule only on the part
of each row whose rays' lines meet it or its axis's infinite cylinder. Where its hit is
nearer than the depth already stored, the pixel takes its depth, its label and its
Lambert shading ``ambient + (1 - ambient) max(0, n . l)`` (n the outward normal, l the
direction towards a distant light). :func:`paint` draws the same shading straight over an
image. The loop is compiled (:mod:`digiteyes.render._kernels` says why).
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
    _cast(scene, grid, light_cam, ambient, 1.0 - ambient, depth, labels, shade)
    return Raster(depth, labels, shade)


def paint(scene: Scene, grid: PixelGrid, light_cam: np.ndarray, base: float, gain: float,
          image: np.ndarray) -> None:
    """Draw a camera-frame scene over ``image`` (H, W) float32 of ``grid``, in place: the
    model's pixels take the shade ``base + gain max(0, n . l)`` (``l`` = ``light_cam``),
    the others keep their values. The same ray cast as :func:`rasterise` without its
    depth, label and shade images (drawing the model over a backdrop in one pass)."""
    if image.shape != (grid.height, grid.width) or image.dtype != np.float32:
        raise ValueError(f"paint needs a float32 image of {grid.height} x {grid.width}, "
                         f"got {image.dtype} {image.shape}")
    depth = np.full(image.shape, np.inf, dtype=np.float32)
    labels = np.empty(image.shape, dtype=np.int16)
    _cast(scene, grid, light_cam, base, gain, depth, labels, image)


def _cast(scene: Scene, grid: PixelGrid, light_cam: np.ndarray, base: float, gain: float,
          depth: np.ndarray, labels: np.ndarray, shade: np.ndarray) -> None:
    cast_kernel(scene.kinds, scene.params, scene.labels, scene.far_labels, grid.intrinsics,
                grid.perspective, grid.scale, np.asarray(light_cam, dtype=float), float(base),
                float(gain), depth, labels, shade)
