"""Camera models (thesis eq. 2.5-2.8): projection against OpenCV and hand-written formulas,
Jacobians against central finite differences (alone and chained to the hand state),
``look_at``, viewing rays and input validation.

Expected values come from OpenCV (``cv2.projectPoints``), from the thesis matrices written
out in numpy, or from finite differences, never from the code under test.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import PROJECTIONS, Camera
from digiteyes.camera.camera import PROJECTION_PARAMS
from digiteyes.errors import CameraError
from digiteyes.kinematics import forward_kinematics, integrate, point_jacobian

WIDTH, HEIGHT = 640, 480


# ------------------------------------------------------------------ helpers
def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random proper rotation (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def random_pose(rng: np.random.Generator) -> np.ndarray:
    """A random rigid T_cam_world with translation up to 500 mm."""
    T = np.eye(4)
    T[:3, :3] = random_rotation(rng)
    T[:3, 3] = rng.uniform(-500.0, 500.0, size=3)
    return T


def random_K(rng: np.random.Generator, projection: str, skew: bool) -> np.ndarray:
    """Intrinsics: focal lengths in px (perspective, scaled orthographic) or px/mm."""
    f = rng.uniform(600.0, 1000.0, size=2)
    if projection == "orthographic":
        f = f / 500.0
    K = np.array([[f[0], 0.0, WIDTH / 2 + rng.uniform(-20, 20)],
                  [0.0, f[1], HEIGHT / 2 + rng.uniform(-20, 20)],
                  [0.0, 0.0, 1.0]])
    if skew:
        K[0, 1] = rng.uniform(-0.05, 0.05) * f[0]
    return K


def random_dist(rng: np.random.Generator) -> np.ndarray:
    """OpenCV (k1, k2, p1, p2, k3) of realistic size."""
    return np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-0.01, 0.01),
                     rng.uniform(-0.01, 0.01), rng.uniform(-0.05, 0.05)])


def random_camera(rng: np.random.Generator, projection: str, *, dist: bool = False,
                  skew: bool = False) -> Camera:
    return Camera.create("cam", random_K(rng, projection, skew), WIDTH, HEIGHT,
                         random_pose(rng), random_dist(rng) if dist else None, projection,
                         depth_mm=rng.uniform(300.0, 900.0))


def points_in_front(rng: np.random.Generator, T_cam_world: np.ndarray, n: int) -> np.ndarray:
    """World points whose camera coordinates lie in a box 300-900 mm in front of the camera."""
    p_cam = np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                             rng.uniform(300, 900, n)])
    R, t = T_cam_world[:3, :3], T_cam_world[:3, 3]
    return (p_cam - t) @ R  # R^T (p_cam - t), row-wise


def central_difference(f, p: np.ndarray, h: float) -> np.ndarray:
    """d f / d p for f: (P, 3) -> (P, 2), by central differences: (P, 2, 3)."""
    cols = []
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        cols.append((f(p + step) - f(p - step)) / (2 * h))
    return np.stack(cols, axis=-1)


def assert_jacobian_close(J: np.ndarray, J_fd: np.ndarray, rtol: float = 1e-6) -> None:
    """Relative agreement, measured against the largest entry (zeros stay comparable)."""
    scale = np.abs(J_fd).max()
    np.testing.assert_allclose(J, J_fd, rtol=rtol, atol=rtol * scale)


# ------------------------------------------------------------------ perspective vs OpenCV
@pytest.mark.parametrize("n_coeffs", [0, 4, 5])
def test_perspective_matches_opencv(n_coeffs):
    rng = np.random.default_rng(10 + n_coeffs)
    for _ in range(20):
        T = random_pose(rng)
        K = random_K(rng, "perspective", skew=False)
        dist = random_dist(rng)[:n_coeffs]
        cam = Camera.create("cam", K, WIDTH, HEIGHT, T, dist)
        p = points_in_front(rng, T, 50)
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        expected = cv2.projectPoints(p, rvec, T[:3, 3], K,
                                     dist if n_coeffs else None)[0][:, 0]
        assert np.abs(cam.project(p) - expected).max() < 1e-9


def test_perspective_skew_matches_eq_2_6_with_skewed_K():
    """OpenCV ignores K[0, 1]; with skew, check w = S[K [R t] p] (eq. 2.6) by hand."""
    rng = np.random.default_rng(3)
    for _ in range(10):
        cam = random_camera(rng, "perspective", skew=True)
        p = points_in_front(rng, cam.T_cam_world, 30)
        P = cam.K @ cam.T_cam_world[:3]  # 3x4 projection matrix of eq. 2.6
        b = np.column_stack([p, np.ones(len(p))]) @ P.T
        np.testing.assert_allclose(cam.project(p), b[:, :2] / b[:, 2:], rtol=0, atol=1e-9)


# ------------------------------------------------------------------ (scaled) orthographic
@pytest.mark.parametrize("projection", ["orthographic", "scaled-orthographic"])
def test_affine_projections_match_eq_2_8(projection):
    """w = Pbar T_cam_world p (eq. 2.7) with the 2x4 Pbar of eq. 2.8 (plus skew); the scaled
    form divides the linear part by the reference depth Z0."""
    rng = np.random.default_rng(4)
    for _ in range(10):
        cam = random_camera(rng, projection, skew=True)
        (fx, s, cx), (_, fy, cy) = cam.K[0], cam.K[1]
        scale = 1.0 if projection == "orthographic" else 1.0 / cam.depth_mm
        P_bar = np.array([[fx * scale, s * scale, 0.0, cx], [0.0, fy * scale, 0.0, cy]])
        p = points_in_front(rng, cam.T_cam_world, 30)
        p_cam = np.column_stack([p, np.ones(len(p))]) @ cam.T_cam_world.T
        np.testing.assert_allclose(cam.project(p), p_cam @ P_bar.T, rtol=0, atol=1e-9)


def test_scaled_orthographic_equals_perspective_on_reference_plane():
    """Weak perspective is exact for points at depth Z0 (Huang et al. Sec. 4.2: t3 m = A x + t)."""
    rng = np.random.default_rng(5)
    persp = random_camera(rng, "perspective", skew=True)
    weak = dataclasses.replace(persp, projection="scaled-orthographic", depth_mm=640.0)
    p_cam = np.column_stack([rng.uniform(-150, 150, (40, 2)), np.full(40, 640.0)])
    R, t = persp.T_cam_world[:3, :3], persp.T_cam_world[:3, 3]
    p = (p_cam - t) @ R
    np.testing.assert_allclose(weak.project(p), persp.project(p), rtol=0, atol=1e-9)


def test_output_shapes_follow_batch_dimensions():
    rng = np.random.default_rng(6)
    for projection in PROJECTIONS:
        cam = random_camera(rng, projection)
        p = points_in_front(rng, cam.T_cam_world, 20).reshape(4, 5, 3)
        w, J = cam.project_with_jacobian(p)
        assert w.shape == (4, 5, 2) and J.shape == (4, 5, 2, 3)
        w1, J1 = cam.project_with_jacobian(p[1, 2])
        assert w1.shape == (2,) and J1.shape == (2, 3)
        np.testing.assert_allclose(w1, w[1, 2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(J1, J[1, 2], rtol=0, atol=1e-12)
        assert cam.project_with_jacobian(p, jacobian=False)[1] is None
        np.testing.assert_array_equal(cam.project(p), w)


def test_to_camera_depth_and_centre():
    rng = np.random.default_rng(7)
    cam = random_camera(rng, "perspective")
    np.testing.assert_allclose(cam.to_camera(cam.centre_world), 0.0, atol=1e-9)
    np.testing.assert_allclose(cam.T_world_cam @ cam.T_cam_world, np.eye(4), atol=1e-12)
    p = points_in_front(rng, cam.T_cam_world, 10)
    p_cam = np.column_stack([p, np.ones(10)]) @ cam.T_cam_world.T
    np.testing.assert_allclose(cam.to_camera(p), p_cam[:, :3], atol=1e-9)
    np.testing.assert_allclose(cam.depth(p), p_cam[:, 2], atol=1e-9)


def test_in_image_uses_pixel_centre_convention():
    cam = Camera.create("c", np.diag([500.0, 500.0, 1.0]), 4, 3)
    w = np.array([[-0.5, -0.5], [3.5, 2.5], [-0.51, 0.0], [0.0, 2.51], [1.0, 1.0]])
    np.testing.assert_array_equal(cam.in_image(w), [True, True, False, False, True])
    np.testing.assert_array_equal(cam.in_image(w, margin=0.6), [False] * 4 + [True])


# ------------------------------------------------------------------ Jacobians
@pytest.mark.parametrize("projection", PROJECTIONS)
def test_jacobian_matches_finite_differences(projection):
    rng = np.random.default_rng(20)
    for _ in range(10):
        cam = random_camera(rng, projection, dist=projection == "perspective", skew=True)
        p = points_in_front(rng, cam.T_cam_world, 25)
        w, J = cam.project_with_jacobian(p)
        np.testing.assert_allclose(w, cam.project(p), rtol=0, atol=1e-12)
        assert_jacobian_close(J, central_difference(cam.project, p, h=1e-3))


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


def surface_points(model, rng: np.random.Generator):
    """Rows and shape-frame points on every link of the model (cylinders, tips, palm)."""
    rows, pts = [], []
    for link in model.links:
        if link.kind == "link":
            u, a = rng.uniform(0, 1), rng.uniform(0, 2 * np.pi)
            pts.append((u * link.length, link.radius * np.cos(a), link.radius * np.sin(a)))
        elif link.kind == "tip":
            pts.append(link.radius * rng.normal(size=3) / np.sqrt(3))
        else:
            pts.append(np.asarray(link.centre) + rng.uniform(-0.5, 0.5, 3) * link.size)
        rows.append(link.row)
    return np.array(rows), np.array(pts, dtype=float)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_jacobian_chained_to_hand_state(hand, projection):
    """dw/dv = (dw/dp_world)(dp_world/dv) against central differences of project(FK(q))
    stepped through ``integrate`` (thesis eq. 2.16 followed by the camera, eq. 2.6-2.8)."""
    rng = np.random.default_rng(30)
    for _ in range(3):
        q = hand.neutral()
        quat = rng.normal(size=4)
        q[0:4] = quat / np.linalg.norm(quat)
        q[4:7] = rng.uniform(-50, 50, 3)
        lo, hi = np.maximum(hand.lower[7:], -1.0), np.minimum(hand.upper[7:], 1.0)
        q[7:] = rng.uniform(lo, hi)
        rows, p_shape = surface_points(hand, rng)
        kin = forward_kinematics(hand, q)
        p_world, J_state = point_jacobian(kin, rows, p_shape)

        direction = rng.normal(size=3)
        eye = p_world.mean(axis=0) + 600.0 * direction / np.linalg.norm(direction)
        pose = Camera.look_at("pose", eye, p_world.mean(axis=0), up=rng.normal(size=3))
        K = random_K(rng, projection, skew=True)
        dist = random_dist(rng) if projection == "perspective" else None
        cam = Camera.create("c", K, WIDTH, HEIGHT, pose.T_cam_world, dist, projection,
                            depth_mm=600.0)
        assert (cam.depth(p_world) > 200).all()

        _, J_cam = cam.project_with_jacobian(p_world)
        J = J_cam @ J_state  # (P, 2, n_v)

        h = 1e-6
        steps = h * np.eye(hand.n_v)
        q_batch = np.concatenate([integrate(hand, q, steps), integrate(hand, q, -steps)])
        w_batch = cam.project(forward_kinematics(hand, q_batch).points(rows, p_shape))
        J_fd = (w_batch[:hand.n_v] - w_batch[hand.n_v:]) / (2 * h)  # (n_v, P, 2)
        assert_jacobian_close(J, np.moveaxis(J_fd, 0, -1))


# ------------------------------------------------------------------ look_at
@pytest.mark.parametrize("projection", PROJECTIONS)
def test_look_at_centres_target_and_keeps_up_up(projection):
    rng = np.random.default_rng(40)
    for _ in range(10):
        target = rng.uniform(-100, 100, 3)
        eye = target + rng.uniform(300, 900) * random_rotation(rng)[:, 0]
        up = rng.normal(size=3)
        cam = Camera.look_at("c", eye, target, up, width=WIDTH, height=HEIGHT,
                             focal_px=700.0, projection=projection)
        principal = np.array([(WIDTH - 1) / 2, (HEIGHT - 1) / 2])
        np.testing.assert_allclose(cam.K[:2, 2], principal)
        np.testing.assert_allclose(cam.project(target), principal, atol=1e-9)
        forward = (target - eye) / np.linalg.norm(target - eye)
        up_perp = up - (up @ forward) * forward
        up_perp /= np.linalg.norm(up_perp)
        right = np.cross(forward, up_perp)  # viewer's right: forward x up
        du = cam.project(target + 20.0 * right) - principal
        dv = cam.project(target + 20.0 * up_perp) - principal
        assert dv[1] < -1.0 and abs(dv[0]) < 1e-6, "world 'up' must appear upward (smaller v)"
        assert du[0] > 1.0 and abs(du[1]) < 1e-6, "viewer's right must appear at larger u"


def test_look_at_focal_length_in_pixels_at_target_depth():
    """focal_px is the perspective focal length; the affine models match its scale at the
    target, so a 10 mm offset there spans the same pixels in all three."""
    eye, target = np.array([0.0, -500.0, 100.0]), np.array([0.0, 0.0, 100.0])
    spans = []
    for projection in PROJECTIONS:
        cam = Camera.look_at("c", eye, target, focal_px=800.0, projection=projection)
        w = cam.project(np.array([target, target + np.array([10.0, 0.0, 0.0])]))
        spans.append(np.linalg.norm(w[1] - w[0]))
    np.testing.assert_allclose(spans, 800.0 * 10.0 / 500.0, rtol=1e-12)


@pytest.mark.parametrize(("eye", "target", "up", "match"), [
    ((0, 0, 0), (0, 0, 0), (0, 0, 1), "eye and target coincide"),
    ((0, 0, 0), (0, 0, 5), (0, 0, 1), "parallel to 'up'"),
])
def test_look_at_rejects_degenerate_views(eye, target, up, match):
    with pytest.raises(CameraError, match=match):
        Camera.look_at("c", eye, target, up)


# ------------------------------------------------------------------ viewing rays
@pytest.mark.parametrize("projection", PROJECTIONS)
def test_viewing_rays_round_trip(projection):
    rng = np.random.default_rng(50)
    for _ in range(10):
        cam = random_camera(rng, projection, skew=True)
        pixels = rng.uniform([-0.5, -0.5], [WIDTH - 0.5, HEIGHT - 0.5], size=(6, 7, 2))
        origins, dirs = cam.viewing_rays(pixels)
        assert origins.shape == dirs.shape == (6, 7, 3)
        np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, atol=1e-12)
        t = rng.uniform(50.0, 2000.0, size=(6, 7, 1))
        np.testing.assert_allclose(cam.project(origins + t * dirs), pixels, rtol=0, atol=1e-9)
        axis = cam.T_cam_world[2, :3]  # optical axis in world coordinates
        if projection == "perspective":
            np.testing.assert_allclose(origins, np.broadcast_to(cam.centre_world, (6, 7, 3)),
                                       atol=1e-9)
            assert (dirs @ axis > 0).all()
        else:
            np.testing.assert_allclose(dirs, np.broadcast_to(axis, (6, 7, 3)), atol=1e-12)
            np.testing.assert_allclose(cam.depth(origins), 0.0, atol=1e-9)


def test_viewing_rays_ignore_distortion():
    rng = np.random.default_rng(51)
    cam = random_camera(rng, "perspective", dist=True, skew=True)
    ideal = dataclasses.replace(cam, dist=np.zeros(5))
    pixels = rng.uniform(0, 400, size=(20, 2))
    o, d = cam.viewing_rays(pixels)
    np.testing.assert_allclose(ideal.project(o + 500.0 * d), pixels, atol=1e-9)


# ------------------------------------------------------------------ validation
GOOD_K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])


def make(**changes):
    args = {"name": "bad", "K": GOOD_K, "width": 640, "height": 480, "T_cam_world": None,
            "dist": None, "projection": "perspective", "depth_mm": 1000.0}
    args.update(changes)
    return Camera.create(**args)


def scaled_pose() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] *= 2.0
    return T


def reflected_pose() -> np.ndarray:
    return np.diag([1.0, 1.0, -1.0, 1.0])


def bad_bottom_row() -> np.ndarray:
    T = np.eye(4)
    T[3, 0] = 0.5
    return T


@pytest.mark.parametrize(("changes", "match"), [
    ({"K": np.diag([0.0, 800.0, 1.0])}, "focal lengths must be positive"),
    ({"K": np.diag([800.0, -5.0, 1.0])}, "focal lengths must be positive"),
    ({"K": np.eye(3)[:2]}, r"K must be a finite 3x3 matrix, got \(2, 3\)"),
    ({"K": np.full((3, 3), np.nan)}, "K must be a finite 3x3"),
    ({"K": GOOD_K + np.diag([0.0, 0.0, 1.0])}, "upper triangular"),
    ({"T_cam_world": np.eye(4)[:3]}, "T_cam_world must be a finite 4x4"),
    ({"T_cam_world": scaled_pose()}, "T_cam_world must be a rigid transform"),
    ({"T_cam_world": reflected_pose()}, "T_cam_world must be a rigid transform"),
    ({"T_cam_world": bad_bottom_row()}, "T_cam_world must be a rigid transform"),
    ({"dist": np.zeros(3)}, "4, 5, 8, 12 or 14 OpenCV coefficients .* got 3"),
    ({"dist": [0, 0, 0, 0, 0, 0.1, 0, 0]}, "rational/prism/tilt coefficients must be zero"),
    ({"dist": [0.1, 0, 0, 0], "projection": "orthographic"}, "perspective cameras only"),
    ({"dist": [0.1, 0, 0, 0], "projection": "scaled-orthographic"}, "perspective cameras only"),
    ({"projection": "fisheye"}, "projection must be one of .*'fisheye'"),
    ({"width": 0}, "width must be an integer from 1 to 65536 pixels, got 0"),
    ({"height": -480}, "height must be an integer from 1 to 65536 pixels"),
    ({"width": 640.5}, "width must be an integer"),
    ({"width": float("nan")}, "width must be an integer"),
    ({"height": float("inf")}, "height must be an integer"),
    ({"width": None}, "width must be an integer"),
    ({"depth_mm": 0.0}, "depth_mm must be a finite positive number"),
])
def test_create_rejects_bad_parameters(changes, match):
    with pytest.raises(CameraError, match=f"camera 'bad': .*{match}"):
        make(**changes)


def test_create_defaults_and_short_distortion():
    cam = make(dist=[0.1, -0.02, 0.001, 0.002])
    np.testing.assert_array_equal(cam.dist, [0.1, -0.02, 0.001, 0.002, 0.0])
    np.testing.assert_array_equal(cam.T_cam_world, np.eye(4))
    assert (cam.width, cam.height, cam.projection) == (640, 480, "perspective")
    assert isinstance(cam.width, int)


def test_zero_extra_distortion_coefficients_are_accepted() -> None:
    """An 8-coefficient OpenCV vector with zero rational terms equals the 5-term model."""
    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    five = [-0.2, 0.05, 0.001, -0.002, 0.01]
    cam5 = Camera.create("a", K, 640, 480, dist=five)
    cam8 = Camera.create("b", K, 640, 480, dist=[*five, 0.0, 0.0, 0.0])
    points = np.array([[10.0, -20.0, 500.0], [-60.0, 35.0, 700.0]])
    np.testing.assert_array_equal(cam5.project(points), cam8.project(points))


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_projection_params_have_the_length_compiled_callers_allocate(projection):
    """The keypoint fit's kernel packs cameras into (C, PROJECTION_PARAMS) arrays."""
    camera = Camera.look_at("c", eye=(0, 0, -500), target=(0, 0, 0), up=(0, -1, 0),
                            projection=projection)
    assert camera.projection_params.shape == (PROJECTION_PARAMS,)
