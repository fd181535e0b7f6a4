"""Robust line fits and bisectors."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.features.lines import bisector, fit_lines


def noisy_lines(rng, n_sets: int, n_points: int, sigma: float):
    angle = rng.uniform(0, np.pi, n_sets)
    normal = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    rho = rng.uniform(-50, 50, n_sets)
    t = rng.uniform(-30, 30, (n_sets, n_points))
    along = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    points = (rho[:, None, None] * normal[:, None] + t[..., None] * along[:, None]
              + rng.normal(0, sigma, (n_sets, n_points))[..., None] * normal[:, None])
    return points, normal, rho


def svd_line(points):
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre)
    normal = vt[-1]
    return np.append(normal, normal @ centre)


def test_plain_fit_is_total_least_squares():
    rng = np.random.default_rng(0)
    points, normal, _ = noisy_lines(rng, 25, 9, sigma=0.7)
    fit = fit_lines(points, np.ones((25, 9), bool), robust="none", normal=normal)
    for b in range(25):
        expected = svd_line(points[b])
        expected *= np.sign(expected[:2] @ normal[b])
        np.testing.assert_allclose(fit.line[b], expected, atol=1e-9)
    assert (fit.count == 9).all() and fit.inlier.all()
    np.testing.assert_allclose(np.linalg.norm(fit.line[:, :2], axis=1), 1.0)
    r = np.abs(np.einsum("bpi,bi->bp", points, fit.line[:, :2]) - fit.line[:, 2:])
    np.testing.assert_allclose(fit.rms, np.sqrt((r**2).mean(axis=1)))


def _with_outliers(seed: int, central: bool):
    rng = np.random.default_rng(seed)
    points, normal, rho = noisy_lines(rng, 30, 10, sigma=0.1)
    truth = points - (np.einsum("bpi,bi->bp", points, normal) - rho[:, None])[..., None] \
        * normal[:, None]
    along = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    t = np.einsum("bpi,bi->bp", points, along)
    if central:  # the two points nearest the middle of each set become outliers
        worst = np.argsort(np.abs(t - np.median(t, axis=1, keepdims=True)), axis=1)[:, :2]
    else:  # the two points at one end: high leverage, they tilt a least-squares fit
        worst = np.argsort(t, axis=1)[:, -2:]
    np.put_along_axis(points, worst[..., None],
                      np.take_along_axis(points, worst[..., None], axis=1)
                      + 6.0 * normal[:, None], axis=1)
    return points, normal, truth, worst


def _worst_distance(truth, line):
    """Largest distance of the true line's points from the fitted lines."""
    return np.abs(np.einsum("bpi,bi->bp", truth, line[:, :2]) - line[:, 2:]).max(axis=1)


def test_tukey_fit_resists_clustered_outliers():
    points, normal, truth, worst = _with_outliers(1, central=False)
    mask = np.ones((30, 10), bool)
    plain = fit_lines(points, mask, robust="none", normal=normal)
    robust = fit_lines(points, mask, robust="tukey", normal=normal)
    assert (_worst_distance(truth, plain.line) > 0.5).all()
    assert _worst_distance(truth, robust.line).max() < 0.3
    assert not np.take_along_axis(robust.inlier, worst, axis=1).any()
    assert (robust.count == 8).all()


def test_huber_fit_damps_central_outliers():
    points, normal, truth, _ = _with_outliers(2, central=True)
    mask = np.ones((30, 10), bool)
    plain = _worst_distance(truth, fit_lines(points, mask, robust="none", normal=normal).line)
    huber = _worst_distance(truth, fit_lines(points, mask, robust="huber", normal=normal).line)
    assert (huber < plain / 3).all()


def test_masked_and_degenerate_sets():
    points = np.array([[[0.0, 0.0], [1.0, 1.0], [np.nan, np.nan], [2.0, 2.0]],
                       [[5.0, 5.0], [np.nan, np.nan], [np.nan, np.nan], [np.nan, np.nan]]])
    mask = np.isfinite(points[..., 0])
    fit = fit_lines(points, mask, normal=np.array([1.0, -1.0]))
    np.testing.assert_allclose(fit.line[0], [np.sqrt(0.5), -np.sqrt(0.5), 0.0], atol=1e-12)
    assert np.isnan(fit.line[1]).all() and fit.count[1] == 0 and not fit.inlier[1].any()
    with pytest.raises(ValueError, match="robust"):
        fit_lines(points, mask, robust="ransac")


def test_bisector_of_parallel_and_crossing_lines():
    a = np.array([0.0, 1.0, -3.0])  # y = -3
    b = np.array([0.0, 1.0, 5.0])  # y = 5
    np.testing.assert_allclose(bisector(a, b), [0.0, 1.0, 1.0])
    s = np.sin(0.2)
    c = np.array([-s, np.cos(0.2), 0.0])
    d = np.array([s, np.cos(0.2), 0.0])
    np.testing.assert_allclose(bisector(c, d), [0.0, 1.0, 0.0], atol=1e-12)
