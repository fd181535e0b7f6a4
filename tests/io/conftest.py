"""Fixtures for the io tests: a small two-camera rig, frames and per-frame truth."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.io import FrameTruth
from digiteyes.kinematics import KinematicModel, load_model

WIDTH, HEIGHT = 64, 48


@pytest.fixture(scope="session")
def hand() -> KinematicModel:
    return load_model("hand")


@pytest.fixture(scope="session")
def rig() -> Rig:
    """Two cameras: cam0 delivers grey images, cam1 RGB (see :func:`frame_images`)."""
    return Rig((
        Camera.look_at("cam0", (0, -400, 300), (0, 50, 0), width=WIDTH, height=HEIGHT,
                       focal_px=80),
        Camera.look_at("cam1", (300, -400, 300), (0, 50, 0), width=WIDTH, height=HEIGHT,
                       focal_px=80),
    ))


def frame_images(index: int) -> list[np.ndarray]:
    """Deterministic test images for frame ``index``: grey for cam0, RGB for cam1."""
    rng = np.random.default_rng(index)
    return [rng.integers(0, 256, (HEIGHT, WIDTH), dtype=np.uint8),
            rng.integers(0, 256, (HEIGHT, WIDTH, 3), dtype=np.uint8)]


def frame_truth(model: KinematicModel, index: int) -> FrameTruth:
    """Deterministic truth for frame ``index``: a state and 3 keypoints seen by 2 cameras."""
    rng = np.random.default_rng(1000 + index)
    q = model.neutral()
    q[7:] = rng.uniform(-0.3, 0.3, model.n_q - 7)
    q[4:7] = rng.uniform(-50, 50, 3)
    return FrameTruth(q, ("a.tip", "b.base", "palm"), rng.normal(size=(3, 3)) * 100,
                      rng.uniform(0, 64, (2, 3, 2)), rng.random((2, 3)) > 0.3)


@pytest.fixture
def images_of():
    return frame_images


@pytest.fixture
def truth_of(hand):
    return lambda index: frame_truth(hand, index)
