"""Depth and labels of the renderer against an independent computation.

A three-body model (a ball, a capsule rod, a rounded slab) is rendered, and every pixel is
compared with sphere tracing along the camera's own viewing ray
(``Camera.viewing_rays``) through the signed distance functions of the bodies, written
here from their definitions: the ball, the capsule (distance to a segment minus the
radius) and the rounded box (distance to a box shrunk by the rounding radius, minus that
radius). Nothing of the renderer's ray casting is reused.
"""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel, parse_model_text
from digiteyes.synth import RenderOptions, render_views

MODEL_TEXT = """
model analytic
description a ball, a capsule and a rounded slab for exact depth tests
[states]
q0  slab.z  length  -100  100
[frames]
0  ball  0   0   100  0  tip(20)                  1
1  rod   0   0   80   0  cyl(10)                  2
2  -     0   q0  0    0  -                        3
3  slab  0   0   0    0  box(60,40,12,-180,0,0)   -
"""
BALL, ROD, SLAB = 0, 1, 2
WIDTH, HEIGHT = 200, 150


@pytest.fixture(scope="module")
def model() -> KinematicModel:
    return KinematicModel(parse_model_text(MODEL_TEXT))


def sdfs(p: np.ndarray, slab_z: float) -> np.ndarray:
    """Signed distances (..., 3) to the ball, the rod and the slab at points p (..., 3).

    The rows chain: the ball sits at the origin, the rod runs from x = 100 to 180, and the
    slab frame (row 3) sits at (180, 0, slab_z), so the slab's centre is (0, 0, slab_z):
    it cuts through the ball or floats in front of or behind it.
    """
    ball = np.linalg.norm(p, axis=-1) - 20.0
    a, b = np.array([100.0, 0, 0]), np.array([180.0, 0, 0])
    s = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    rod = np.linalg.norm(p - (a + s[..., None] * (b - a)), axis=-1) - 10.0
    rounding = 6.0
    q = np.abs(p - np.array([0.0, 0.0, slab_z])) - (np.array([30.0, 20.0, 6.0]) - rounding)
    slab = (np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)
            - rounding)
    return np.stack([ball, rod, slab], axis=-1)


def sphere_trace(cam: Camera, slab_z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected depth (inf on a miss) and label (-1) per pixel, and a silhouette mask."""
    u, v = np.meshgrid(np.arange(WIDTH), np.arange(HEIGHT))
    origins, dirs = cam.viewing_rays(np.stack([u, v], axis=-1).astype(float))
    origins, dirs = origins.reshape(-1, 3), dirs.reshape(-1, 3)
    t = np.zeros(len(origins))
    active = np.arange(len(origins))
    for _ in range(5000):
        step = sdfs(origins[active] + t[active, None] * dirs[active], slab_z).min(axis=-1)
        t[active] += step
        active = active[(step > 1e-9) & (t[active] < 1e4)]
        if not len(active):
            break
    p = (origins + t[:, None] * dirs).reshape(HEIGHT, WIDTH, 3)
    dist = sdfs(p, slab_z)
    hit = dist.min(axis=-1) < 1e-6
    depth = np.where(hit, cam.depth(p), np.inf)
    label = np.where(hit, dist.argmin(axis=-1), -1)
    padded = np.pad(hit, 1, mode="edge")
    neighbours = [padded[1 + dv:HEIGHT + 1 + dv, 1 + du:WIDTH + 1 + du]
                  for dv in (-1, 0, 1) for du in (-1, 0, 1)]
    silhouette = np.any([n != hit for n in neighbours], axis=0)
    return depth, label, silhouette


def cameras() -> dict[str, Camera]:
    target, eye = np.array([40.0, 10.0, 0.0]), np.array([190.0, -190.0, 560.0])
    pose = Camera.look_at("pose", eye, target, up=(0, 1, 0))
    skewed = np.array([[290.0, 6.0, 93.0], [0.0, 300.0, 71.0], [0.0, 0.0, 1.0]])
    ortho = np.array([[0.5, 0.01, 99.5], [0.0, 0.52, 74.5], [0.0, 0.0, 1.0]])
    return {
        "perspective": Camera.create("p", skewed, WIDTH, HEIGHT, pose.T_cam_world),
        "orthographic": Camera.create("o", ortho, WIDTH, HEIGHT, pose.T_cam_world,
                                      projection="orthographic"),
        "scaled-orthographic": Camera.create("s", skewed, WIDTH, HEIGHT, pose.T_cam_world,
                                             projection="scaled-orthographic",
                                             depth_mm=620.0),
    }


@pytest.mark.parametrize("name", ["perspective", "orthographic", "scaled-orthographic"])
@pytest.mark.parametrize("slab_z", [0.0, 35.0])
def test_depth_and_labels_match_sphere_tracing(model, name, slab_z):
    cam = cameras()[name]
    view = render_views(model, np.array([slab_z]), cam, RenderOptions(background="uniform"))[0]
    depth, label, silhouette = sphere_trace(cam, slab_z)
    assert set(np.unique(label)) == {-1, BALL, ROD, SLAB}, "all three bodies must be seen"

    both = np.isfinite(depth) & (view.labels >= 0)
    np.testing.assert_allclose(view.depth[both], depth[both], rtol=0, atol=2e-3)
    assert np.array_equal(view.labels[both], label[both])
    assert np.isinf(view.depth[view.labels < 0]).all()
    mismatch = np.isfinite(depth) != (view.labels >= 0)
    assert not (mismatch & ~silhouette).any(), "hit/miss may differ only on silhouettes"
    assert mismatch.sum() <= 0.01 * silhouette.sum()


@pytest.mark.parametrize("eye", [(420.0, 0.0, 0.0), (420.0, 3.0, 2.0), (300.0, 60.0, 0.0)])
def test_rod_seen_end_on_matches_sphere_tracing(model, eye):
    """Looking down the rod's axis (exactly, nearly, and at a slant): the rays of a row then
    meet its infinite cylinder in any pattern, which the caster's per-row spans must not
    cut short."""
    cam = Camera.look_at("end", eye=eye, target=(100.0, 0.0, 0.0), up=(0, 0, 1),
                         width=WIDTH, height=HEIGHT, focal_px=250.0)
    view = render_views(model, np.array([0.0]), cam, RenderOptions(background="uniform"))[0]
    depth, label, silhouette = sphere_trace(cam, 0.0)
    assert (label == ROD).sum() > 200
    both = np.isfinite(depth) & (view.labels >= 0)
    np.testing.assert_allclose(view.depth[both], depth[both], rtol=0, atol=2e-3)
    assert np.array_equal(view.labels[both], label[both])
    mismatch = np.isfinite(depth) != (view.labels >= 0)
    assert not (mismatch & ~silhouette).any(), "hit/miss may differ only on silhouettes"


def test_slab_in_front_hides_the_ball(model):
    """Moving the slab towards a camera that sees it in front of the ball changes the
    ball's pixels to slab pixels, with the slab's (smaller) depth."""
    cam = Camera.look_at("c", eye=(0.0, 0.0, 500.0), target=(0.0, 0.0, 0.0),
                         up=(0, 1, 0), width=WIDTH, height=HEIGHT, focal_px=300.0)
    far = render_views(model, np.array([-80.0]), cam)[0]
    near = render_views(model, np.array([80.0]), cam)[0]
    overlap = (far.labels == BALL) & (near.labels == SLAB)
    assert overlap.sum() > 50
    assert (near.depth[overlap] < far.depth[overlap]).all()


def test_distorted_camera_agrees_with_project(model):
    """With lens distortion the image is warped so that ``cam.project`` of a body's point
    lands on that body, with the depth of the surface in front of it."""
    pose = Camera.look_at("pose", (40.0, 10.0, 380.0), (40.0, 10.0, 0.0), up=(0, 1, 0))
    K = np.array([[220.0, 0.0, 101.0], [0.0, 220.0, 73.0], [0.0, 0.0, 1.0]])
    dist = np.array([-0.35, 0.12, 0.002, -0.001, 0.0])
    cam = Camera.create("d", K, WIDTH, HEIGHT, pose.T_cam_world, dist)
    view = render_views(model, np.array([0.0]), cam)[0]
    ideal = render_views(model, np.array([0.0]),
                         Camera.create("i", K, WIDTH, HEIGHT, pose.T_cam_world))[0]
    # barrel distortion (k1 < 0) pulls the rod, far off-axis, towards the image centre
    def rod_offset(labels):
        v, u = np.nonzero(labels == ROD)
        return np.hypot(u.mean() - K[0, 2], v.mean() - K[1, 2])

    assert rod_offset(view.labels) < rod_offset(ideal.labels) - 2.0

    xs = np.linspace(-110.0, 175.0, 40)
    points = np.concatenate([np.array([[-25.0, 15.0, 6.0], [25.0, -15.0, 6.0]]),  # slab face
                             np.array([[0.0, 0.0, 20.0]]),  # ball front
                             np.stack([xs, np.zeros_like(xs), np.full_like(xs, 10.0)],
                                      axis=1)[(xs > 105) & (xs < 175)]])  # rod front line
    expected = np.array([SLAB, SLAB, BALL] + [ROD] * (len(points) - 3))
    pixels = np.rint(cam.project(points)).astype(int)
    assert cam.in_image(pixels).all()
    np.testing.assert_array_equal(view.labels[pixels[:, 1], pixels[:, 0]], expected)
    # surfaces here face the camera; a pixel of rounding moves the depth by well under 1 mm
    np.testing.assert_allclose(view.depth[pixels[:, 1], pixels[:, 0]], cam.depth(points),
                               atol=1.0)
