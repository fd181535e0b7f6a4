"""The flesh renderer against analytic cases and independent distance computations."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.benchmarks.render import relaxed_hand_state
from digiteyes.camera import Camera
from digiteyes.kinematics import forward_kinematics
from digiteyes.render._flesh_kernels import N_PARAMS, ROUND_BOX, ROUND_CONE
from digiteyes.render.flesh import FleshScene, build_flesh
from digiteyes.render.flesh_raster import keypoint_visibility, rasterise_flesh
from digiteyes.render.pixels import PixelGrid
from digiteyes.synth import RenderOptions, render_views


def _cone_scene(a, b, ra, rb) -> FleshScene:
    params = np.zeros((1, N_PARAMS))
    params[0, 0:3], params[0, 3:6], params[0, 6:8] = a, b, (ra, rb)
    frames = np.zeros((1, 12))
    frames[0, 3:12] = np.eye(3).ravel()
    return FleshScene(np.array([ROUND_CONE], np.int8), params, np.zeros(1),
                      np.array([0], np.int16), np.array([1], np.int16), frames,
                      np.zeros((1, 4)))


def _grid(f=2000.0, w=400, h=200) -> PixelGrid:
    K = np.array([[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1.0]])
    return PixelGrid(True, K, w, h)


def test_tapered_cone_silhouette_width_and_depth():
    Z, L, ra, rb = 1000.0, 60.0, 10.0, 5.0
    grid = _grid()
    scene = _cone_scene((-L / 2, 0, Z), (L / 2, 0, Z), ra, rb)
    raster = rasterise_flesh(scene, grid, np.array([0, 0, -1.0]))
    sin_phi = (ra - rb) / L
    for x in (-10.0, 0.0, 10.0):  # axial positions between the tangent points
        half = (ra - (x + L / 2) * sin_phi) / np.sqrt(1 - sin_phi ** 2)
        u = round(grid.K[0, 0] * x / Z + grid.K[0, 2])
        width_px = raster.hit[:, u].sum()
        assert width_px == pytest.approx(2 * half * grid.K[1, 1] / Z, abs=1.5)
    centre = raster.depth[grid.height // 2 - 1:grid.height // 2 + 1,
                          grid.width // 2 - 1:grid.width // 2 + 1]
    half0 = (ra - (L / 2) * sin_phi) / np.sqrt(1 - sin_phi ** 2)
    assert np.allclose(centre, Z - half0, atol=0.1)
    # the cap beyond b carries the far label
    u_end = round(grid.K[0, 0] * (L / 2 + rb / 2) / Z + grid.K[0, 2])
    assert raster.labels[grid.height // 2, u_end] == 1
    assert raster.labels[grid.height // 2, grid.width // 2] == 0


def _cone_distance(p, a, b, ra, rb):
    """Distance to the union of balls along the segment with linearly varying radius (the
    convex hull of the end balls), brute force over the axis."""
    s = np.linspace(0.0, 1.0, 2001)
    centres = a[None] + s[:, None] * (b - a)[None]
    radii = ra + s * (rb - ra)
    return np.min(np.linalg.norm(p[:, None, :] - centres[None], axis=2) - radii[None], axis=1)


def _box_distance(p, P):
    axes = P[3:12].reshape(3, 3)
    q = np.abs((p - P[0:3]) @ axes.T) - P[12:15]
    return (np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
            - P[15])


@pytest.fixture(scope="module")
def hand_view():
    hand = load_model("hand")
    q = relaxed_hand_state(hand)
    cam = Camera.look_at("c", (-150.0, 40.0, 520.0), (0, 40, 0), up=(0, 1, 0))
    scene = build_flesh(hand, forward_kinematics(hand, q)).transformed(cam.T_cam_world)
    raster = rasterise_flesh(scene, PixelGrid.from_camera(cam), np.array([0, 0, -1.0]))
    return hand, q, cam, scene, raster


def test_labels_are_the_nearest_link(hand_view):
    hand, _, cam, scene, raster = hand_view
    v, u = np.nonzero(raster.hit)
    pick = np.random.default_rng(0).choice(len(v), 1500, replace=False)
    v, u = v[pick], u[pick]
    z = raster.depth[v, u].astype(float)
    rays = np.linalg.inv(cam.K) @ np.stack([u, v, np.ones_like(u)]).astype(float)
    points = (rays * z).T
    dist = np.empty((len(points), len(scene.kinds)))
    for k, (kind, P) in enumerate(zip(scene.kinds, scene.params, strict=True)):
        dist[:, k] = (_cone_distance(points, P[0:3], P[3:6], P[6], P[7])
                      if kind == ROUND_CONE else _box_distance(points, P))
    # points lie on the blended surface: within a fraction of the widest blend of a primitive
    assert np.abs(np.min(dist, axis=1)).max() < 0.5 * scene.blend.max()
    order = np.sort(dist, axis=1)
    clear = order[:, 1] - order[:, 0] > 0.5
    nearest = np.argmin(dist, axis=1)
    expected = scene.labels[nearest].astype(int)
    P = scene.params[nearest]
    along = np.einsum("ij,ij->i", points - P[:, 0:3], P[:, 3:6] - P[:, 0:3]) / \
        np.maximum(np.sum((P[:, 3:6] - P[:, 0:3]) ** 2, axis=1), 1e-12)
    far = (scene.kinds[nearest] == ROUND_CONE) & (along > 1.0)
    expected[far] = scene.far_labels[nearest][far]
    got = raster.labels[v, u].astype(int)
    assert clear.sum() > 1000
    assert np.mean(got[clear] == expected[clear]) > 0.995
    assert set(np.unique(raster.labels)) - {-1} >= set(range(len(hand.links) - 3))


def test_keypoint_visibility_two_cones():
    grid = _grid()
    back = _cone_scene((-20, 0, 1000.0), (20, 0, 1000.0), 8.0, 6.0)
    front_params = back.params.copy()
    front_params[0, [2, 5]] = 950.0
    both = FleshScene(np.array([ROUND_CONE, ROUND_CONE], np.int8),
                      np.concatenate([back.params, front_params]), np.zeros(2),
                      np.array([0, 1], np.int16), np.array([0, 1], np.int16),
                      np.concatenate([back.frames, back.frames]), np.zeros((2, 4)))
    point = np.array([[0.0, 0.0, 1000.0], [0.0, 0.0, 950.0]])
    links = np.array([0, 1])
    assert keypoint_visibility(both, point, links, True).tolist() == [False, True]
    assert keypoint_visibility(back, point[:1], links[:1], True).tolist() == [True]
    raster = rasterise_flesh(both, grid, np.array([0, 0, -1.0]))
    assert raster.labels[grid.height // 2, grid.width // 2] == 1
    # moved aside (beyond its radius in the image), the front cone no longer hides it
    aside = both.params.copy()
    aside[1, [1, 4]] = 30.0
    moved = FleshScene(both.kinds, aside, both.blend, both.labels, both.far_labels,
                       both.frames, both.nails)
    assert keypoint_visibility(moved, point[:1], links[:1], True).tolist() == [True]


def test_keypoint_visibility_in_a_fist_seen_from_behind():
    hand = load_model("hand")
    q = hand.neutral()
    for finger in ("index", "middle", "ring", "little"):
        for joint, deg in (("mcp", 85), ("pip", 100), ("dip", 70)):
            q[hand.state_index(f"{finger}.{joint}")] = np.radians(deg)
    cam = Camera.look_at("back", (0.0, 60.0, -450.0), (0, 40, 0), up=(0, 1, 0))
    view = render_views(hand, q, cam, RenderOptions(appearance="flesh"))[0]
    points_cam = view.keypoints_3d @ cam.T_cam_world[:3, :3].T + cam.T_cam_world[:3, 3]
    u, v = np.rint(view.keypoints_2d).astype(int).T
    seen = view.depth[v, u]
    names = list(view.keypoint_names)
    for tip in ("index.tip", "middle.tip", "ring.tip", "little.tip"):
        assert not view.visible[names.index(tip)]  # behind the back of the hand
    assert view.visible[names.index("thumb.tip")]
    hidden = ~view.visible
    assert np.all(seen[hidden] < points_cam[hidden, 2] - 5.0)


def test_flesh_is_deterministic_and_seeded():
    hand = load_model("hand")
    q = relaxed_hand_state(hand)
    cam = Camera.look_at("c", (-150.0, 40.0, 520.0), (0, 40, 0), up=(0, 1, 0),
                         width=320, height=240, focal_px=400)
    opts = RenderOptions(appearance="flesh", color=True, noise_sigma=2.0)
    a = render_views(hand, q, cam, opts, rng=3)[0]
    b = render_views(hand, q, cam, opts, rng=3)[0]
    assert np.array_equal(a.image, b.image) and np.array_equal(a.labels, b.labels)
    other = RenderOptions(appearance="flesh", color=True, noise_sigma=2.0, skin_seed=5)
    c = render_views(hand, q, cam, other, rng=3)[0]
    assert np.array_equal(a.depth, c.depth) and not np.array_equal(a.image, c.image)
    model = render_views(hand, q, cam, RenderOptions(color=True), rng=3)[0]
    assert np.array_equal(model.keypoints_2d, a.keypoints_2d)
    assert (a.labels >= 0).sum() != (model.labels >= 0).sum()  # its own geometry


def test_shadows_darken_and_tones_differ():
    hand = load_model("hand")
    q = relaxed_hand_state(hand)
    cam = Camera.look_at("c", (-150.0, 40.0, 520.0), (0, 40, 0), up=(0, 1, 0),
                         width=320, height=240, focal_px=400)
    light = (-1.0, 0.2, 0.3)
    plain = render_views(hand, q, cam, RenderOptions(appearance="flesh", light_dir=light))[0]
    shadow = render_views(hand, q, cam, RenderOptions(appearance="flesh", light_dir=light,
                                                      shadows=True))[0]
    hit = plain.labels >= 0
    assert np.all(shadow.image[hit] <= plain.image[hit])
    assert (shadow.image[hit] < plain.image[hit]).sum() > 50
    dark = render_views(hand, q, cam, RenderOptions(appearance="flesh", skin_tone="dark"))[0]
    light_tone = render_views(hand, q, cam,
                              RenderOptions(appearance="flesh", skin_tone="light"))[0]
    assert dark.image[hit].mean() < 0.6 * light_tone.image[hit].mean()


def test_bad_appearance_is_named():
    from digiteyes.synth import RenderError

    with pytest.raises(RenderError, match="appearance"):
        RenderOptions(appearance="clay")
    with pytest.raises(RenderError, match="skin_tone"):
        RenderOptions(skin_tone="green")


def test_round_box_primitive_matches_its_distance():
    params = np.zeros((1, N_PARAMS))
    params[0, 0:3] = (0, 0, 800.0)
    params[0, 3:12] = np.eye(3).ravel()
    params[0, 12:16] = (20.0, 10.0, 5.0, 4.0)
    frames = np.zeros((1, 12))
    frames[0, 3:12] = np.eye(3).ravel()
    scene = FleshScene(np.array([ROUND_BOX], np.int8), params, np.zeros(1),
                       np.array([0], np.int16), np.array([0], np.int16), frames,
                       np.zeros((1, 4)))
    grid = _grid(f=1000.0)
    raster = rasterise_flesh(scene, grid, np.array([0, 0, -1.0]))
    assert raster.depth[grid.height // 2, grid.width // 2] == pytest.approx(800 - 9.0, abs=0.05)
    row = raster.hit[grid.height // 2]
    assert row.sum() == pytest.approx(2 * 24.0 * 1000 / 791.0, abs=2.0)
