"""1D edge detection: derivative response, signed peaks, subpixel positions."""

from __future__ import annotations

import numpy as np
from scipy.special import erf

from digiteyes.features.edges import edge_response, find_edges

OFFSETS = np.arange(-20.0, 21.0)


def step_profile(x0: float, height: float = 100.0, blur: float = 0.0, rising: bool = True,
                 base: float = 20.0) -> np.ndarray:
    """Pixel-integrated step edge at ``x0`` on the sample grid OFFSETS (optionally a
    Gaussian-blurred one): sample j covers [o_j - 0.5, o_j + 0.5]."""
    def integral(x):  # integral of the unit step (blurred) from -inf to x, minus clipping
        if blur == 0.0:
            return np.maximum(x, 0.0)
        s = blur
        return x * 0.5 * (1 + erf(x / (s * np.sqrt(2)))) + s / np.sqrt(2 * np.pi) * np.exp(
            -x**2 / (2 * s * s))
    frac = integral(OFFSETS + 0.5 - x0) - integral(OFFSETS - 0.5 - x0)
    return base + height * (frac if rising else 1.0 - frac)


def run(profiles, centre, signs, half=6.0, min_contrast=8.0, inside=None):
    profiles = np.atleast_2d(profiles)
    if inside is None:
        inside = np.ones(profiles.shape, dtype=bool)
    found = find_edges(profiles, inside, np.atleast_2d(centre), np.asarray(signs, float),
                       OFFSETS, half, min_contrast)
    return found.position, found.height


def test_response_of_a_step_is_its_height():
    e = edge_response(step_profile(0.0, height=73.0))
    assert np.isclose(e.max(), 73.0)
    assert np.all(e[:2] == 0) and np.all(e[-2:] == 0)


def test_subpixel_positions_of_sharp_and_blurred_steps():
    rng = np.random.default_rng(0)
    for blur in (0.0, 0.6, 1.2):
        x0 = rng.uniform(-3, 3, size=40)
        profiles = np.array([step_profile(x, blur=blur) for x in x0])
        position, height = run(profiles, np.zeros((40, 1)), [1.0])
        np.testing.assert_allclose(position[:, 0], x0, atol=0.03)
        assert (height[:, 0] > 50).all()


def test_sign_selects_rising_or_falling_edges():
    profile = step_profile(-4.3) + step_profile(3.6, rising=False) - 120.0  # a bright bar
    position, _ = run(profile, [[-4.0, 4.0]], [1.0, -1.0])
    np.testing.assert_allclose(position[0], [-4.3, 3.6], atol=0.03)
    wrong, height = run(profile, [[-4.0, 4.0]], [-1.0, 1.0])
    assert np.isnan(wrong).all() and (height == 0).all()


def test_min_contrast_and_skipped_searches():
    weak = step_profile(0.4, height=5.0)
    assert np.isnan(run(weak, [[0.0]], [1.0], min_contrast=8.0)[0]).all()
    assert np.isfinite(run(weak, [[0.0]], [1.0], min_contrast=4.0)[0]).all()
    assert np.isnan(run(step_profile(0.0), [[np.nan]], [1.0])[0]).all()


def test_strongest_peak_wins_and_flanks_are_not_edges():
    two = step_profile(-3.0, height=30.0) + step_profile(2.2, height=90.0)
    position, height = run(two, [[0.0]], [1.0], half=6.0)
    assert abs(position[0, 0] - 2.2) < 0.03 and abs(height[0, 0] - 90.0) < 1.0
    # A strong edge just outside the range: its flank inside the range is no edge.
    outside = step_profile(7.0, height=200.0, blur=1.5)
    assert np.isnan(run(outside, [[0.0]], [1.0], half=5.0)[0]).all()


def test_levels_beside_the_edge_and_window_mean():
    profile = step_profile(0.0, height=100.0, base=20.0)
    found = find_edges(profile[None], np.ones((1, len(OFFSETS)), bool), np.array([[0.0]]),
                       np.array([1.0]), OFFSETS, 6.0, 8.0, side_px=3.0)
    assert np.isclose(found.before[0, 0], 20.0) and np.isclose(found.after[0, 0], 120.0)
    window = np.abs(OFFSETS) <= 6.0
    assert np.isclose(found.window_mean[0, 0], profile[window].mean())


def test_samples_outside_the_image_are_ignored():
    profile = step_profile(1.0)
    inside = np.ones((1, len(OFFSETS)), dtype=bool)
    inside[0, OFFSETS > -1] = False
    assert np.isnan(run(profile, [[0.0]], [1.0], inside=inside)[0]).all()
