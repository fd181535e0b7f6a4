"""The background template (thesis Sec. 4.4.2): what it knows, zero error on its own
frame, and its boundary gradient against finite differences."""

import numpy as np
import pytest

from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.occlusion.parts import template_parts
from digiteyes.occlusion.windows import image_windows
from digiteyes.templates.background import (
    acquire_background,
    evaluate_background,
    window_region,
)


def _windows(model, cam, parts, templates, q, planes=None):
    kin = forward_kinematics(model, q)
    planes = templates.planes(kin, cam) if planes is None else planes
    return image_windows(parts, planes, kin, cam), planes


@pytest.fixture(scope="module")
def background(setup):
    """The background template of frame 0 (windows at its state, margin 2 px)."""
    scenario, images, model, cam, templates = setup
    windows, _ = _windows(model, cam, template_parts(model), templates, scenario.states[0])
    return acquire_background(images[0], windows, margin=2.0)


def test_background_is_known_off_the_hand_and_fits_its_own_frame(setup, background):
    scenario, images, model, cam, templates = setup
    parts = template_parts(model)
    windows, _ = _windows(model, cam, parts, templates, scenario.states[0])
    pixels = window_region(windows, images[0].shape, 20.0)
    inside = windows.bounds()
    # far from the hand everything is known; some pixels under the hand are not
    assert background.known[0, 0] and background.known[-1, -1]
    assert 0.05 < 1.0 - background.known[pixels[:, 1], pixels[:, 0]].mean() < 0.9
    centre = np.rint(windows.points[0].mean(axis=0)).astype(int)
    assert not background.known[centre[1], centre[0]]
    assert inside.shape == (len(parts), 4)
    ev = evaluate_background(background, images[0], windows, 1.0, 2.0, pixels)
    assert ev.energy < 1e-9 and np.all(ev.visibility[background.known[pixels[:, 1],
                                                                       pixels[:, 0]]] > 0)


def test_background_gradient_matches_finite_differences(setup, background, fd_gradient):
    """On frame 12 (the index moved in front of the middle finger), at a state off the
    truth: the gradient of E_B (boundary terms only) against central differences."""
    scenario, images, model, cam, templates = setup
    parts = template_parts(model)
    q = integrate(model, scenario.states[12],
                  np.r_[0.8, -0.5, 0.6, 0.05, -0.04, 0.06, 0.03, -0.02, 0.04])
    windows, planes = _windows(model, cam, parts, templates, q)
    pixels = window_region(windows, images[12].shape, 20.0)
    tau = 1.5
    ev = evaluate_background(background, images[12], windows, tau, 2.0, pixels)
    assert ev.energy > 0

    def energy(dv):
        w, _ = _windows(model, cam, parts, templates, integrate(model, q, dv), planes)
        return evaluate_background(background, images[12], w, tau, 2.0, pixels).energy

    fd = fd_gradient(energy, model.n_v)
    scale = np.abs(fd).max()
    assert scale > 0
    np.testing.assert_allclose(ev.gradient, fd, atol=2e-3 * scale)
    # unit windows: no boundary, no gradient
    assert not evaluate_background(background, images[12], windows, 0.0, 2.0,
                                   pixels).gradient.any()
