"""A camera for footage nobody calibrated: pinhole, principal point at the image centre,
focal length from an assumed horizontal field of view."""

from __future__ import annotations

import math

import numpy as np

from digiteyes.camera.camera import Camera
from digiteyes.errors import CameraError

DEFAULT_HFOV_DEG = 60.0
"""Assumed horizontal field of view, degrees: webcams span about 55-78 deg and phone main
cameras about 65-75 deg (landscape). The focal length scales with ``1 / tan(hfov / 2)``,
so a camera whose true field is 70 deg gets a focal length 21 % too long; with the hand's
size fixed that places the hand 21 % too far (the pixels agree either way)."""


def default_camera(width: int, height: int, hfov_deg: float = DEFAULT_HFOV_DEG,
                   name: str = "camera") -> Camera:
    """A perspective camera at the world origin (``T_cam_world`` = identity) with square
    pixels, no distortion, centre ``((W - 1) / 2, (H - 1) / 2)`` and focal length
    ``f = (W / 2) / tan(hfov / 2)`` px."""
    if not 1.0 < hfov_deg < 179.0:
        raise CameraError(f"camera {name!r}: field of view must lie in (1, 179) degrees, got "
                          f"{hfov_deg}")
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2)
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    return Camera.create(name, K, width, height)
