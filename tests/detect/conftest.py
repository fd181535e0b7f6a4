"""Shared fixtures of the detector tests: the hand model, a camera and a posed hand."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.rotations import quaternion_from_rotvec


@pytest.fixture(scope="session")
def hand() -> KinematicModel:
    return load_model("hand")


@pytest.fixture(scope="session")
def camera() -> Camera:
    """A 640x480 camera 450 mm in front of the world origin, image up = world -y... so the
    fingers (+y) point down the image unless the palm is turned."""
    return Camera.look_at("front", eye=(0, 0, 450), target=(0, 0, 0), up=(0, -1, 0))


@pytest.fixture(scope="session")
def posed():
    """The function :func:`posed_hand`."""
    return posed_hand


def posed_hand(hand: KinematicModel, seed: int, flex: tuple[float, float] = (0.0, 0.6),
               rotvec: tuple[float, float, float] = (0.25, 0.15, 2.9)) -> np.ndarray:
    """A state with random joint angles (rad, uniform in ``flex`` then clipped), palm turned
    by ``rotvec`` (so the fingers point up the image) and moved a little."""
    rng = np.random.default_rng(seed)
    q = hand.neutral()
    q[7:] = np.clip(rng.uniform(*flex, hand.n_q - 7), hand.lower[7:], hand.upper[7:])
    q[0:4] = quaternion_from_rotvec(np.array(rotvec))
    q[4:7] = (rng.uniform(-20, 20), rng.uniform(0, 30), rng.uniform(-20, 20))
    return q
