"""Calibration recovers the camera that rendered synthetic chessboard and ChArUco views."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.camera.calibration import (
    CharucoBoard,
    Chessboard,
    board_points,
    calibrate,
    find_chessboard,
    render_charuco,
    render_chessboard,
)
from digiteyes.camera.default import default_camera
from digiteyes.errors import CameraError
from digiteyes.kinematics.rotations import matrix_from_quaternion, quaternion_from_rotvec

PATTERN = (7, 5)
SQUARE = 25.0
BOARD = Chessboard(PATTERN, SQUARE)
CHARUCO = CharucoBoard((8, 6), SQUARE, 18.0)


def board_poses(n: int, seed: int) -> list[np.ndarray]:
    """Board poses 350-500 mm in front of the camera, tilted by up to 30 degrees."""
    rng = np.random.default_rng(seed)
    poses = []
    for _ in range(n):
        T = np.eye(4)
        T[:3, :3] = matrix_from_quaternion(quaternion_from_rotvec(rng.uniform(-0.5, 0.5, 3)))
        centre = np.array([PATTERN[0] - 1, PATTERN[1] - 1, 0]) * SQUARE / 2
        T[:3, 3] = np.array([rng.uniform(-40, 40), rng.uniform(-30, 30),
                             rng.uniform(350, 500)]) - T[:3, :3] @ centre
        poses.append(T)
    return poses


@pytest.fixture(scope="module")
def camera() -> Camera:
    K = np.array([[700.0, 0, 322.0], [0, 700.0, 236.0], [0, 0, 1]])
    return Camera.create("truth", K, 640, 480)


def test_rendered_corners_are_found_where_they_project(camera):
    T = board_poses(1, 0)[0]
    image = render_chessboard(camera, T, PATTERN, SQUARE)
    corners = find_chessboard(image, PATTERN)
    truth = camera.project((board_points(PATTERN, SQUARE) @ T[:3, :3].T) + T[:3, 3])
    assert corners is not None
    assert np.abs(corners - truth).max() < 0.5


def test_mono_calibration_recovers_K(camera):
    images = [render_chessboard(camera, T, PATTERN, SQUARE) for T in board_poses(8, 1)]
    result = calibrate(images, BOARD)
    K = result.rig[0].K
    assert result.rms_px["cam0"] < 0.3
    np.testing.assert_allclose(K[[0, 1], [0, 1]], [700.0, 700.0], rtol=0.01)
    np.testing.assert_allclose(K[:2, 2], [322.0, 236.0], atol=4.0)


def test_stereo_calibration_recovers_baseline(camera):
    T_right_left = np.eye(4)
    T_right_left[0, 3] = -120.0  # right camera 120 mm to the left camera's right
    right = Camera.create("right", camera.K, 640, 480, T_right_left)
    poses = board_poses(8, 2)
    left_images = [render_chessboard(camera, T, PATTERN, SQUARE) for T in poses]
    right_images = [render_chessboard(right, T_right_left @ T, PATTERN, SQUARE) for T in poses]
    result = calibrate(left_images, BOARD, right_images)
    T = result.rig[1].T_cam_world
    np.testing.assert_allclose(T[:3, 3], [-120.0, 0.0, 0.0], atol=2.0)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=0.01)


def test_too_few_views_is_an_error(camera):
    blank = np.full((480, 640), 128, dtype=np.uint8)
    with pytest.raises(CameraError, match="found in 0 of 2"):
        calibrate([blank, blank], BOARD)


def test_charuco_corners_are_found_where_they_project(camera):
    T = board_poses(1, 3)[0]
    found = CHARUCO.detect(render_charuco(camera, T, CHARUCO))
    assert found is not None
    ids, pixels = found
    truth = camera.project((CHARUCO.points()[ids] @ T[:3, :3].T) + T[:3, 3])
    assert len(ids) >= 30 and np.abs(pixels - truth).max() < 0.5


def test_charuco_stereo_calibration_with_part_of_the_board_out_of_view(camera):
    """The right camera, 120 mm aside, sees only part of the board in most views (24 to
    32 of its 35 corners): the named corners both saw still calibrate the pair."""
    T_right_left = np.eye(4)
    T_right_left[0, 3] = -120.0
    right = Camera.create("right", camera.K, 640, 480, T_right_left)
    poses = board_poses(8, 4)
    left_images = [render_charuco(camera, T, CHARUCO) for T in poses]
    right_images = [render_charuco(right, T_right_left @ T, CHARUCO) for T in poses]
    seen = [len(CHARUCO.detect(image)[0]) for image in right_images]
    assert sum(n < len(CHARUCO.points()) for n in seen) >= 3
    result = calibrate(left_images, CHARUCO, right_images)
    np.testing.assert_allclose(result.rig[0].K[[0, 1], [0, 1]], [700.0, 700.0], rtol=0.01)
    t = result.rig[1].T_cam_world[:3, 3]
    assert np.linalg.norm(t) == pytest.approx(120.0, abs=1.5)  # the baseline
    np.testing.assert_allclose(t, [-120.0, 0.0, 0.0], atol=3.0)  # z, along the axes: 2.2 mm
    np.testing.assert_allclose(result.rig[1].T_cam_world[:3, :3], np.eye(3), atol=0.01)
    assert result.rms_px["stereo"] < 0.5


def test_charuco_board_checks_its_settings():
    with pytest.raises(CameraError, match="smaller than the squares"):
        CharucoBoard((5, 5), 20.0, 25.0)
    with pytest.raises(CameraError, match="unknown ArUco dictionary"):
        CharucoBoard((5, 5), 20.0, 15.0, "DICT_NOPE")


def test_default_camera_from_field_of_view():
    cam = default_camera(1280, 720, 60.0)
    assert cam.K[0, 0] == pytest.approx(640 / np.tan(np.radians(30)))
    assert tuple(cam.K[:2, 2]) == (639.5, 359.5)
    with pytest.raises(CameraError, match="field of view"):
        default_camera(640, 480, 0.5)
