"""render_views on the Appendix A hand: ground truth consistency, options, inputs."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.errors import CameraError, StateError
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.keypoints import keypoint_names
from digiteyes.synth import RenderError, RenderOptions, render_views

W, H = 320, 240


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


@pytest.fixture(scope="module")
def relaxed(hand) -> np.ndarray:
    """Open hand, fingers spread and a little bent, thumb out, palm turned 20 deg about y."""
    q = hand.neutral()
    q[0:4] = (np.cos(np.radians(10)), 0.0, np.sin(np.radians(10)), 0.0)
    degrees = {"index.abd": -8, "ring.abd": 8, "little.abd": 16, "thumb.cmc_abd": 35,
               "thumb.cmc_flex": 30, "thumb.mp": 10, "thumb.ip": 15}
    for finger in ("index", "middle", "ring", "little"):
        degrees |= {f"{finger}.mcp": 15, f"{finger}.pip": 20, f"{finger}.dip": 10}
    for name, value in degrees.items():
        q[hand.state_index(name)] = np.radians(value)
    return q


def camera(eye, target=(0.0, 40.0, 0.0), focal=400.0, **kw) -> Camera:
    return Camera.look_at("c", eye, target, up=(0, 1, 0), width=W, height=H, focal_px=focal,
                          **kw)


CAMERAS = {
    "palm": camera((0.0, 40.0, 520.0)),
    "back": camera((60.0, 100.0, -480.0)),
    "oblique": camera((-260.0, 220.0, 380.0)),
}


def pixel_of(view, points_2d):
    u = np.rint(points_2d[:, 0]).astype(int)
    v = np.rint(points_2d[:, 1]).astype(int)
    return v, u


# ------------------------------------------------------------------ outputs
@pytest.mark.parametrize("color", [False, True])
def test_output_types_and_shapes(hand, relaxed, color):
    views = render_views(hand, relaxed, list(CAMERAS.values()), RenderOptions(color=color),
                         rng=0)
    assert len(views) == 3
    K = len(keypoint_names(hand))
    for view in views:
        assert view.image.dtype == np.uint8
        assert view.image.shape == ((H, W, 3) if color else (H, W))
        assert view.depth.dtype == np.float32 and view.depth.shape == (H, W)
        assert view.labels.dtype == np.int16 and view.labels.shape == (H, W)
        assert view.keypoints_3d.shape == (K, 3) and view.keypoints_2d.shape == (K, 2)
        assert view.visible.dtype == bool and view.visible.shape == (K,)
        assert view.keypoint_names == keypoint_names(hand)
        assert set(np.unique(view.labels)) <= set(range(-1, K))
        assert np.array_equal(np.isinf(view.depth), view.labels < 0)


def test_keypoints_are_fk_points_and_their_projections(hand, relaxed):
    cam = CAMERAS["oblique"]
    view = render_views(hand, relaxed, cam)[0]
    kin = forward_kinematics(hand, relaxed)
    start, _, link_idx = kin.link_segments()
    tips, tip_idx = kin.tip_centres()
    np.testing.assert_allclose(view.keypoints_3d[link_idx], start, atol=1e-12)
    np.testing.assert_allclose(view.keypoints_3d[tip_idx], tips, atol=1e-12)
    np.testing.assert_allclose(view.keypoints_2d, cam.project(view.keypoints_3d), atol=1e-9)


# ------------------------------------------------------------------ geometry vs labels
def _bodies(hand, kin):
    """Every link's body as (kind, geometry, radius): capsules (start, end), tip balls and
    the palm box (corners' centre and half size), world mm."""
    start, end, idx = kin.link_segments()
    tips, tip_idx = kin.tip_centres()
    bodies = {i: ("capsule", (s, e), hand.links[i].radius)
              for s, e, i in zip(start, end, idx, strict=True)}
    bodies |= {i: ("ball", c, hand.links[i].radius) for c, i in zip(tips, tip_idx, strict=True)}
    return start, end, idx, bodies


def _distance(point, body):
    kind, geometry, radius = body
    if kind == "ball":
        return np.linalg.norm(point - geometry) - radius
    a, b = geometry
    t = np.clip((point - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(point - (a + t * (b - a))) - radius


@pytest.mark.parametrize("name", list(CAMERAS))
def test_unhidden_link_axes_fall_in_their_label(hand, relaxed, name):
    """Points on a link's axis project onto that link's label unless something lies in front
    of the link's own (cylinder) surface there. Within reach of a joint (closer than the
    link's radius plus a neighbour's), a neighbouring body (another link touching that
    joint, or the palm) may show instead, as a bent joint's inner side covers the axis."""
    cam = CAMERAS[name]
    view = render_views(hand, relaxed, cam)[0]
    kin = forward_kinematics(hand, relaxed)
    start, end, idx, bodies = _bodies(hand, kin)
    palm = hand.links.index(hand.link("palm"))
    checked = hidden = 0
    for s, e, i in zip(start, end, idx, strict=True):
        r = hand.links[i].radius
        ends = []
        for joint in (s, e):
            touching = [j for j, body in bodies.items()
                        if j != i and _distance(joint, body) < r]
            reach = r + max([bodies[j][2] for j in touching] + [r])
            ends.append((joint, set(touching) | {palm}, reach))
        points = s + np.linspace(0.0, 1.0, 21)[:, None] * (e - s)
        v, u = pixel_of(view, cam.project(points))
        assert cam.in_image(np.stack([u, v], axis=1)).all()
        # the ray through an axis point meets the cylinder r / sin(angle to the axis) before it
        _, rays = cam.viewing_rays(cam.project(points))
        axis = (e - s) / np.linalg.norm(e - s)
        along = r / np.sqrt(1.0 - (rays @ axis) ** 2)
        surface = cam.depth(points - along[:, None] * rays)
        free = view.depth[v, u] > surface - 0.5
        for point, label in zip(points[free], view.labels[v, u][free], strict=True):
            allowed = {i}
            for joint, touching, reach in ends:
                if np.linalg.norm(point - joint) < reach:
                    allowed |= touching
            assert label in allowed, (hand.links[i].name, hand.links[label].name)
        checked += free.sum()
        hidden += (~free).sum()
    assert checked > 3 * hidden, "the test must mostly see unhidden axes"


@pytest.mark.parametrize("name", list(CAMERAS))
def test_visible_tip_centres_fall_on_tip_or_distal_label(hand, relaxed, name):
    cam = CAMERAS[name]
    view = render_views(hand, relaxed, cam)[0]
    tips = [i for i, link in enumerate(hand.links) if link.kind == "tip"]
    assert view.visible[tips].sum() >= 3
    v, u = pixel_of(view, view.keypoints_2d[tips])
    for tip, label, visible in zip(tips, view.labels[v, u], view.visible[tips], strict=True):
        distal = tip - 1  # each tip follows its distal link in model.links
        assert hand.links[distal].kind == "link"
        assert not visible or label in (tip, distal)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_visibility_agrees_with_depth(hand, relaxed, name):
    """A visible keypoint sees a surface at most one body radius in front of it (the palm
    centre: half the palm's diagonal); a hidden one inside the image has a surface in front
    of its own body."""
    cam = CAMERAS[name]
    view = render_views(hand, relaxed, cam)[0]
    v, u = pixel_of(view, view.keypoints_2d)
    seen = view.depth[v, u]
    z = cam.depth(view.keypoints_3d)
    palm = hand.link("palm")
    reach = np.array([link.radius if link.kind != "palm" else 0.5 * np.linalg.norm(palm.size)
                      for link in hand.links if link.kind != "edge"])
    vis = view.visible
    assert vis.sum() >= 10
    assert (seen[vis] <= z[vis] + 1e-3).all()
    assert (seen[vis] >= z[vis] - reach[vis] - 6.0).all()  # 6 mm: a thicker parent's end ball
    inside = cam.in_image(view.keypoints_2d)
    hidden = inside & ~vis
    assert (seen[hidden] < z[hidden] - 0.5).all()


def test_side_view_hides_the_little_finger_behind_the_others(hand):
    """Seen from the thumb side with the hand flat, the index tip is visible and the little
    fingertip is hidden behind the middle finger (thesis Sec. 3.4.1's ordering)."""
    q = hand.neutral()
    q[hand.state_index("thumb.cmc_flex")] = np.radians(50)  # thumb out of the way
    cam = camera((400.0, 80.0, 0.0), target=(0.0, 80.0, 0.0))
    view = render_views(hand, q, cam)[0]
    names = list(view.keypoint_names)
    assert view.visible[names.index("index.tip")]
    assert not view.visible[names.index("little.tip")]
    assert not view.visible[names.index("ring.tip")]


# ------------------------------------------------------------------ options
def test_same_seed_same_image_other_seed_other_noise(hand, relaxed):
    cam = CAMERAS["palm"]
    options = RenderOptions(noise_sigma=4.0)
    a = render_views(hand, relaxed, cam, options, rng=7)[0].image
    b = render_views(hand, relaxed, cam, options, rng=7)[0].image
    c = render_views(hand, relaxed, cam, options, rng=8)[0].image
    assert np.array_equal(a, b)
    assert (a != c).mean() > 0.5
    gen = np.random.default_rng(3)
    d = render_views(hand, relaxed, cam, options, rng=gen)[0].image
    e = render_views(hand, relaxed, cam, options, rng=gen)[0].image
    assert not np.array_equal(d, e), "a Generator is consumed, not reset"


def test_noise_has_the_requested_sigma(hand, relaxed):
    view = render_views(hand, relaxed, CAMERAS["palm"],
                        RenderOptions(background="uniform", background_level=0.5,
                                      noise_sigma=5.0), rng=1)[0]
    background = view.image[view.labels < 0].astype(float)
    assert abs(background.mean() - 127.5) < 0.3
    assert abs(background.std() - 5.0) < 0.15  # quantisation adds 1/12 to the variance


def test_uniform_background_is_exact_and_skin_is_brighter(hand, relaxed):
    view = render_views(hand, relaxed, CAMERAS["palm"],
                        RenderOptions(background="uniform", background_level=0.2))[0]
    assert (view.image[view.labels < 0] == round(0.2 * 255)).all()
    skin = view.image[view.labels >= 0].astype(float)
    assert skin.min() >= round(0.85 * 0.25 * 255) - 1  # ambient floor
    assert skin.max() <= round(0.85 * 255) + 1


def test_black_cloth_is_dark_smooth_and_static(hand, relaxed):
    cam = CAMERAS["back"]
    a = render_views(hand, relaxed, cam, rng=1)[0]
    b = render_views(hand, relaxed, cam, rng=2)[0]
    assert np.array_equal(a.image, b.image), "the backdrop does not depend on rng"
    back = a.image.astype(float)
    assert abs(back[a.labels < 0].mean() - 0.08 * 255) < 3.0
    assert 0.5 < back[a.labels < 0].std() < 5.0
    full = render_views(hand, relaxed, cam, RenderOptions(background_seed=5))[0].image
    assert not np.array_equal(full, a.image)
    rows = np.abs(np.diff(back, axis=1))[(a.labels[:, 1:] < 0) & (a.labels[:, :-1] < 0)]
    assert rows.max() <= 1.0, "cloth folds have no edges"


@pytest.mark.parametrize("color", [False, True])
def test_clutter_is_busy_and_seeded_by_background_seed(hand, relaxed, color):
    cam = CAMERAS["palm"]
    a = render_views(hand, relaxed, cam, RenderOptions(color=color, background="clutter"),
                     rng=0)[0]
    b = render_views(hand, relaxed, cam, RenderOptions(color=color, background="clutter"),
                     rng=9)[0]
    c = render_views(hand, relaxed, cam,
                     RenderOptions(color=color, background="clutter", background_seed=1))[0]
    assert np.array_equal(a.image, b.image)
    assert (a.image != c.image).mean() > 0.5
    assert a.image[a.labels < 0].astype(float).std() > 20.0
    if color:
        chroma = np.ptp(a.image[a.labels < 0].astype(int), axis=1)
        assert np.median(chroma) > 10


def test_rig_cameras_get_different_clutter(hand, relaxed):
    second = camera((0.0, 40.0, 521.0))
    views = render_views(hand, relaxed, Rig((CAMERAS["palm"], replace(second, name="d"))),
                         RenderOptions(background="clutter"))
    both = (views[0].labels < 0) & (views[1].labels < 0)
    assert (views[0].image[both] != views[1].image[both]).mean() > 0.5


@pytest.mark.parametrize("color", [False, True])
def test_image_file_background(hand, relaxed, tmp_path, color):
    rng = np.random.default_rng(0)
    picture = rng.integers(0, 256, size=(90, 110, 3), dtype=np.uint8)
    path = tmp_path / "backdrop.png"
    cv2.imwrite(str(path), picture)
    view = render_views(hand, relaxed, CAMERAS["palm"],
                        RenderOptions(color=color, background=str(path)))[0]
    expected = cv2.resize(picture, (W, H), interpolation=cv2.INTER_AREA)
    expected = cv2.cvtColor(expected, cv2.COLOR_BGR2RGB if color else cv2.COLOR_BGR2GRAY)
    assert np.array_equal(view.image[view.labels < 0], expected[view.labels < 0])


def test_colour_skin_has_skin_hue(hand, relaxed):
    view = render_views(hand, relaxed, CAMERAS["palm"], RenderOptions(color=True))[0]
    skin = view.image[view.labels >= 0].astype(int)
    assert (skin[:, 0] > skin[:, 1]).all() and (skin[:, 1] > skin[:, 2]).all()


def test_supersampling_smooths_edges_only(hand, relaxed):
    cam = CAMERAS["oblique"]
    plain = render_views(hand, relaxed, cam, RenderOptions(background="uniform"))[0]
    smooth = render_views(hand, relaxed, cam,
                          RenderOptions(background="uniform", supersample=3))[0]
    assert np.array_equal(plain.labels, smooth.labels)
    assert np.array_equal(plain.depth, smooth.depth)
    edge = cv2.dilate((cv2.Canny(plain.labels.astype(np.uint8) + 1, 0, 0) > 0)
                      .astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    diff = np.abs(plain.image.astype(int) - smooth.image.astype(int))
    assert diff[edge].mean() > 3.0
    assert diff[~edge].mean() < 1.0


def test_blur_softens_edges(hand, relaxed):
    cam = CAMERAS["palm"]
    sharp = render_views(hand, relaxed, cam, RenderOptions(background="uniform"))[0].image
    soft = render_views(hand, relaxed, cam,
                        RenderOptions(background="uniform", blur_sigma=2.0))[0].image
    assert np.abs(np.diff(soft.astype(int), axis=1)).max() < \
        0.5 * np.abs(np.diff(sharp.astype(int), axis=1)).max()


@pytest.mark.parametrize("kwargs", [
    {"background": "no-such-file.png"}, {"background_level": 1.5}, {"ambient": -0.1},
    {"skin_albedo": 2}, {"noise_sigma": -1}, {"blur_sigma": float("nan")},
    {"supersample": 0}, {"supersample": 1.5}, {"light_dir": (0, 0, 0)},
    {"skin_rgb": (1, 2, 0)}, {"background_seed": -1},
])
def test_bad_options_raise(kwargs):
    with pytest.raises(RenderError, match=next(iter(kwargs))[:6]):
        RenderOptions(**kwargs)


def test_unreadable_image_background_raises(hand, relaxed, tmp_path):
    path = tmp_path / "broken.png"
    path.write_text("not an image")
    with pytest.raises(RenderError, match="not a readable image"):
        render_views(hand, relaxed, CAMERAS["palm"], RenderOptions(background=str(path)))


# ------------------------------------------------------------------ inputs
def test_accepts_rig_camera_and_sequence(hand, relaxed):
    cams = (CAMERAS["palm"], replace(camera((1.0, 40.0, 520.0)), name="d"))
    by_rig = render_views(hand, relaxed, Rig(cams), rng=0)
    by_list = render_views(hand, relaxed, list(cams), rng=0)
    by_one = render_views(hand, relaxed, cams[0], rng=0)
    assert len(by_rig) == len(by_list) == 2 and len(by_one) == 1
    assert np.array_equal(by_rig[1].image, by_list[1].image)
    assert np.array_equal(by_one[0].image, by_list[0].image)
    Rig(cams).check_images([v.image for v in by_rig])


def test_bad_inputs_raise(hand, relaxed):
    with pytest.raises(StateError, match="one state"):
        render_views(hand, np.stack([relaxed, relaxed]), CAMERAS["palm"])
    with pytest.raises(StateError):
        render_views(hand, relaxed[:5], CAMERAS["palm"])
    with pytest.raises(CameraError, match="Camera"):
        render_views(hand, relaxed, [])
    with pytest.raises(CameraError, match="Camera"):
        render_views(hand, relaxed, ["not a camera"])


def test_camera_behind_the_hand_sees_nothing(hand, relaxed):
    cam = camera((0.0, 40.0, 520.0), target=(0.0, 40.0, 1000.0))
    view = render_views(hand, relaxed, cam)[0]
    assert (view.labels < 0).all() and not view.visible.any()
    assert np.isnan(view.keypoints_2d).all()


def test_headlight_lights_the_side_facing_the_camera(hand, relaxed):
    """A light from the palmar side leaves the back of the hand mostly at its ambient level;
    a headlight (light_dir=None) lights whatever faces the camera."""
    cam = CAMERAS["back"]
    fixed = render_views(hand, relaxed, cam, RenderOptions(light_dir=(0.0, 0.0, 1.0)))[0]
    head = render_views(hand, relaxed, cam, RenderOptions(light_dir=None))[0]
    ambient = round(0.85 * 0.25 * 255)
    dark = np.abs(fixed.image[fixed.labels >= 0].astype(int) - ambient) <= 1
    assert dark.mean() > 0.8  # surfaces seen from the back mostly face away from +z
    lit = head.image[head.labels >= 0].astype(float)
    assert np.median(lit) > 0.85 * 0.9 * 255


def test_fingertip_caps_carry_the_tip_labels(hand):
    """The distal capsule's far hemisphere is the fingertip: it takes the tip's label even
    where the tip ball is smaller than the distal link (middle: tip 7 mm, distal 9 mm)."""
    q = hand.neutral()
    q[hand.state_index("thumb.cmc_flex")] = np.radians(40)
    cam = camera((0.0, 60.0, 500.0), target=(0.0, 60.0, 0.0), focal=600.0)
    view = render_views(hand, q, cam)[0]
    kin = forward_kinematics(hand, q)
    start, end, link_idx = kin.link_segments()
    for tip, link in enumerate(hand.links):
        if link.kind != "tip":
            continue
        distal = list(link_idx).index(tip - 1)
        axis = (end[distal] - start[distal]) / np.linalg.norm(end[distal] - start[distal])
        r = hand.links[tip - 1].radius
        beyond, before = end[distal] + 0.6 * r * axis, end[distal] - 0.6 * r * axis
        v, u = pixel_of(view, cam.project(np.stack([beyond, before])))
        assert view.labels[v[0], u[0]] == tip, link.name
        assert view.labels[v[1], u[1]] == tip - 1, link.name
