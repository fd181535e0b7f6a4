"""A scaled model poses ``scale`` times the original's points."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.kinematics.scaling import scaled_model


def test_scaled_model_scales_every_point():
    hand = load_model("hand")
    big = scaled_model(hand, 1.2, name="big")
    q = hand.neutral()
    q[7:] = np.clip(0.4, hand.lower[7:], hand.upper[7:])
    q[4:7] = (5.0, -3.0, 200.0)
    q_big = q.copy()
    q_big[4:7] *= 1.2
    _, p = keypoints(hand, forward_kinematics(hand, q))
    _, p_big = keypoints(big, forward_kinematics(big, q_big))
    np.testing.assert_allclose(p_big, 1.2 * p, atol=1e-9)
    assert big.name == "big"
    assert big.link("index.proximal").radius == pytest.approx(12.0)


def test_scale_must_be_positive():
    with pytest.raises(DigitEyesError, match="positive"):
        scaled_model(load_model("hand"), 0.0)
