"""Fixtures shared by the kinematics tests: the shipped hand and random hand states."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from digiteyes.kinematics import KinematicModel, load_model

StateSampler = Callable[..., np.ndarray]


@pytest.fixture(scope="session")
def hand() -> KinematicModel:
    """The 28-state hand of thesis Appendix A."""
    return load_model("hand")


@pytest.fixture
def random_states() -> StateSampler:
    """``random_states(rng, n, quat_norm=1.0)``: (n, 28) hand states.

    Palm quaternion uniform on the sphere (then scaled to ``quat_norm``), palm translation
    uniform in +-300 mm, joint angles uniform in +-1.2 rad (limits are not enforced by
    forward kinematics, and wide angles exercise every branch).
    """

    def sample(rng: np.random.Generator, n: int, quat_norm: float = 1.0) -> np.ndarray:
        q = np.empty((n, 28))
        quat = rng.normal(size=(n, 4))
        q[:, 0:4] = quat_norm * quat / np.linalg.norm(quat, axis=1, keepdims=True)
        q[:, 4:7] = rng.uniform(-300.0, 300.0, size=(n, 3))
        q[:, 7:] = rng.uniform(-1.2, 1.2, size=(n, 21))
        return q

    return sample
