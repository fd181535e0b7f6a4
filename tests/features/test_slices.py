"""Slice geometry and sampling: image preparation, bilinear lookup, silhouette tangents."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from digiteyes.camera import Camera
from digiteyes.errors import CameraError
from digiteyes.features.slices import (
    cylinder_tangent_points,
    prepare_image,
    sample_profiles,
    sphere_tangent_points,
)


def test_prepare_image_gray_rgb_and_float():
    rng = np.random.default_rng(0)
    gray8 = rng.integers(0, 256, (12, 17), dtype=np.uint8)
    assert prepare_image(gray8) is gray8  # read as is: no copy, no conversion
    strided = prepare_image(gray8[:, ::2])
    assert strided.dtype == np.uint8 and strided.flags.c_contiguous
    np.testing.assert_array_equal(strided, gray8[:, ::2])
    np.testing.assert_array_equal(prepare_image(gray8.astype(np.int16)), gray8)
    assert prepare_image(gray8.astype(np.int16)).dtype == np.float32
    rgb = rng.integers(0, 256, (12, 17, 3), dtype=np.uint8)
    np.testing.assert_array_equal(prepare_image(rgb), cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    ready = np.ascontiguousarray(gray8, dtype=np.float32)
    assert prepare_image(ready) is ready
    np.testing.assert_allclose(prepare_image(rgb.astype(float)),
                               cv2.cvtColor(rgb.astype(np.float32), cv2.COLOR_RGB2GRAY), atol=1e-3)
    with pytest.raises(CameraError, match="grey or"):
        prepare_image(np.zeros((4, 4, 2)))


def test_sample_profiles_is_bilinear_and_nan_outside():
    rng = np.random.default_rng(1)
    gray = cv2.GaussianBlur(rng.uniform(0, 255, (60, 80)).astype(np.float32), (0, 0), 2.0)
    origins = rng.uniform([-5, -5], [85, 65], size=(7, 3, 2))
    angles = rng.uniform(0, 2 * np.pi, size=(7, 3))
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    offsets = np.arange(-12.0, 12.5, 0.5)
    profiles, inside = sample_profiles(gray, origins, directions, offsets)
    assert profiles.shape == inside.shape == (7, 3, len(offsets))
    xy = origins[..., None, :] + offsets[:, None] * directions[..., None, :]
    x, y = xy[..., 0], xy[..., 1]
    clearly_in = (x >= 0.05) & (x <= 78.95) & (y >= 0.05) & (y <= 58.95)
    clearly_out = (x < -0.05) | (x > 79.05) | (y < -0.05) | (y > 59.05)
    assert clearly_in.sum() > 300 and clearly_out.sum() > 50
    assert inside[clearly_in].all() and not inside[clearly_out].any()
    np.testing.assert_array_equal(np.isnan(profiles), ~inside)
    exact = map_coordinates(gray.astype(float), [y[inside], x[inside]], order=1)
    # OpenCV interpolates at 1/32 px positions: errors stay below |gradient| / 64.
    np.testing.assert_allclose(profiles[inside], exact, atol=0.05)


@pytest.fixture(params=["perspective", "orthographic", "scaled-orthographic"])
def camera(request) -> Camera:
    return Camera.look_at("c", eye=[80.0, -300.0, 250.0], target=[0.0, 0.0, 0.0],
                          projection=request.param)


def test_cylinder_tangent_points_touch_the_viewing_rays(camera):
    rng = np.random.default_rng(2)
    p = rng.uniform(-40, 40, size=(20, 3))
    axis = rng.normal(size=(20, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    radius = rng.uniform(5, 15, size=20)
    X = cylinder_tangent_points(camera, p, axis, radius)  # (20, 2, 3)
    radial = X - p[:, None]
    assert np.allclose(np.sum(radial * axis[:, None], axis=-1), 0.0, atol=1e-9)
    assert np.allclose(np.linalg.norm(radial, axis=-1), radius[:, None])
    if camera.projection == "perspective":
        view = X - camera.centre_world
    else:
        view = np.broadcast_to(camera.T_cam_world[2, :3], X.shape)
    # The viewing ray grazes the surface: it is perpendicular to the surface normal.
    assert np.allclose(np.sum(view * radial, axis=-1), 0.0, atol=1e-8)
    # The two points project on opposite sides of the projected axis.
    w_p, w_axis = camera.project(p), camera.project(p + axis)
    d = w_axis - w_p
    normal = np.stack([-d[:, 1], d[:, 0]], axis=-1)
    side = np.sum((camera.project(X) - w_p[:, None]) * normal[:, None], axis=-1)
    assert (side[:, 0] * side[:, 1] < 0).all()


def test_sphere_tangent_points_lie_on_the_silhouette(camera):
    rng = np.random.default_rng(3)
    c = rng.uniform(-40, 40, size=(10, 3))
    e = rng.normal(size=(10, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    r = rng.uniform(5, 10, size=10)
    X, sin_view = sphere_tangent_points(camera, c, e, r)
    radial = X - c[:, None]
    assert np.allclose(np.linalg.norm(radial, axis=-1), r[:, None])
    if camera.projection == "perspective":
        view = X - camera.centre_world
        v = (c - camera.centre_world) / np.linalg.norm(c - camera.centre_world, axis=1)[:, None]
    else:
        view = np.broadcast_to(camera.T_cam_world[2, :3], X.shape)
        v = view[:, 0]
    assert np.allclose(np.sum(view * radial, axis=-1), 0.0, atol=1e-8)
    np.testing.assert_allclose(sin_view, np.linalg.norm(np.cross(v, e), axis=1))
    # The "along" point lies on the side of e, the "across" point beside it.
    e_perp = e - np.sum(e * v, axis=1, keepdims=True) * v
    assert (np.sum(radial[:, 0] * e_perp, axis=-1) > 0).all()
    assert np.allclose(np.sum(radial[:, 1] * e_perp, axis=-1), 0.0, atol=1e-8)
