"""Fixtures for the feature tests (the one-link "stick" model is in tests/conftest.py): an
orthographic camera with 1 px per mm (so image geometry is world geometry), an exact
capsule rasteriser, and an open hand in front of a perspective camera."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel

WIDTH, HEIGHT = 200, 160


@pytest.fixture(scope="session")
def flat_camera() -> Camera:
    """Orthographic camera looking down world +z: pixel = world (x, y) mm + image centre."""
    K = np.array([[1.0, 0.0, WIDTH / 2 - 0.5], [0.0, 1.0, HEIGHT / 2 - 0.5], [0.0, 0.0, 1.0]])
    return Camera.create("flat", K, WIDTH, HEIGHT, np.eye(4), projection="orthographic")


@pytest.fixture(scope="session")
def stick_state(stick) -> Callable[..., np.ndarray]:
    """``stick_state(x, y, angle)``: the stick in the plane z = 100 mm, turned by ``angle``
    about world z, its base at (x, y) mm."""

    def make(x: float, y: float, angle: float) -> np.ndarray:
        q = stick.neutral()
        q[0], q[3] = np.cos(angle / 2), np.sin(angle / 2)
        q[4:7] = x, y, 100.0
        return q

    return make


def capsule_coverage(a: np.ndarray, b: np.ndarray, radius: float, width: int = WIDTH,
                     height: int = HEIGHT, supersample: int = 8) -> np.ndarray:
    """Fraction (H, W) of each pixel inside the 2D capsule of axis a-b (px), by
    ``supersample`` x ``supersample`` point sampling (pixel (0, 0) centred at (0, 0))."""
    o = (np.arange(supersample) + 0.5) / supersample - 0.5
    ys, xs = np.mgrid[0:height, 0:width].astype(float)
    out = np.zeros((height, width))
    ab = b - a
    for dy in o:
        for dx in o:
            X, Y = xs + dx, ys + dy
            t = np.clip(((X - a[0]) * ab[0] + (Y - a[1]) * ab[1]) / (ab @ ab), 0.0, 1.0)
            out += np.hypot(X - a[0] - t * ab[0], Y - a[1] - t * ab[1]) <= radius
    return out / supersample**2


@pytest.fixture(scope="session")
def capsule_image() -> Callable[..., np.ndarray]:
    """``capsule_image(a, b, radius, fg, bg, noise, rng)``: float image of a capsule."""

    def make(a, b, radius, fg=200.0, bg=40.0, noise=0.0, rng=None) -> np.ndarray:
        image = bg + (fg - bg) * capsule_coverage(np.asarray(a), np.asarray(b), radius)
        if noise:
            image = image + rng.normal(0.0, noise, image.shape)
        return image

    return make


@pytest.fixture(scope="session")
def scene() -> tuple[KinematicModel, np.ndarray, Camera]:
    """An open right hand, palm towards a camera 430 mm away, thumb spread (no overlaps)."""
    model = load_model("hand")
    q = model.neutral()
    for finger, spread in zip(("index", "middle", "ring", "little"), (-20, -5, 8, 22),
                              strict=True):
        q[model.state_index(f"{finger}.abd")] = np.radians(spread)
        q[model.state_index(f"{finger}.mcp")] = np.radians(15)
        q[model.state_index(f"{finger}.pip")] = np.radians(20)
        q[model.state_index(f"{finger}.dip")] = np.radians(10)
    q[model.state_index("thumb.cmc_flex")] = np.radians(40)
    q[model.state_index("thumb.mp")] = np.radians(10)
    q[model.state_index("thumb.ip")] = np.radians(10)
    q[4:7] = [0.0, -50.0, 0.0]
    camera = Camera.look_at("front", eye=[0.0, -200.0, 380.0], target=[0.0, 0.0, 0.0],
                            up=[0.0, 1.0, 0.0])
    return model, q, camera
