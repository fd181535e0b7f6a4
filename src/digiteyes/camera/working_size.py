"""Track large images at a working size: the cameras of a rig for resized images.

A 4K phone video shows the hand three times larger in pixels than the 1280x720 footage the
trackers' pixel settings (search windows, edge scales) were measured on, and costs nine
times the pixels: the feature tracker loses it in many frames and runs at a few frames per
second. ``digiteyes track`` therefore resizes frames whose longer side exceeds
``max_side`` pixels (``--max-size``, default :data:`DEFAULT_MAX_SIDE`) and tracks them
with the cameras that see the resized images; every pixel output is mapped back to the
real images (:meth:`digiteyes.camera.Rig.real_pixels`).

Resizing an image from ``W x H`` to ``W' x H'`` maps a pixel centre ``u`` (integers at
pixel centres) to ``u' = s_x (u + 1/2) - 1/2`` with ``s_x = W'/W`` (OpenCV's resize uses
the same centres), so the camera keeps its pose and distortion and its intrinsics become
``f_x' = s_x f_x``, ``skew' = s_x skew``, ``c_x' = s_x (c_x + 1/2) - 1/2`` (likewise in y).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from digiteyes.camera.camera import Camera
from digiteyes.camera.rig import Rig

DEFAULT_MAX_SIDE = 1920
"""Longer image side (px) ``track`` works at by default: 1080p and smaller unchanged."""


def working_size(width: int, height: int, max_side: int | None) -> tuple[int, int]:
    """The ``(width, height)`` an image is tracked at: the same aspect, the longer side at
    most ``max_side`` (None: no limit)."""
    if max_side is None or max(width, height) <= max_side:
        return width, height
    scale = max_side / max(width, height)
    return max(1, round(width * scale)), max(1, round(height * scale))


def resized_camera(camera: Camera, width: int, height: int) -> Camera:
    """``camera`` for its images resized to ``width x height`` (module docstring)."""
    sx, sy = width / camera.width, height / camera.height
    K = np.array(camera.K, dtype=float)
    K[0] *= sx
    K[1] *= sy
    K[0, 2] = sx * (camera.K[0, 2] + 0.5) - 0.5
    K[1, 2] = sy * (camera.K[1, 2] + 0.5) - 0.5
    return Camera.create(camera.name, K, width, height, camera.T_cam_world, camera.dist,
                         camera.projection, camera.depth_mm)


def working_rig(rig: Rig, max_side: int | None) -> Rig:
    """The rig for images resized to :func:`working_size`, with the real sizes recorded;
    ``rig`` itself when no camera's images are larger than ``max_side``."""
    if rig.mirrored or rig.real_sizes is not None:
        raise ValueError("resize the real rig, then mirror it")
    sizes = [working_size(c.width, c.height, max_side) for c in rig]
    if all(size == (c.width, c.height) for size, c in zip(sizes, rig, strict=True)):
        return rig
    return Rig(tuple(resized_camera(c, *size) for c, size in zip(rig, sizes, strict=True)),
               real_sizes=tuple((c.width, c.height) for c in rig))


def resize_images(images: Sequence[np.ndarray], rig: Rig) -> list[np.ndarray]:
    """Each image resized to its camera's size in ``rig`` (area averaging)."""
    return [image if image.shape[1::-1] == (c.width, c.height) else
            cv2.resize(image, (c.width, c.height), interpolation=cv2.INTER_AREA)
            for image, c in zip(images, rig, strict=True)]
