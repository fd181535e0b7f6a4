"""The joints' links ordered pixel by pixel (``pixel_depth_at_joints``): the ray test in
the compiled layered error, and the visibility it predicts against the renderer's depth
buffer on the desk pair, where the joint rule alone hides curling phalanges that the
cameras see."""

import numpy as np
import pytest

from digiteyes.benchmarks.accuracy import scenario_for
from digiteyes.kinematics import forward_kinematics
from digiteyes.occlusion.parts import template_parts
from digiteyes.synth import RenderOptions, render_views
from digiteyes.templates._kernels import _nearer_along_ray
from digiteyes.templates.filtering import LogFilter
from digiteyes.templates.layered import acquire_templates, evaluate_layered


def _nearer(eye, p, axis, radius_front, radius_back):
    """The compiled ray test for one capsule axis ``axis`` ((3,), (3,)) as window 0."""
    axes = np.zeros((1, 4, 3))
    axes[0, :2] = axis
    return _nearer_along_ray(*eye, *p, axes, 0, radius_front, radius_back)


def test_the_ray_test_measures_how_much_nearer_the_capsule_lies():
    eye = np.zeros(3)
    p = np.array([0.0, 0.0, 500.0])  # a pixel's point 500 mm down the ray
    across = (np.array([-20.0, 0.0, 480.0]), np.array([20.0, 0.0, 480.0]))
    assert _nearer(eye, p, across, 8.0, 8.0) == pytest.approx(20.0)
    behind = (np.array([-20.0, 0.0, 530.0]), np.array([20.0, 0.0, 530.0]))
    assert _nearer(eye, p, behind, 8.0, 8.0) == pytest.approx(-30.0)
    # the axis point nearest the ray, not the nearest end; radii count as surfaces
    slanted = (np.array([0.0, 0.0, 520.0]), np.array([0.0, 40.0, 560.0]))
    assert _nearer(eye, p, slanted, 10.0, 2.0) == pytest.approx(-12.0)
    # an orthographic camera: an eye far back along the optical axis
    far = p - 1e6 * np.array([0.0, 0.0, 1.0])
    assert _nearer(far, p, across, 8.0, 8.0) == pytest.approx(20.0, abs=1e-6)


@pytest.fixture(scope="module")
def desk_frames():
    scenario = scenario_for("desk", "exact", 13)
    log = LogFilter(size=7, contrast_px=2.0)
    frames = {}
    for f in (6, 9, 12):
        kin = forward_kinematics(scenario.model, scenario.states[f])
        views = render_views(scenario.model, scenario.states[f], scenario.rig, RenderOptions(),
                             rng=f)
        frames[f] = (kin, [(cam, log.apply(v.image), v.labels)
                           for cam, v in zip(scenario.rig, views, strict=True)])
    return scenario.model, frames


def _visible_shares(model, kin, cam, image, labels, pixel_depth):
    """Per link part with template pixels: (share with V >= 0.5, share the label image
    shows as that link)."""
    templates = acquire_templates(template_parts(model), image, cam, kin, 2.0, 0.0,
                                  pixel_depth)
    ev = evaluate_layered(templates, image, cam, kin, templates.planes(kin, cam), None, 0.0,
                          derivatives=False, pixel_depth_at_joints=pixel_depth)
    px = np.rint(ev.pixels).astype(int)
    h, w = labels.shape
    inside = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
    shown = np.full(len(px), -2)
    shown[inside] = labels[px[inside, 1], px[inside, 0]]
    out = {}
    for k, part in enumerate(templates.parts):
        sl = templates.slices[k]
        if part.kind == "link" and sl.stop > sl.start:
            out[part.name] = (float(np.mean(ev.visibility[sl] >= 0.5)),
                              float(np.mean(shown[sl] == part.link)))
    return out


def test_pixel_depth_sees_the_curling_phalanges_the_renderer_shows(desk_frames):
    model, frames = desk_frames
    kin, views = frames[12]
    cam, image, labels = views[1]
    ruled = _visible_shares(model, kin, cam, image, labels, False)["index.middle"]
    by_pixel = _visible_shares(model, kin, cam, image, labels, True)["index.middle"]
    shown = by_pixel[1]
    assert shown > 0.3  # the curled index's middle phalanx hangs in view of camera 1
    assert ruled[0] < 0.5 * shown  # the joint rule hides most of it (0.08 of 0.39)
    assert abs(by_pixel[0] - shown) < 0.1  # pixel by pixel: 0.36


def test_pixel_depth_agrees_better_with_the_depth_buffer_over_the_curl(desk_frames):
    model, frames = desk_frames
    gaps = {False: [], True: []}
    for kin, views in frames.values():
        for cam, image, labels in views:
            for pixel_depth in (False, True):
                shares = _visible_shares(model, kin, cam, image, labels, pixel_depth)
                gaps[pixel_depth] += [abs(a - b) for a, b in shares.values()]
    # mean gap over every link, both cameras, frames 6, 9, 12: 0.063 against 0.101
    assert np.mean(gaps[True]) < 0.8 * np.mean(gaps[False]), (np.mean(gaps[True]),
                                                             np.mean(gaps[False]))
