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


def test_hand_keypoints_at_a_scale_are_the_scaled_models_at_the_same_state():
    """``hand_keypoints(model, q, s)`` is the hand of ``scaled_model(model, s)`` posed at
    the very state ``q`` (palm at ``q``'s translation), per state with per-state scales,
    and the model's own hand at scale 1."""
    from digiteyes.kinematics.keypoints import hand_keypoints

    hand = load_model("hand")
    rng = np.random.default_rng(3)
    states = np.tile(hand.neutral(), (3, 1))
    states[:, 7:] = rng.uniform(hand.lower[7:], hand.upper[7:], (3, hand.n_q - 7))
    states[:, 4:7] = rng.uniform(-200.0, 200.0, (3, 3))
    scales = np.array([0.85, 1.0, 1.2])
    names, points = hand_keypoints(hand, states, scales)
    for q, s, p in zip(states, scales, points, strict=True):
        big = scaled_model(hand, s)
        expected_names, expected = keypoints(big, forward_kinematics(big, q))
        assert names == expected_names
        np.testing.assert_allclose(p, expected[0], atol=1e-9)
    np.testing.assert_allclose(hand_keypoints(hand, states)[1],
                               keypoints(hand, forward_kinematics(hand, states))[1])


def test_a_model_without_a_pose_base_takes_only_its_own_size():
    from digiteyes.kinematics.scaling import model_unit_states

    mouse = load_model("mouse-hand")
    q = mouse.neutral()
    np.testing.assert_array_equal(model_unit_states(mouse, q, 1.0), q)
    with pytest.raises(DigitEyesError, match="no pose base"):
        model_unit_states(mouse, q, 0.9)
