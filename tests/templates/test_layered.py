"""The layered template error: zero at the acquisition state, region and boundary
derivatives against finite differences of the smoothed error, the Gauss-Newton matrix,
the refresh rule and the segmentation."""

import numpy as np
import pytest

from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.occlusion.segmentation import segment_image
from digiteyes.templates.filtering import TemplateError
from digiteyes.templates.layered import (
    HIDDEN_RESIDUAL_RIG,
    TemplateOptions,
    acquire_templates,
    evaluate_layered,
    part_views,
    refresh_templates,
)


def test_acquired_templates_fit_their_own_frame(setup):
    scenario, images, model, cam, templates = setup
    kin = forward_kinematics(model, scenario.states[0])
    ev = evaluate_layered(templates, images[0], cam, kin, templates.planes(kin, cam), None,
                          0.0, margin=2.0)
    assert ev.energy < 1e-6
    assert 0.5 < templates.weights.mean() < 1.0  # occluded pixels wait for a refresh
    assert ev.visible_rms < 1e-4


def _off_state(setup):
    """A state near frame 12 (where the fingers overlap), off the truth: (state, its
    kinematics, the template planes there)."""
    scenario, _, model, cam, templates = setup
    q = integrate(model, scenario.states[12],
                  np.r_[0.8, -0.5, 0.6, 0.05, -0.04, 0.06, 0.03, -0.02, 0.04])
    kin = forward_kinematics(model, q)
    return q, kin, templates.planes(kin, cam)


@pytest.mark.parametrize("tau, pixel_depth, hidden", [(0.0, False, 0.0), (1.5, False, 0.0),
                                                    (1.5, True, 0.0), (1.5, False, 16.0),
                                                    (1.5, True, 16.0)])
def test_gradient_matches_finite_differences(setup, tau, pixel_depth, hidden, fd_gradient):
    _, images, model, cam, templates = setup
    q, kin, planes = _off_state(setup)
    ev = evaluate_layered(templates, images[12], cam, kin, planes, None, tau, margin=2.0,
                          pixel_depth_at_joints=pixel_depth, hidden_residual=hidden)
    assert ev.order.relations, "the test state must have occlusions"
    assert bool(ev.order.pixel_depth) == pixel_depth, "the test state must bend a joint"
    if pixel_depth:  # some pixels are seen that the joint rule alone would hide
        rule = evaluate_layered(templates, images[12], cam, kin, planes, None, tau,
                                margin=2.0)
        assert (ev.visibility > rule.visibility + 0.5).any()

    def energy(dv):
        kin_dv = forward_kinematics(model, integrate(model, q, dv))
        return evaluate_layered(templates, images[12], cam, kin_dv, planes, ev.order, tau,
                                margin=2.0, hidden_residual=hidden).energy

    fd = fd_gradient(energy, model.n_v)
    scale = np.abs(fd).max()
    np.testing.assert_allclose(ev.gradient, fd, atol=2e-3 * scale)
    if tau == 0.0:
        assert not ev.gradient_boundary.any()
    else:
        assert np.abs(ev.gradient_boundary).max() > 1e-3 * scale


@pytest.mark.parametrize("tau", [0.0, 1.5])
def test_error_without_derivatives_is_the_same_error(setup, tau):
    """The residual-only pass (a solve's final state) gives the full pass's error,
    residuals, visibility and pixels, and no derivatives."""
    _, images, _, cam, templates = setup
    _, kin, planes = _off_state(setup)
    full = evaluate_layered(templates, images[12], cam, kin, planes, None, tau, margin=2.0)
    bare = evaluate_layered(templates, images[12], cam, kin, planes, None, tau, margin=2.0,
                            derivatives=False)
    assert full.energy > 0 and bare.energy == full.energy
    for name in ("residuals", "visibility", "pixels"):
        np.testing.assert_array_equal(getattr(bare, name), getattr(full, name))
    assert bare.H is None and bare.gradient is None and bare.gradient_boundary is None
    with pytest.raises(ValueError, match="form_rows"):
        evaluate_layered(templates, images[12], cam, kin, planes, None, tau,
                         form_rows=True, derivatives=False)


def test_hidden_pixels_cost_the_hidden_residual(setup):
    """``hidden_residual`` h adds h^2 / 2 for each hidden share of a pixel, and changes
    nothing else: residuals, visibility and the region terms are the thesis's."""
    _, images, _, cam, templates = setup
    _, kin, planes = _off_state(setup)
    plain = evaluate_layered(templates, images[12], cam, kin, planes, None, 1.5, margin=2.0)
    hidden = 16.0
    charged = evaluate_layered(templates, images[12], cam, kin, planes, None, 1.5,
                               margin=2.0, hidden_residual=hidden)
    seen = templates.weights * ((plain.pixels >= 0).all(axis=1)
                                & (plain.pixels[:, 0] < cam.width - 1)
                                & (plain.pixels[:, 1] < cam.height - 1))
    assert (seen * (1.0 - plain.visibility)).sum() > 20  # the state hides some pixels
    extra = 0.5 * hidden ** 2 * float((seen * (1.0 - plain.visibility)).sum())
    assert charged.energy == pytest.approx(plain.energy + extra, rel=1e-9)
    for name in ("residuals", "visibility", "H", "gradient_region"):
        np.testing.assert_array_equal(getattr(charged, name), getattr(plain, name))
    assert not np.allclose(charged.gradient_boundary, plain.gradient_boundary)


def test_boundary_term_alone_matches_finite_differences_of_visibility(setup, fd_gradient):
    """With the residuals frozen, E changes only through V: that is eq. 3.12's part."""
    scenario, images, model, cam, templates = setup
    q = integrate(model, scenario.states[12], np.r_[0.5, 0.5, -0.5, 0.08, 0.02, -0.05,
                                                    0.0, 0.03, 0.0])
    kin = forward_kinematics(model, q)
    planes = templates.planes(kin, cam)
    tau = 2.0
    ev = evaluate_layered(templates, images[12], cam, kin, planes, None, tau, form_rows=True,
                          margin=2.0)
    r = ev.residuals

    def frozen(dv):
        kin_dv = forward_kinematics(model, integrate(model, q, dv))
        other = evaluate_layered(templates, images[12], cam, kin_dv, planes, ev.order, tau,
                                 margin=2.0)
        return 0.5 * float((templates.weights * other.visibility * r * r).sum())

    fd = fd_gradient(frozen, model.n_v)
    np.testing.assert_allclose(ev.gradient_boundary, fd, atol=2e-3 * np.abs(fd).max())
    rows_fd = 0.5 * (templates.weights * r * r) @ ev.rows_visibility
    np.testing.assert_allclose(rows_fd, ev.gradient_boundary, rtol=1e-9,
                               atol=1e-9 * np.abs(fd).max())


def test_gauss_newton_matrix_is_the_visible_region_rows(setup):
    scenario, images, model, cam, templates = setup
    kin = forward_kinematics(model, scenario.states[12])
    ev = evaluate_layered(templates, images[12], cam, kin, templates.planes(kin, cam), None,
                          1.0, form_rows=True, margin=2.0)
    s = templates.weights * ev.visibility
    H = (ev.rows_region * s[:, None]).T @ ev.rows_region
    np.testing.assert_allclose(ev.H, H, rtol=1e-8, atol=1e-8 * np.abs(H).max())
    np.testing.assert_allclose(ev.gradient_region, ev.rows_region.T @ (s * ev.residuals),
                               rtol=1e-8, atol=1e-8 * np.abs(ev.gradient_region).max())


def _refresh_case(setup):
    """Fresh templates of frame 0 evaluated at frame 12's true state: (templates, the
    evaluation, frame 12's kinematics)."""
    scenario, images, model, cam, base = setup
    kin0 = forward_kinematics(model, scenario.states[0])
    templates = acquire_templates(base.parts, images[0], cam, kin0, spacing_px=2.0)
    kin = forward_kinematics(model, scenario.states[12])
    ev = evaluate_layered(templates, images[12], cam, kin, templates.planes(kin, cam), None,
                          0.0)
    return templates, ev, kin


def test_refresh_blends_only_good_frames(setup):
    base = setup[4]
    templates, ev, _ = _refresh_case(setup)
    before = templates.values.copy()
    options = TemplateOptions(refresh_rate=0.5, reference_pull=0.0, refresh_max_rms=1e3,
                              refresh_turn_deg=None)
    assert refresh_templates(templates, ev, options) > 0
    seen = (ev.visibility >= 0.99) & (base.weights > 0)
    observed = ev.residuals + before
    np.testing.assert_allclose(templates.values[seen], 0.5 * (before + observed)[seen],
                               atol=1e-3)
    strict = TemplateOptions(refresh_max_rms=1e-3, refresh_turn_deg=None)
    assert refresh_templates(templates, ev, strict) == 0


def test_refresh_gated_by_turn_leaves_parts_that_did_not_turn(setup):
    """With ``refresh_turn_deg`` a part's rate is scaled by its turn since its template was
    written (frame 0 to 12: the index curls, the palm and the middle finger keep their
    orientation), and the written orientation follows the refresh."""
    cam, base = setup[3], setup[4]
    templates, ev, kin = _refresh_case(setup)
    before, written = templates.values.copy(), templates.views.copy()
    turn = 3.0
    options = TemplateOptions(refresh_rate=0.5, reference_pull=0.0, refresh_max_rms=1e3,
                              refresh_turn_deg=turn)
    with pytest.raises(TemplateError):
        refresh_templates(templates, ev, options)
    assert refresh_templates(templates, ev, options, kin, cam) > 0
    now = part_views(base.parts, kin, cam)
    angles = [np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))
              for a, b in zip(written, now, strict=True)]  # the definition, by the trace
    seen = (ev.visibility >= 0.99) & (base.weights > 0)
    observed = ev.residuals + before
    turned = still = 0
    for k, angle in enumerate(angles):
        pixels = seen & (templates.part_of == k)
        rate = 0.5 * min(1.0, angle / turn)
        np.testing.assert_allclose(templates.values[pixels],
                                   (before + rate * (observed - before))[pixels], atol=1e-3)
        if angle < 0.01:
            still += 1
            np.testing.assert_allclose(templates.views[k], written[k], atol=1e-12)
        elif angle >= turn:
            turned += 1
            np.testing.assert_allclose(templates.views[k], now[k], atol=1e-9)
    assert still >= 2 and turned >= 2  # palm and middle finger still; the index curls


def test_the_gate_is_for_rigs_of_one_camera_by_default():
    options = TemplateOptions()
    assert options.refresh_turn_deg == 3.0 and options.refresh_turn_cameras == 1
    assert options.for_rig(1).refresh_turn_deg == 3.0
    assert options.for_rig(2).refresh_turn_deg is None
    assert TemplateOptions(refresh_turn_cameras=2).for_rig(2).refresh_turn_deg == 3.0
    with pytest.raises(TemplateError):
        TemplateOptions(refresh_turn_cameras=0)
    with pytest.raises(TemplateError):
        TemplateOptions(refresh_turn_deg=0.0)


def test_joints_are_ordered_pixel_by_pixel_with_two_cameras_by_default():
    options = TemplateOptions()
    assert options.pixel_depth_at_joints is None
    assert options.for_rig(1).pixel_depth_at_joints is False
    assert options.for_rig(2).pixel_depth_at_joints is True
    assert TemplateOptions(pixel_depth_at_joints=False).for_rig(2).pixel_depth_at_joints is False
    assert TemplateOptions(pixel_depth_at_joints=True).for_rig(1).pixel_depth_at_joints is True


def test_hiding_costs_with_two_cameras_by_default():
    options = TemplateOptions()
    assert options.hidden_residual is None
    assert options.for_rig(1).hidden_residual == 0.0
    assert options.for_rig(2).hidden_residual == HIDDEN_RESIDUAL_RIG
    assert TemplateOptions(hidden_residual=0.0).for_rig(3).hidden_residual == 0.0
    assert TemplateOptions(hidden_residual=9.0).for_rig(1).hidden_residual == 9.0
    with pytest.raises(TemplateError, match="hidden_residual"):
        TemplateOptions(hidden_residual=-1.0)


def test_segmentation_puts_the_front_part_on_top(setup):
    scenario, images, model, cam, templates = setup
    kin = forward_kinematics(model, scenario.states[12])
    ev = evaluate_layered(templates, images[12], cam, kin, templates.planes(kin, cam), None,
                          0.0)
    labels = segment_image(ev.windows, ev.order, cam.width, cam.height)
    single = {}
    for k in range(len(templates.parts)):
        alone = type(ev.order)(np.array([k]), [])
        single[k] = segment_image(ev.windows, alone, cam.width, cam.height) == k
    assert ev.order.relations
    for relation in ev.order.relations:
        both = single[relation.front] & single[relation.back]
        if both.any():
            assert not (labels[both] == relation.back).any()
    covered = np.any(np.stack(list(single.values())), axis=0)
    np.testing.assert_array_equal(labels >= 0, covered)
