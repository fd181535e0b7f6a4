"""Fixtures for the evaluation tests: a rig, hand trajectories, truth and logs built from
states the way the renderer builds them (digiteyes.kinematics.keypoints)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.io import GroundTruth, StateLog
from digiteyes.kinematics import KinematicModel, forward_kinematics, load_model
from digiteyes.kinematics.keypoints import keypoints


@pytest.fixture(scope="session")
def hand() -> KinematicModel:
    return load_model("hand")


@pytest.fixture(scope="session")
def mouse_hand() -> KinematicModel:
    return load_model("mouse-hand")


@pytest.fixture(scope="session")
def rig() -> Rig:
    return Rig((
        Camera.look_at("left", (-250, -450, 350), (0, 60, 0), width=320, height=240,
                       focal_px=400),
        Camera.look_at("right", (250, -450, 350), (0, 60, 0), width=320, height=240,
                       focal_px=400),
    ))


def trajectory(model: KinematicModel, n: int, seed: int = 0) -> np.ndarray:
    """(n, n_q) smooth random states inside the joint limits."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)[:, None]
    lo = np.where(np.isfinite(model.lower), model.lower, -50.0)
    hi = np.where(np.isfinite(model.upper), model.upper, 50.0)
    a, b = rng.uniform(lo, hi), rng.uniform(lo, hi)
    q = a + (b - a) * t
    if model.base_state is not None:
        k = model.base_state
        quat = np.array([1.0, 0.0, 0.0, 0.0]) + 0.3 * rng.normal(size=4) * t
        q[:, k:k + 4] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return q


def truth_from_states(model: KinematicModel, rig: Rig, states: np.ndarray) -> GroundTruth:
    """Ground truth as the renderer writes it: keypoints, projections, in-image flags."""
    names, kp3 = keypoints(model, forward_kinematics(model, states))
    kp2 = np.stack([cam.project(kp3) for cam in rig.cameras], axis=1)
    visible = np.stack([cam.in_image(cam.project(kp3)) & (cam.depth(kp3) > 0)
                        for cam in rig.cameras], axis=1)
    return GroundTruth(np.array(states), tuple(names), kp3, kp2, visible)


def log_from_states(states: np.ndarray, lost: np.ndarray | None = None,
                    frames: np.ndarray | None = None) -> StateLog:
    n = len(states)
    return StateLog(np.arange(n) if frames is None else np.asarray(frames), np.array(states),
                    np.zeros(n, bool) if lost is None else np.asarray(lost, bool),
                    np.full(n, 0.5), np.full(n, 3), np.full(n, 0.02))


@pytest.fixture
def make_truth():
    return truth_from_states


@pytest.fixture
def make_log():
    return log_from_states


@pytest.fixture
def make_trajectory():
    return trajectory
