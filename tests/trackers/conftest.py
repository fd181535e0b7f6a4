"""Fixtures shared by the tracker tests."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.kinematics import load_model
from digiteyes.kinematics.rotations import quaternion_from_matrix

PALM_DOWN_HAND = load_model("hand")
N_FRAMES = 20
"""Frames of :func:`palm_down_states`."""


def table_camera(name: str, azimuth_deg: float) -> Camera:
    """640x480 camera 550 mm from the hand, 70 degrees above the table."""
    target = np.array([0.0, 50.0, 25.0])
    az, el = np.radians(azimuth_deg), np.radians(70.0)
    direction = np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    return Camera.look_at(name, target + 550.0 * direction, target, width=640, height=480,
                          focal_px=800.0)


@pytest.fixture(scope="module")
def rig() -> Rig:
    """Two table cameras, 80 degrees apart (:func:`table_camera`)."""
    return Rig((table_camera("left", -40.0), table_camera("right", 40.0)))


@pytest.fixture(scope="module")
def true_states() -> np.ndarray:
    """:func:`palm_down_states`."""
    return palm_down_states()


def palm_down_states() -> np.ndarray:
    """A right hand palm-down on a table (world z up), fingers spread and slightly bent;
    over 20 frames the index finger flexes (MCP +34 deg, PIP +29 deg) while the palm
    slides 20 mm along x and 10 mm along y."""
    q = PALM_DOWN_HAND.neutral()
    palm_down = np.diag([-1.0, 1.0, -1.0])  # palm x -> -x, fingers +y, palmar side down
    q[0:4] = quaternion_from_matrix(palm_down)
    q[4:7] = (0.0, 0.0, 25.0)
    for finger, spread in {"index": -18, "middle": -4.5, "ring": 9, "little": 24}.items():
        q[PALM_DOWN_HAND.state_index(f"{finger}.abd")] = np.radians(spread)
        q[PALM_DOWN_HAND.state_index(f"{finger}.mcp")] = 0.2
        q[PALM_DOWN_HAND.state_index(f"{finger}.pip")] = 0.3
        q[PALM_DOWN_HAND.state_index(f"{finger}.dip")] = 0.1
    q[PALM_DOWN_HAND.state_index("thumb.cmc_abd")] = -0.5
    q[PALM_DOWN_HAND.state_index("thumb.cmc_flex")] = 0.3
    q[PALM_DOWN_HAND.state_index("thumb.mp")] = 0.2
    states = np.repeat(q[None], N_FRAMES, axis=0)
    t = np.linspace(0.0, 1.0, N_FRAMES)
    states[:, PALM_DOWN_HAND.state_index("index.mcp")] += 0.6 * t
    states[:, PALM_DOWN_HAND.state_index("index.pip")] += 0.5 * t
    states[:, 4] += 20.0 * t
    states[:, 5] += 10.0 * t
    return states
