"""Similarity alignment (kabsch) recovers a known rotation, translation and scale."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics.procrustes import kabsch
from digiteyes.kinematics.rotations import matrix_from_quaternion


def test_kabsch_recovers_similarity():
    rng = np.random.default_rng(3)
    x = rng.normal(scale=40.0, size=(8, 3))
    quat = rng.normal(size=4)
    R = matrix_from_quaternion(quat / np.linalg.norm(quat))
    t = np.array([10.0, -5.0, 300.0])
    y = 1.3 * x @ R.T + t
    R_fit, t_fit, c = kabsch(x, y)
    np.testing.assert_allclose(R_fit, R, atol=1e-9)
    np.testing.assert_allclose(t_fit, t, atol=1e-7)
    assert c == pytest.approx(1.3, abs=1e-10)


def test_kabsch_never_reflects():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(6, 3))
    R, _, _ = kabsch(x, x * np.array([-1.0, 1.0, 1.0]))  # a mirror image: best rotation
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_kabsch_rejects_too_few_points():
    with pytest.raises(DigitEyesError, match="P >= 3"):
        kabsch(np.zeros((2, 3)), np.zeros((2, 3)))
