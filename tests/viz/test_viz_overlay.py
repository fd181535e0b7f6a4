"""Overlay drawing of feature measurements (report Fig. 4 style)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.errors import CameraError
from digiteyes.features import feature_residuals, project_features
from digiteyes.features.measure import FeatureMeasurement, measure_features
from digiteyes.kinematics import forward_kinematics
from digiteyes.viz.overlay import EDGE_IN, MEASURED, RESIDUAL, TRACKER, draw_features


@pytest.fixture(scope="module")
def scene(stick):
    model = stick
    K = np.array([[1.0, 0.0, 79.5], [0.0, 1.0, 59.5], [0.0, 0.0, 1.0]])
    camera = Camera.create("flat", K, 160, 120, np.eye(4), projection="orthographic")
    q = model.neutral()
    q[4:7] = [-30.0, 0.0, 100.0]
    image = np.full((120, 160), 30, np.uint8)
    image[52:68, 50:110] = 200  # the stick's silhouette (axis y = 59.5, x from 49.5)
    q_guess = q.copy()
    q_guess[5] = 3.0
    meas = measure_features(image, camera, model, forward_kinematics(model, q_guess))
    return model, camera, image, q, q_guess, meas


def colour_present(image: np.ndarray, colour) -> bool:
    return bool(np.all(np.abs(image.astype(int) - colour) <= 40, axis=-1).any())


def test_draws_trackers_edges_lines_and_residuals(scene):
    _, camera, image, _, _, meas = scene
    assert isinstance(meas, FeatureMeasurement) and meas.link_valid[0]
    out = draw_features(image, meas, camera)
    assert out.shape == (120, 160, 3) and out.dtype == np.uint8
    for colour in (TRACKER, EDGE_IN, MEASURED, RESIDUAL):
        assert colour_present(out, colour)
    untouched = np.all(out == image[..., None], axis=-1)
    assert 0.5 < untouched.mean() < 0.99


def test_scale_and_residual_layout(scene):
    model, camera, image, q, _, meas = scene
    kin = forward_kinematics(model, q)
    _, _, layout = feature_residuals(meas, camera, kin)
    out = draw_features(image.astype(float) / 255.0, meas, camera, layout, scale=3,
                        show_slices=False)
    assert out.shape == (360, 480, 3)
    exact = project_features(camera, model, kin)
    assert draw_features(np.repeat(image[..., None], 3, axis=2), exact).shape == (120, 160, 3)


def test_errors(scene):
    _, camera, image, _, _, meas = scene
    with pytest.raises(CameraError, match="expects 160x120"):
        draw_features(image[:-2], meas, camera)
    with pytest.raises(ValueError, match="scale"):
        draw_features(image, meas, scale=0)
