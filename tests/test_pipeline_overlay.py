"""The overlay frame of ``digiteyes track``: one panel per camera, side by side."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.features.measure import measure_features
from digiteyes.kinematics import forward_kinematics
from digiteyes.pipeline import overlay_image
from digiteyes.viz.overlay import draw_features


def test_panels_side_by_side_padded_to_even_size(stick):
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
    result = SimpleNamespace(measurements=measurements, residual_layouts=[None, None])
    tiled = overlay_image(images, result, Rig(tuple(cameras)))
    assert tiled.shape == (122, 262, 3) and tiled.dtype == np.uint8
    for left, image, camera, meas in zip((0, 161), images, cameras, measurements,
                                         strict=True):
        panel = draw_features(image, meas, camera)
        h, w = image.shape
        assert np.array_equal(tiled[:h, left:left + w], panel)
    assert not tiled[121].any() and not tiled[90:, 161:].any() and not tiled[:, 261].any()
