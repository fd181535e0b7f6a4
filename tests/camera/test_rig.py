"""Camera rigs: validation, image checks, JSON rig files, OpenCV calibration files.

OpenCV files are written in the tests with ``cv2.FileStorage`` exactly as OpenCV's
calibration samples do; expected pixels come from ``cv2.projectPoints``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from digiteyes.camera import Camera, Rig, load_rig, save_rig
from digiteyes.errors import CameraError, DigitEyesError

K_LEFT = np.array([[822.8, 0.4, 318.5], [0.0, 819.1, 250.3], [0.0, 0.0, 1.0]])
DIST = np.array([-0.21, 0.08, 0.0012, -0.0007, -0.013])
RVEC = np.array([0.3, -0.2, 0.1])
TVEC = np.array([15.0, -40.0, 650.0])


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector, written out (not via OpenCV)."""
    angle = np.linalg.norm(rvec)
    k = rvec / angle
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * Kx + (1 - np.cos(angle)) * Kx @ Kx


def pose(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rodrigues(rvec)
    T[:3, 3] = tvec
    return T


def three_cameras() -> Rig:
    return Rig((
        Camera.create("left", K_LEFT, 640, 480, pose(RVEC, TVEC), DIST),
        Camera.create("top", np.array([[1.6, 0, 320], [0, 1.6, 240], [0, 0, 1.0]]),
                      640, 480, pose(np.array([2.0, 0.1, 0.0]), np.array([0, 0, 500.0])),
                      projection="orthographic"),
        Camera.create("side", np.array([[700, 0, 400], [0, 700, 300], [0, 0, 1.0]]), 800, 600,
                      pose(np.array([0.0, 1.2, 0.0]), np.array([5, 5, 700.0])),
                      projection="scaled-orthographic", depth_mm=700.0),
    ))


def sample_points(rng: np.random.Generator, n: int = 40) -> np.ndarray:
    """World points in front of every camera of :func:`three_cameras` (near the origin)."""
    return rng.uniform(-80.0, 80.0, size=(n, 3))


def write_opencv(path: Path, *, extrinsics: bool = True, skip: str | None = None) -> None:
    """An OpenCV calibration file as written by ``cv::FileStorage``."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    entries = {
        "image_width": 640,
        "image_height": 480,
        "camera_matrix": K_LEFT,
        "distortion_coefficients": DIST.reshape(1, 5),
    }
    if extrinsics:
        entries["rvec"] = RVEC.reshape(3, 1)
        entries["tvec"] = TVEC.reshape(3, 1)
    for key, value in entries.items():
        if key != skip:
            fs.write(key, value)
    fs.release()


def opencv_pixels(p: np.ndarray, T: np.ndarray, K: np.ndarray, dist) -> np.ndarray:
    rvec = cv2.Rodrigues(T[:3, :3])[0]
    return cv2.projectPoints(p, rvec, T[:3, 3], K, dist)[0][:, 0]


# ------------------------------------------------------------------ Rig object
def test_rig_is_an_ordered_sequence_of_cameras():
    rig = three_cameras()
    assert len(rig) == 3 and rig.names == ["left", "top", "side"]
    assert [c.name for c in rig] == rig.names and rig[1].name == "top"


def test_rig_rejects_duplicate_names_and_empty_rigs():
    cam = three_cameras()[0]
    with pytest.raises(CameraError, match=r"names in a rig must be unique.*'left', 'left'"):
        Rig((cam, cam))
    with pytest.raises(CameraError, match="at least one camera"):
        Rig(())


def test_check_images_accepts_one_image_of_the_right_size_per_camera():
    rig = three_cameras()
    rig.check_images([np.zeros((480, 640)), np.zeros((480, 640, 3), np.uint8),
                      np.zeros((600, 800))])


def test_check_images_rejects_wrong_count():
    rig = three_cameras()
    with pytest.raises(CameraError, match=r"3 camera\(s\) \(left, top, side\) but 2 image"):
        rig.check_images([np.zeros((480, 640))] * 2)


def test_check_images_rejects_wrong_size():
    rig = three_cameras()
    images = [np.zeros((480, 640)), np.zeros((640, 480)), np.zeros((600, 800))]
    with pytest.raises(CameraError, match="camera 'top' expects 640x480 images, got 480x640"):
        rig.check_images(images)


# ------------------------------------------------------------------ JSON rig files
def test_json_round_trip(tmp_path):
    rig = three_cameras()
    path = tmp_path / "rig.json"
    save_rig(rig, path)
    payload = json.loads(path.read_text())
    assert [c["name"] for c in payload["cameras"]] == rig.names
    loaded = load_rig(path)
    assert loaded.names == rig.names
    p = sample_points(np.random.default_rng(0))
    for a, b in zip(rig, loaded, strict=True):
        assert (a.width, a.height, a.projection, a.depth_mm) == \
            (b.width, b.height, b.projection, b.depth_mm)
        np.testing.assert_array_equal(a.K, b.K)
        np.testing.assert_array_equal(a.dist, b.dist)
        np.testing.assert_array_equal(a.T_cam_world, b.T_cam_world)
        np.testing.assert_array_equal(a.project(p), b.project(p))


def test_json_rvec_tvec_entry_matches_opencv(tmp_path):
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"cameras": [{
        "name": "left", "width": 640, "height": 480, "K": K_LEFT.tolist(),
        "dist": DIST.tolist(), "rvec": RVEC.tolist(), "tvec": [[v] for v in TVEC]}]}))
    cam = load_rig(path)[0]
    np.testing.assert_allclose(cam.T_cam_world, pose(RVEC, TVEC), atol=1e-12)
    assert cam.projection == "perspective"
    p = sample_points(np.random.default_rng(1))
    K0 = K_LEFT.copy()
    K0[0, 1] = 0.0  # OpenCV's model has no skew
    cam0 = Camera.create("noskew", K0, 640, 480, cam.T_cam_world, cam.dist)
    expected = cv2.projectPoints(p, RVEC, TVEC, K0, DIST)[0][:, 0]
    assert np.abs(cam0.project(p) - expected).max() < 1e-9


def test_json_defaults(tmp_path):
    """Without extrinsics the camera sits at the world origin; name defaults to camN."""
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"cameras": [{"width": 64, "height": 48,
                                             "K": np.eye(3).tolist()}]}))
    cam = load_rig(path)[0]
    assert cam.name == "cam0" and cam.projection == "perspective"
    np.testing.assert_array_equal(cam.T_cam_world, np.eye(4))
    np.testing.assert_array_equal(cam.dist, np.zeros(5))


# ------------------------------------------------------------------ OpenCV calibration files
@pytest.mark.parametrize("suffix", [".yml", ".yaml", ".xml"])
def test_bare_opencv_file_loads_as_one_camera_rig(tmp_path, suffix):
    path = tmp_path / f"calib{suffix}"
    write_opencv(path)
    rig = load_rig(path)
    assert rig.names == ["calib"]
    cam = rig[0]
    assert (cam.width, cam.height) == (640, 480)
    np.testing.assert_array_equal(cam.K, K_LEFT)
    np.testing.assert_array_equal(cam.dist, DIST)
    np.testing.assert_allclose(cam.T_cam_world, pose(RVEC, TVEC), atol=1e-12)
    p = sample_points(np.random.default_rng(2))
    K0 = K_LEFT.copy()
    K0[0, 1] = 0.0
    cam0 = Camera.create("noskew", K0, 640, 480, cam.T_cam_world, cam.dist)
    expected = cv2.projectPoints(p, RVEC, TVEC, K0, DIST)[0][:, 0]
    assert np.abs(cam0.project(p) - expected).max() < 1e-9


def test_rig_json_references_opencv_file(tmp_path):
    write_opencv(tmp_path / "calib.yml")
    write_opencv(tmp_path / "intrinsics.yml", extrinsics=False)
    T_right = pose(np.array([0.0, -0.4, 0.0]), np.array([-120.0, 0.0, 640.0]))
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"cameras": [
        {"name": "left", "opencv": "calib.yml"},
        {"name": "right", "opencv": "intrinsics.yml", "T_cam_world": T_right.tolist()},
        {"name": "over", "opencv": "calib.yml", "T_cam_world": np.eye(4).tolist(),
         "dist": [0, 0, 0, 0]},
    ]}))
    rig = load_rig(path)
    assert rig.names == ["left", "right", "over"]
    left, right, over = rig
    np.testing.assert_allclose(left.T_cam_world, pose(RVEC, TVEC), atol=1e-12)
    np.testing.assert_array_equal(right.T_cam_world, T_right)
    np.testing.assert_array_equal(right.K, K_LEFT)
    np.testing.assert_array_equal(right.dist, DIST)
    # entries in the rig file win over the calibration file
    np.testing.assert_array_equal(over.T_cam_world, np.eye(4))
    np.testing.assert_array_equal(over.dist, np.zeros(5))
    np.testing.assert_array_equal(over.K, K_LEFT)


# ------------------------------------------------------------------ file errors
def expect_error(path: Path, match: str) -> None:
    """load_rig(path) raises a CameraError (a DigitEyesError) naming ``path``."""
    with pytest.raises(CameraError, match=f"{re.escape(str(path))}.*{match}") as info:
        load_rig(path)
    assert isinstance(info.value, DigitEyesError)


def write_rig(tmp_path: Path, cameras) -> Path:
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"cameras": cameras}))
    return path


GOOD = {"name": "c", "width": 640, "height": 480, "K": K_LEFT.tolist()}


def test_missing_rig_file(tmp_path):
    expect_error(tmp_path / "nope.json", "no such rig file")


@pytest.mark.parametrize("text", ['{"cameras": [', "not json", "\x00\x01"])
def test_malformed_json_names_the_file(tmp_path, text):
    path = tmp_path / "rig.json"
    path.write_text(text)
    expect_error(path, "not a readable JSON rig file")


@pytest.mark.parametrize("text", ["[]", '{"cams": []}', '{"cameras": {}}'])
def test_json_without_camera_list(tmp_path, text):
    path = tmp_path / "rig.json"
    path.write_text(text)
    expect_error(path, "'cameras' list")


@pytest.mark.parametrize(("entry", "match"), [
    ({k: v for k, v in GOOD.items() if k != "K"}, "camera 'c' lacks 'K'"),
    ({k: v for k, v in GOOD.items() if k != "width"}, "camera 'c' lacks 'width'"),
    ({k: v for k, v in GOOD.items() if k != "height"}, "camera 'c' lacks 'height'"),
    ("camera", "camera 0 must be an object"),
    ({**GOOD, "rvec": [0, 0, 0]}, "rvec and tvec must both be 3-vectors"),
    ({**GOOD, "rvec": [0, 0], "tvec": [0, 0, 0]}, "rvec and tvec must both be 3-vectors"),
    ({**GOOD, "T_cam_world": (2 * np.eye(4)).tolist()}, "rigid transform"),
    ({**GOOD, "T_cam_world": [[1, 0], [0]]}, "camera 'c'"),
    ({**GOOD, "K": [[0, 0, 0], [0, 1, 0], [0, 0, 1]]}, "focal lengths must be positive"),
    ({**GOOD, "width": "wide"}, "camera 'c'"),
    ({**GOOD, "width": -1}, "width must be an integer"),
    ({**GOOD, "dist": [0.1, 0.2]}, "4, 5, 8, 12 or 14 OpenCV coefficients"),
    ({**GOOD, "projection": "fisheye"}, "projection must be one of"),
    ({**GOOD, "projection": "orthographic", "dist": [0.1, 0, 0, 0]}, "perspective cameras only"),
])
def test_bad_camera_entry_names_file_and_problem(tmp_path, entry, match):
    expect_error(write_rig(tmp_path, [entry]), match)


def test_duplicate_names_in_file(tmp_path):
    expect_error(write_rig(tmp_path, [GOOD, GOOD]), "unique")


def test_empty_camera_list(tmp_path):
    expect_error(write_rig(tmp_path, []), "at least one camera")


@pytest.mark.parametrize("key", ["camera_matrix", "image_width", "image_height"])
def test_opencv_file_missing_key(tmp_path, key):
    path = tmp_path / "calib.yml"
    write_opencv(path, skip=key)
    expect_error(path, f"OpenCV calibration lacks '{key}'")


def test_missing_opencv_file_referenced_from_rig(tmp_path):
    write_rig(tmp_path, [{"name": "c", "opencv": "missing.yml"}])
    with pytest.raises(CameraError, match=r"missing\.yml: no such OpenCV calibration file"):
        load_rig(tmp_path / "rig.json")


@pytest.mark.parametrize("text", ["camera_matrix: [1, 2", "", "{{{ not yaml : ["])
def test_malformed_opencv_file(tmp_path, text):
    path = tmp_path / "calib.yml"
    path.write_text(text)
    expect_error(path, "not an OpenCV calibration file")
