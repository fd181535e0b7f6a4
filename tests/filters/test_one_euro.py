"""The One Euro filter on hand states: unit quaternions, causality, noise reduction on a
still hand, little lag on a moving one, resets, and the filter's own maths."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from digiteyes.benchmarks.smoothing import lag_frames
from digiteyes.errors import StateError
from digiteyes.filters import OneEuroOptions, one_euro_filter, one_euro_trace
from digiteyes.filters.one_euro import _alpha
from digiteyes.kinematics import difference, forward_kinematics, integrate, load_model
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


def test_moving_hand_lags_at_most_a_frame_without_noise(hand):
    """Keypoints of the filtered whole-hand motion match the truth best between 0.1 and
    1 frame back."""
    truth = build_scenario("whole-hand", n_frames=200).states
    out = one_euro_filter(hand, truth, FPS)
    true_kp = keypoints(hand, forward_kinematics(hand, truth))[1]
    out_kp = keypoints(hand, forward_kinematics(hand, out))[1]
    lag, _ = lag_frames(out_kp, true_kp)
    assert 0.1 <= lag <= 1.0


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
    options = OneEuroOptions(min_cutoff_hz=0.7, beta_per_mm_s=0.0)
    out = one_euro_filter(hand, states, FPS, options)[:, 9]
    a = _alpha(0.7, 1.0 / FPS)
    assert a == pytest.approx(1.0 / (1.0 + 1.0 / (2 * np.pi * 0.7 * 0.1)))
    expected = [states[0, 9]]
    for z in states[1:, 9]:
        expected.append(expected[-1] + a * (z - expected[-1]))
    np.testing.assert_allclose(out, expected, atol=1e-12)


def test_speed_cutoff_and_dead_band_follow_the_equations(hand):
    """A joint alone follows the module docstring step by step: keypoint velocities from
    the previous output to the measurement, smoothed at ``d_cutoff``; their RMS speed
    raises the cutoff by ``beta`` per mm/s above the dead band."""
    rng = np.random.default_rng(4)
    states = np.repeat(hand.neutral()[None], 40, axis=0)
    states[:, 9] = 0.2 + 0.03 * np.arange(40) + rng.normal(0.0, 0.01, 40)
    options = OneEuroOptions(min_cutoff_hz=0.2, beta_per_mm_s=0.5, d_cutoff_hz=0.2,
                             deadband_mm_s=5.0)
    trace = one_euro_trace(hand, states, FPS, options)
    period = 1.0 / FPS

    def points(q):
        return keypoints(hand, forward_kinematics(hand, q))[1][0]

    expected, velocity, speeds = [states[0].copy()], 0.0, [0.0]
    for z in states[1:]:
        velocity = (_alpha(0.2, period) * (points(z) - points(expected[-1])) / period
                    + (1 - _alpha(0.2, period)) * velocity)
        speeds.append(np.sqrt(np.mean(np.sum(velocity ** 2, axis=-1))))
        cutoff = 0.2 + 0.5 * max(speeds[-1] - 5.0, 0.0)
        x = expected[-1].copy()
        x[9] += _alpha(cutoff, period) * (z[9] - x[9])
        expected.append(x)
    np.testing.assert_allclose(trace.states, expected, atol=1e-12)
    np.testing.assert_allclose(trace.speed_mm_s, speeds, atol=1e-9)
    assert np.isinf(trace.cutoff_hz[0]) and trace.cutoff_hz[1:].max() > 1.0
    published = one_euro_filter(hand, states, FPS, replace(options, deadband_mm_s=0.0))
    assert np.abs(published[:, 9] - trace.states[:, 9]).max() > 1e-3


def test_one_cutoff_moves_every_component_by_the_same_fraction(hand):
    """Palm pose and joints share the cutoff: after one frame, each component of the
    output's step is the same fraction of the measurement's (a per-component filter, as
    the published one, would give each its own)."""
    rng = np.random.default_rng(6)
    start = build_scenario("whole-hand", n_frames=10).states[0]
    step = rng.normal(0.0, 1.0, hand.n_v) * tangent_sigma(hand, 0.05, 5.0, 0.1)
    states = np.stack([start, integrate(hand, start, step)])
    out = one_euro_filter(hand, states, FPS)
    fraction = difference(hand, states[0], out[1]) / step
    np.testing.assert_allclose(fraction, fraction[0], rtol=1e-6)
    assert 0.0 < fraction[0] < 1.0


def test_dead_band_keeps_slow_noise_at_the_resting_cutoff(hand):
    """Noise whose smoothed speed stays under the dead band is filtered as with beta 0."""
    rng = np.random.default_rng(5)
    states = np.repeat(hand.neutral()[None], 30, axis=0)
    states[:, 9] = 0.5 + rng.normal(0.0, 0.002, 30)
    calm = OneEuroOptions(min_cutoff_hz=0.2, beta_per_mm_s=0.0, deadband_mm_s=0.0)
    banded = OneEuroOptions(min_cutoff_hz=0.2, beta_per_mm_s=5.0, deadband_mm_s=50.0)
    np.testing.assert_allclose(one_euro_filter(hand, states, FPS, banded)[:, 9],
                               one_euro_filter(hand, states, FPS, calm)[:, 9], atol=1e-12)


def test_bad_arguments(hand):
    with pytest.raises(StateError, match="min_cutoff_hz"):
        OneEuroOptions(min_cutoff_hz=0.0)
    with pytest.raises(StateError, match="deadband_mm_s"):
        OneEuroOptions(deadband_mm_s=-1.0)
    with pytest.raises(StateError, match="fps"):
        one_euro_filter(hand, hand.neutral()[None], 0.0)
    with pytest.raises(StateError, match="shape"):
        one_euro_filter(hand, hand.neutral(), FPS)
