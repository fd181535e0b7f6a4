"""Feature measurement on images of the whole hand drawn by the renderer (perspective
camera, shaded capsules, cloth backdrop, sensor noise)."""

from __future__ import annotations

import numpy as np

from digiteyes.features import feature_residuals, measure_features
from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.synth import RenderOptions, render_views


def rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2)))


def test_residuals_at_the_true_state_are_small(scene):
    model, q, camera = scene
    image = render_views(model, q, [camera], RenderOptions(noise_sigma=2.0, supersample=3),
                         rng=0)[0].image
    kin = forward_kinematics(model, q)
    meas = measure_features(image, camera, model, kin)
    assert meas.link_valid.all() and meas.tip_valid.all()
    r, _, _ = feature_residuals(meas, camera, kin)
    assert rms(r) < 1.5


def test_flat_shading_leaves_only_sampling_error(scene):
    """Without shading the silhouette is a pure step: the perspective contour model and
    the capsule tips must then agree with the renderer to a small fraction of a pixel
    (with shading, the intensity ramp inside the silhouette moves the edges by ~0.3 px)."""
    model, q, camera = scene
    image = render_views(model, q, [camera], RenderOptions(ambient=1.0, supersample=4),
                         rng=0)[0].image
    kin = forward_kinematics(model, q)
    meas = measure_features(image, camera, model, kin)
    assert meas.link_valid.all() and meas.tip_valid.all()
    r, _, _ = feature_residuals(meas, camera, kin)
    assert rms(r) < 0.15


def test_measurement_from_a_wrong_prediction_finds_the_true_features(scene):
    model, q, camera = scene
    image = render_views(model, q, [camera], RenderOptions(noise_sigma=2.0, supersample=3),
                         rng=1)[0].image
    rng = np.random.default_rng(5)
    step = np.zeros(model.n_v)
    step[3:6] = rng.normal(0.0, 2.0, 3)  # palm translation, mm
    step[6:] = rng.normal(0.0, np.radians(3.0), model.n_v - 6)  # joint angles
    guess = forward_kinematics(model, integrate(model, q, step))
    meas = measure_features(image, camera, model, guess)
    assert meas.link_valid.sum() >= 14 and meas.tip_valid.sum() >= 4
    r_guess, _, _ = feature_residuals(meas, camera, guess)
    r_true, _, _ = feature_residuals(meas, camera, forward_kinematics(model, q))
    assert rms(r_true) < 1.5 < rms(r_guess)
