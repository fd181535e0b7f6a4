"""The shading model fitted from an image, its predicted image, and the edge bias it
predicts, against the renderer's own lighting and images."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.errors import StateError
from digiteyes.features import FeatureOptions, feature_residuals, measure_features
from digiteyes.features.appearance import ShadingModel, edge_bias, fit_shading
from digiteyes.kinematics import forward_kinematics
from digiteyes.synth import RenderOptions, render_views

LIGHTING = RenderOptions(background="uniform", light_dir=(-0.5, 0.3, 1.0), ambient=0.3,
                         skin_albedo=0.8, background_level=0.1)


def true_shading(options: RenderOptions) -> ShadingModel:
    """The shading model the renderer draws with (grey levels 0-255)."""
    light = np.asarray(options.light_dir, dtype=float)
    skin = 255.0 * options.skin_albedo
    return ShadingModel(light / np.linalg.norm(light), skin * options.ambient,
                        skin * (1.0 - options.ambient), 255.0 * options.background_level)


def width_rows(meas, camera, kin) -> tuple[np.ndarray, object]:
    r, _, layout = feature_residuals(meas, camera, kin, jacobian=False, width_weight=1.0)
    return r, layout


def fit_rendered(scene, options: RenderOptions, seed: int
                 ) -> tuple[ShadingModel, ShadingModel, float]:
    """The shading model fitted on a rendering of ``scene``, the true one, and the angle
    between their lights (degrees)."""
    model, q, camera = scene
    image = render_views(model, q, [camera], options, rng=seed)[0].image
    fitted = fit_shading([image], Rig((camera,)), model, q)
    truth = true_shading(options)
    angle = np.degrees(np.arccos(np.clip(fitted.light_world @ truth.light_world, -1, 1)))
    return fitted, truth, float(angle)


def test_fit_recovers_the_renderers_lighting(scene):
    model, q, camera = scene
    fitted, truth, angle = fit_rendered(scene, LIGHTING, 0)
    assert angle < 0.5
    assert fitted.ambient_level == pytest.approx(truth.ambient_level, abs=1.0)
    assert fitted.diffuse_level == pytest.approx(truth.diffuse_level, abs=1.0)
    assert fitted.background_level == pytest.approx(truth.background_level, abs=0.5)
    hidden = render_views(model, q, [camera], LIGHTING)[0].labels >= 0
    backdrop = fitted.backdrops[camera.name]
    assert np.abs(backdrop[hidden] - truth.background_level).max() <= 1.0


def test_fit_with_sensor_noise_and_a_cloth_backdrop(scene):
    fitted, truth, angle = fit_rendered(scene, RenderOptions(noise_sigma=3.0,
                                                             background="black"), 1)
    assert angle < 2.0
    assert fitted.diffuse_level == pytest.approx(truth.diffuse_level, rel=0.03)


def test_predicted_image_is_the_renderers(scene):
    model, q, camera = scene
    rendered = render_views(model, q, [camera], LIGHTING)[0].image
    predicted = true_shading(LIGHTING).render(forward_kinematics(model, q), camera)
    assert predicted.shape == rendered.shape and predicted.dtype == np.float32
    assert np.abs(predicted - rendered).max() <= 0.5 + 1e-3  # the renderer rounds to uint8


def test_predicted_image_through_lens_distortion(scene):
    """With a distorted camera the drawing goes through the renderer's warp: away from the
    silhouette (where the renderer blends coverage and the drawing does not) the two agree
    to the renderer's rounding."""
    model, q, camera = scene
    distorted = Camera.create("barrel", camera.K, camera.width, camera.height,
                              camera.T_cam_world, dist=[-0.25, 0.08, 0.0, 0.0, 0.0])
    rendered = render_views(model, q, [distorted], LIGHTING)[0]
    predicted = true_shading(LIGHTING).render(forward_kinematics(model, q), distorted)
    hit = (rendered.labels >= 0).astype(np.uint8)
    kernel = np.ones((5, 5), np.uint8)
    away = (cv2.erode(hit, kernel) == hit) & (cv2.dilate(hit, kernel) == hit)
    assert hit.sum() > 5000 and away.mean() > 0.9
    assert np.abs(predicted - rendered.image)[away].max() <= 0.5 + 1e-3


def test_edge_bias_cancels_the_shading_bias(scene):
    """At the true state the raw width rows of a shaded image are biased inwards; minus the
    predicted bias they are near zero, and every other row shrinks too."""
    model, q, camera = scene
    image = render_views(model, q, [camera], LIGHTING)[0].image
    kin = forward_kinematics(model, q)
    meas = measure_features(image, camera, model, kin)
    r, layout = width_rows(meas, camera, kin)
    bias = edge_bias(true_shading(LIGHTING), model, q, camera, FeatureOptions(),
                     width_weight=1.0)
    corrected = r - bias.of_rows(layout.kind_code, layout.link_index, layout.component)
    widths = layout.rows("width")
    assert np.mean(r[widths]) > 0.15  # predicted minus measured: edges measured inwards
    assert np.abs(corrected[widths]).max() < 0.05
    assert np.sqrt(np.mean(corrected**2)) < 0.2 * np.sqrt(np.mean(r**2))


def test_fit_needs_the_model_in_view(scene):
    model, q, camera = scene
    image = render_views(model, q, [camera], LIGHTING)[0].image
    away = q.copy()
    away[4] += 5000.0
    with pytest.raises(StateError, match="interior pixels"):
        fit_shading([image], Rig((camera,)), model, away)


def test_edge_bias_checks_the_state(scene):
    model, q, camera = scene
    with pytest.raises(StateError, match="one state"):
        edge_bias(true_shading(LIGHTING), model, q[:5], camera, FeatureOptions())


@pytest.mark.parametrize(("background", "low", "high"), [("black", 1.5, 3.0),
                                                         ("clutter", 8.0, np.inf)])
def test_backdrop_texture_tells_a_cloth_from_clutter(scene, background, low, high):
    """On the cloth the texture is the sensor noise (2 grey levels); clutter has edges."""
    fitted, _, _ = fit_rendered(scene, RenderOptions(background=background, noise_sigma=2.0),
                                2)
    assert low < fitted.backdrop_texture < high
