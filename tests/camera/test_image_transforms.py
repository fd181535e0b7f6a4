"""Rigs for transformed images: a mirrored camera sees the reflected world in the flipped
image (checked against OpenCV's projection; mirroring twice is the identity), a resized
camera sees the resized image, and real_pixels maps both back."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.camera.mirror import (
    mirror_images,
    mirrored_camera,
    mirrored_rig,
    rig_for_hand,
    unmirror_pixels,
    unmirror_points,
)
from digiteyes.camera.working_size import resize_images, working_rig


def a_camera(dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> Camera:
    camera = Camera.look_at("c", eye=(120.0, -700.0, 260.0), target=(10.0, 0.0, 40.0),
                            width=640, height=480, focal_px=760.0)
    K = np.array(camera.K)
    K[0, 2], K[1, 2] = 301.5, 252.25  # off centre, so the mirror moves it
    return Camera.create("c", K, 640, 480, camera.T_cam_world, np.array(dist))


def points(n=50, seed=0) -> np.ndarray:
    return np.random.default_rng(seed).uniform([-90, -90, -60], [90, 90, 120], (n, 3))


@pytest.mark.parametrize("dist", [(0, 0, 0, 0, 0), (-0.21, 0.08, 0.0012, -0.0017, -0.02)])
def test_the_mirrored_camera_sees_the_reflected_world_in_the_flipped_image(dist):
    camera = a_camera(dist)
    mirror = mirrored_camera(camera)
    world = points()
    reflected = world * [-1.0, 1.0, 1.0]
    uv = camera.project(world)
    np.testing.assert_allclose(mirror.project(reflected), unmirror_pixels(uv, 640), atol=1e-9)
    # OpenCV, given the mirrored camera's parameters, agrees (independent projection)
    R, t = mirror.T_cam_world[:3, :3], mirror.T_cam_world[:3, 3]
    theirs, _ = cv2.projectPoints(reflected, cv2.Rodrigues(R)[0], t, mirror.K, mirror.dist)
    np.testing.assert_allclose(theirs[:, 0], unmirror_pixels(uv, 640), atol=1e-6)
    np.testing.assert_allclose(mirror.to_camera(reflected),
                               unmirror_points(camera.to_camera(world)), atol=1e-9)


def test_a_flipped_pixel_is_the_same_scene_point():
    """Pixel centres at integers: column u of an image is column W - 1 - u of its flip."""
    image = np.arange(4 * 6).reshape(4, 6)
    flipped = mirror_images([image])[0]
    for u in range(6):
        assert flipped[2, int(unmirror_pixels(np.array([u, 2.0]), 6)[0])] == image[2, u]


def test_mirroring_twice_gives_the_rig_back():
    rig = Rig((a_camera((-0.2, 0.1, 0.001, 0.002, 0.0)),))
    once = mirrored_rig(rig)
    assert once.mirrored and not mirrored_rig(once).mirrored
    back = mirrored_rig(once)[0]
    np.testing.assert_array_equal(back.K, rig[0].K)
    np.testing.assert_array_equal(back.dist, rig[0].dist)
    np.testing.assert_array_equal(back.T_cam_world, rig[0].T_cam_world)
    assert rig_for_hand(rig, "right") is rig and rig_for_hand(rig, "left").mirrored
    with pytest.raises(ValueError, match="hand must be one of"):
        rig_for_hand(rig, "both")


def test_a_resized_camera_sees_the_resized_image_and_real_pixels_map_back():
    """Pixel centres at integers: a point's column u becomes s (u + 1/2) - 1/2 in an image
    resized by s; the rig's real_pixels undoes it, also after a mirror."""
    camera = a_camera((-0.21, 0.08, 0.0012, -0.0017, -0.02))
    world = points()
    real_uv = camera.project(world)
    work = working_rig(Rig((camera,)), max_side=480)
    assert (work[0].width, work[0].height) == (480, 360) and work.real_sizes == ((640, 480),)
    np.testing.assert_allclose(work[0].project(world), (real_uv + 0.5) * 0.75 - 0.5,
                               atol=1e-9)
    np.testing.assert_allclose(work.real_pixels(work[0].project(world), 0), real_uv,
                               atol=1e-9)
    both = mirrored_rig(work)
    reflected = world * [-1.0, 1.0, 1.0]
    np.testing.assert_allclose(both.real_pixels(both[0].project(reflected), 0), real_uv,
                               atol=1e-9)
    assert working_rig(Rig((camera,)), max_side=640) == Rig((camera,))  # nothing to do
    # OpenCV's resize puts an image's content where the resized camera projects it
    image = np.zeros((480, 640), np.float32)
    image[200:204, 300:304] = 1.0  # a block centred on (301.5, 201.5)
    small = resize_images([image], work)[0]
    v, u = np.unravel_index(np.argmax(small), small.shape)
    weights = small[v - 2:v + 3, u - 2:u + 3]
    grid_v, grid_u = np.mgrid[v - 2:v + 3, u - 2:u + 3]
    centre = np.array([(grid_u * weights).sum(), (grid_v * weights).sum()]) / weights.sum()
    np.testing.assert_allclose(centre, (np.array([301.5, 201.5]) + 0.5) * 0.75 - 0.5,
                               atol=0.05)
