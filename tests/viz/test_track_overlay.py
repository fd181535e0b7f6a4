"""The overlay frame of ``digiteyes track``: one panel per camera, side by side, each drawn
by the drawer registered for the result's details type."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.features.measure import measure_features
from digiteyes.kinematics import forward_kinematics
from digiteyes.trackers import FeatureDetails, TrackResult
from digiteyes.viz.model_view import draw_wireframe
from digiteyes.viz.overlay import draw_features, to_rgb
from digiteyes.viz.track_overlay import drawer_for, overlay_image, register_overlay


def _result(q, details) -> TrackResult:
    return TrackResult(state=q, cost=0.0, residual_rms_px=0.0, lost=False, loss_reason="",
                       iterations=0, details=details)


def _scene(stick):
    q = stick.neutral()
    q[4:7] = [-30.0, 0.0, 100.0]
    kin = forward_kinematics(stick, q)
    cameras, images, measurements = [], [], []
    for name, (width, height) in (("a", (161, 121)), ("b", (100, 90))):
        K = np.array([[1.0, 0.0, width / 2], [0.0, 1.0, height / 2], [0.0, 0.0, 1.0]])
        camera = Camera.create(name, K, width, height, np.eye(4), projection="orthographic")
        image = np.random.default_rng(0).integers(0, 60, (height, width), dtype=np.uint8)
        cameras.append(camera)
        images.append(image)
        measurements.append(measure_features(image, camera, stick, kin))
    return q, cameras, images, measurements


def test_feature_panels_side_by_side_padded_to_even_size(stick):
    q, cameras, images, measurements = _scene(stick)
    details = FeatureDetails(measurements, [None, None], np.zeros(0), 0, 0, 0, None)
    tiled = overlay_image(images, _result(q, details), Rig(tuple(cameras)), stick)
    assert tiled.shape == (122, 262, 3) and tiled.dtype == np.uint8
    for left, image, camera, meas in zip((0, 161), images, cameras, measurements,
                                         strict=True):
        panel = draw_features(image, meas, camera)
        h, w = image.shape
        assert np.array_equal(tiled[:h, left:left + w], panel)
    assert not tiled[121].any() and not tiled[90:, 161:].any() and not tiled[:, 261].any()


def test_unknown_details_get_the_projected_model(stick):
    q, cameras, images, _ = _scene(stick)
    tiled = overlay_image(images, _result(q, object()), Rig(tuple(cameras)), stick)
    panel = draw_wireframe(stick, q, cameras[0], to_rgb(images[0]))
    assert np.array_equal(tiled[:121, :161], panel)
    assert not np.array_equal(panel, to_rgb(images[0]))  # the model was drawn


def test_registered_drawer_is_used_for_its_type_and_subtypes(stick):
    @dataclass
    class Marks:
        value: int

    class MoreMarks(Marks):
        pass

    def draw(image, camera_index, camera, result, model):
        out = to_rgb(image).copy()
        out[:] = (result.details.value, camera_index, 0)
        return out

    register_overlay(Marks, draw)
    assert drawer_for(MoreMarks(1)) is draw
    q, cameras, images, _ = _scene(stick)
    tiled = overlay_image(images, _result(q, MoreMarks(7)), Rig(tuple(cameras)), stick)
    assert (tiled[0, 0] == (7, 0, 0)).all() and (tiled[0, 161] == (7, 1, 0)).all()
