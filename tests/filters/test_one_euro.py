"""The One Euro filter on hand states: unit quaternions, causality, noise reduction on a
still hand, little lag on a moving one, resets, and the filter's own maths."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from digiteyes.errors import StateError
from digiteyes.filters import OneEuroOptions, one_euro_filter
from digiteyes.filters.one_euro import _alpha
from digiteyes.kinematics import forward_kinematics, integrate, load_model
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.synth.scenarios import build_scenario

FPS = 10.0


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


def noisy(model, states, sigma_v, seed=0):
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 1.0, (len(states), model.n_v)) * sigma_v
    return integrate(model, states, steps)


def tangent_sigma(model, rot_rad=0.005, trans_mm=0.5, joint_rad=0.01):
    sigma = np.full(model.n_v, joint_rad)
    sigma[0:3] = rot_rad
    sigma[3:6] = trans_mm
    return sigma


def test_still_hand_noise_shrinks_and_quaternion_stays_unit(hand):
    truth = np.repeat(build_scenario("whole-hand", n_frames=200).states[:1], 120, axis=0)
    raw = noisy(hand, truth, tangent_sigma(hand))
    out = one_euro_filter(hand, raw, FPS)
    np.testing.assert_allclose(np.linalg.norm(out[:, :4], axis=1), 1.0, atol=1e-12)
    step_raw = np.sqrt(np.mean(np.diff(raw[20:, 7:], axis=0) ** 2))
    step_out = np.sqrt(np.mean(np.diff(out[20:, 7:], axis=0) ** 2))
    assert step_raw / step_out > 5.0
    assert np.abs(out[20:, 7:] - truth[20:, 7:]).mean() < np.abs(raw[20:, 7:]
                                                                 - truth[20:, 7:]).mean()


def test_moving_hand_lags_about_a_frame_without_noise(hand):
    """Keypoints of the filtered whole-hand motion match the truth best about one frame
    back (between 0.5 and 1.5 frames)."""
    truth = build_scenario("whole-hand", n_frames=200).states
    out = one_euro_filter(hand, truth, FPS)
    true_kp = keypoints(hand, forward_kinematics(hand, truth))[1]
    out_kp = keypoints(hand, forward_kinematics(hand, out))[1]

    def error(shift: int) -> float:
        return float(np.linalg.norm(out_kp[10:] - true_kp[10 - shift:len(truth) - shift],
                                    axis=-1).mean())

    assert error(1) < error(0) and error(1) < error(2)


def test_causal_and_reset(hand):
    states = noisy(hand, np.repeat(hand.neutral()[None], 30, axis=0), tangent_sigma(hand))
    full = one_euro_filter(hand, states, FPS)
    np.testing.assert_allclose(one_euro_filter(hand, states[:17], FPS), full[:17])
    reset = np.zeros(30, dtype=bool)
    reset[12] = True
    restarted = one_euro_filter(hand, states, FPS, reset=reset)
    np.testing.assert_allclose(restarted[12], states[12] / [*([np.linalg.norm(
        states[12, :4])] * 4), *([1.0] * (hand.n_q - 4))])
    np.testing.assert_allclose(restarted[12:], one_euro_filter(hand, states[12:], FPS))


def test_scalar_case_is_the_published_filter(hand):
    """A joint alone with beta 0 is an exponential smoother with alpha(min_cutoff)."""
    rng = np.random.default_rng(3)
    states = np.repeat(hand.neutral()[None], 25, axis=0)
    states[:, 9] = 0.5 + rng.normal(0.0, 0.05, 25)
    options = OneEuroOptions(min_cutoff_hz=0.7, beta_per_rad=0.0, beta_per_mm=0.0)
    out = one_euro_filter(hand, states, FPS, options)[:, 9]
    a = _alpha(0.7, 1.0 / FPS)
    assert a == pytest.approx(1.0 / (1.0 + 1.0 / (2 * np.pi * 0.7 * 0.1)))
    expected = [states[0, 9]]
    for z in states[1:, 9]:
        expected.append(expected[-1] + a * (z - expected[-1]))
    np.testing.assert_allclose(out, expected, atol=1e-12)


def test_scalar_case_with_speed_and_dead_band(hand):
    """A joint alone follows the equations of the module docstring step by step: the speed
    smoothed at ``d_cutoff``, the cutoff raised by ``beta`` per rad/s above the dead band."""
    rng = np.random.default_rng(4)
    states = np.repeat(hand.neutral()[None], 40, axis=0)
    states[:, 9] = 0.2 + 0.03 * np.arange(40) + rng.normal(0.0, 0.01, 40)
    options = OneEuroOptions(min_cutoff_hz=0.2, beta_per_rad=12.0, d_cutoff_hz=0.2,
                             deadband_rad_s=0.1)
    out = one_euro_filter(hand, states, FPS, options)[:, 9]
    period = 1.0 / FPS
    expected, speed = [states[0, 9]], 0.0
    for z in states[1:, 9]:
        step = z - expected[-1]
        speed = _alpha(0.2, period) * step / period + (1 - _alpha(0.2, period)) * speed
        cutoff = 0.2 + 12.0 * max(abs(speed) - 0.1, 0.0)
        expected.append(expected[-1] + _alpha(cutoff, period) * step)
    np.testing.assert_allclose(out, expected, atol=1e-12)
    published = one_euro_filter(hand, states, FPS, replace(options, deadband_rad_s=0.0))
    assert np.abs(published[:, 9] - out).max() > 1e-3


def test_dead_band_keeps_slow_noise_at_the_resting_cutoff(hand):
    """Noise whose smoothed speed stays under the dead band is filtered as with beta 0."""
    rng = np.random.default_rng(5)
    states = np.repeat(hand.neutral()[None], 30, axis=0)
    states[:, 9] = 0.5 + rng.normal(0.0, 0.002, 30)
    calm = OneEuroOptions(min_cutoff_hz=0.2, beta_per_rad=0.0, deadband_rad_s=0.0)
    banded = OneEuroOptions(min_cutoff_hz=0.2, beta_per_rad=50.0, deadband_rad_s=1.0)
    np.testing.assert_allclose(one_euro_filter(hand, states, FPS, banded)[:, 9],
                               one_euro_filter(hand, states, FPS, calm)[:, 9], atol=1e-12)


def test_bad_arguments(hand):
    with pytest.raises(StateError, match="min_cutoff_hz"):
        OneEuroOptions(min_cutoff_hz=0.0)
    with pytest.raises(StateError, match="deadband_rad_s"):
        OneEuroOptions(deadband_rad_s=-1.0)
    with pytest.raises(StateError, match="fps"):
        one_euro_filter(hand, hand.neutral()[None], 0.0)
    with pytest.raises(StateError, match="shape"):
        one_euro_filter(hand, hand.neutral(), FPS)
