"""The model fit recovers rendered hands from their keypoints; its Jacobian is exact."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.detect.hand21 import HAND21_NAMES, PALM, TIPS, model_anchors
from digiteyes.detect.model_fit import (
    FitOptions,
    KeypointFitProblem,
    KeypointObservation,
    fit_keypoints,
)
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.kinematics.keypoints import keypoint_names, keypoints
from digiteyes.synth.views import render_views


def true_points(hand, q, scale=1.0):
    rows, points = model_anchors(hand)
    return scale * forward_kinematics(hand, q).points(rows, points)


def test_anchors_agree_with_library_keypoints(hand, posed):
    """Joints are the link bases of kinematics.keypoints; tips lie beyond the sphere centre."""
    q = posed(hand, 0)
    names, ref = keypoints(hand, forward_kinematics(hand, q))
    ours = true_points(hand, q)
    assert ours.shape == (21, 3) and len(HAND21_NAMES) == 21
    ref_of = dict(zip(names, ref[0], strict=True))
    np.testing.assert_allclose(ours[5], ref_of["index.proximal.base"], atol=1e-9)
    np.testing.assert_allclose(ours[3], ref_of["thumb.distal.base"], atol=1e-9)
    tip_gap = np.linalg.norm(ours[8] - ref_of["index.tip"])
    assert tip_gap == pytest.approx(hand.link("index.tip").radius)
    assert "palm" in keypoint_names(hand)


def test_jacobian_matches_finite_differences(hand, camera, posed):
    q = posed(hand, 1)
    uv = camera.project(true_points(hand, q)) + 3.0
    cam2 = Camera.look_at("side", eye=(250, 0, 400), target=(0, 0, 0), up=(0, -1, 0))
    shape = 1.3 * camera.to_camera(true_points(hand, q)) + np.array([5.0, -40.0, 900.0])
    obs = [KeypointObservation(camera, uv, np.linspace(0.2, 1.0, 21), shape + 1.5),
           KeypointObservation(cam2, cam2.project(true_points(hand, q)))]
    problem = KeypointFitProblem(hand, obs, true_points(hand, q) + 2.0,
                                 FitOptions(sigma_shape_mm=15.0), True)
    x = np.append(q, 1.05)
    r0, J = problem.residuals(x, True)
    eps = 1e-6
    J_fd = np.empty_like(J)
    for i in range(problem.n_v):
        dv = np.zeros(problem.n_v)
        dv[i] = eps
        J_fd[:, i] = (problem.residuals(problem.retract(x, dv), False)[0]
                      - problem.residuals(problem.retract(x, -dv), False)[0]) / (2 * eps)
    np.testing.assert_allclose(J, J_fd, atol=1e-5 * np.abs(J).max())
    assert r0.shape == (42 * 2 + 63 + 63 + 21 + 1,)  # 2D x 2, shape, 3D, joints, scale


def test_a_detectors_3d_shape_is_matched_whatever_its_size_and_origin(hand, camera, posed):
    """The shape term compares shapes, not sizes or places: the true keypoints in the
    camera's axes, 1.3 times larger and moved, leave no residual at the true state."""
    q = posed(hand, 2)
    truth = true_points(hand, q)
    shape = 1.3 * camera.to_camera(truth) + np.array([5.0, -40.0, 900.0])
    obs = [KeypointObservation(camera, camera.project(truth), shape_3d=shape)]
    problem = KeypointFitProblem(hand, obs, None, FitOptions(sigma_shape_mm=15.0), False)
    ignored = KeypointFitProblem(hand, obs, None, FitOptions(), False)
    r = problem.residuals(np.append(q, 1.0), False)[0]
    assert len(ignored.residuals(np.append(q, 1.0), False)[0]) == len(r) - 63  # off by default
    np.testing.assert_allclose(r[42:42 + 63], 0.0, atol=1e-9)
    moved = problem.residuals(np.append(posed(hand, 3), 1.0), False)[0][42:42 + 63]
    assert np.abs(moved).max() > 0.5  # another pose does not fit the shape


def test_the_shape_term_fixes_what_one_view_leaves_open(hand, camera, posed):
    """Noisy keypoints in one camera (3 px) with and without the true shape (as a
    detector's 3D keypoints would give it): with it, the root-relative error drops."""
    rng = np.random.default_rng(0)
    errors = {False: [], True: []}
    for seed in range(4):
        q = posed(hand, seed)
        truth = true_points(hand, q)
        uv = camera.project(truth) + rng.normal(0.0, 3.0, (21, 2))
        for with_shape in (False, True):
            shape = camera.to_camera(truth) if with_shape else None
            fit = fit_keypoints(hand, [KeypointObservation(camera, uv, shape_3d=shape)],
                                options=FitOptions(sigma_shape_mm=15.0))
            rel = (fit.keypoints_world - fit.keypoints_world[9]) - (truth - truth[9])
            errors[with_shape].append(np.linalg.norm(rel, axis=1).mean())
    assert np.mean(errors[True]) < 0.8 * np.mean(errors[False]), errors


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_monocular_fit_recovers_rendered_keypoints(hand, camera, posed, seed):
    """Keypoints of a rendered hand (render_views truth): the fit reprojects them within
    3 px and puts the palm within 8 mm when the hand size is known."""
    q = posed(hand, seed)
    view = render_views(hand, q, [camera], rng=0)[0]
    assert view.image.max() > 100  # the hand is in the picture
    uv = camera.project(true_points(hand, q))
    fit = fit_keypoints(hand, [KeypointObservation(camera, uv)])
    assert not fit.scale_fitted and fit.scale == 1.0
    assert np.median(fit.reprojection_px) < 1.0
    assert fit.reprojection_px.max() < 4.0
    truth = true_points(hand, q)
    assert np.linalg.norm(fit.keypoints_world[0] - truth[0]) < 8.0  # wrist, metric
    root_rel = (fit.keypoints_world - fit.keypoints_world[9]) - (truth - truth[9])
    assert np.median(np.linalg.norm(root_rel, axis=1)) < 10.0


def test_monocular_depth_follows_the_assumed_scale(hand, camera, posed):
    """A hand 10 % larger than assumed is placed about 10 % too close (same pixels)."""
    q = posed(hand, 4)
    truth = true_points(hand, q, 1.1)
    fit = fit_keypoints(hand, [KeypointObservation(camera, camera.project(truth))])
    depth_true = camera.depth(truth[9])
    depth_fit = camera.depth(fit.keypoints_world[9])
    assert depth_fit / depth_true == pytest.approx(1 / 1.1, abs=0.03)


def test_stereo_fit_recovers_scale_and_state(hand, camera, posed):
    q = posed(hand, 5)
    truth = true_points(hand, q, 1.12)
    cam2 = Camera.look_at("side", eye=(250, 0, 400), target=(0, 0, 0), up=(0, -1, 0))
    obs = [KeypointObservation(c, c.project(truth)) for c in (camera, cam2)]
    fit = fit_keypoints(hand, obs)
    assert fit.scale_fitted
    assert fit.scale == pytest.approx(1.12, abs=0.02)
    assert np.linalg.norm(fit.keypoints_world - truth, axis=1).max() < 6.0


def test_3d_fit_with_scale(hand, posed):
    q = posed(hand, 6, flex=(0.0, 0.9))
    truth = true_points(hand, q, 0.93)
    fit = fit_keypoints(hand, target_3d=truth)
    assert fit.scale == pytest.approx(0.93, abs=0.01)
    assert np.linalg.norm(fit.keypoints_world - truth, axis=1).max() < 3.0
    np.testing.assert_allclose(fit.scaled_state()[4:7], fit.scale * fit.q[4:7])


def test_fit_from_a_perturbed_start_and_joint_limits(hand, camera, posed):
    q = posed(hand, 7)
    uv = camera.project(true_points(hand, q))
    start = integrate(hand, q, np.r_[np.zeros(6), np.full(hand.n_v - 6, 0.1)])
    fit = fit_keypoints(hand, [KeypointObservation(camera, uv)], q0=start)
    assert np.all(fit.q >= hand.lower - 1e-12) and np.all(fit.q <= hand.upper + 1e-12)
    assert np.median(fit.reprojection_px[0][list(TIPS)]) < 2.0


def test_fit_needs_data(hand, posed):
    with pytest.raises(DigitEyesError, match="at least one camera"):
        fit_keypoints(hand)


def test_3d_fit_ignores_missing_points(hand, posed):
    q = posed(hand, 8)
    truth = true_points(hand, q, 1.05)
    given = truth.copy()
    given[0] = np.nan  # e.g. STB labels the palm centre, not the wrist
    fit = fit_keypoints(hand, target_3d=given)
    assert fit.scale == pytest.approx(1.05, abs=0.01)
    assert np.linalg.norm(fit.keypoints_world - truth, axis=1).max() < 3.0


def test_the_motion_prior_is_the_step_from_the_start_with_its_jacobian(hand, camera, posed):
    """At the start the prior's residual is zero; away from it, it is the tangent step
    over the sigmas (mm for the palm's position, rad for angles), and its Jacobian is the
    finite-difference one where the step is small (the rotation's is exact to first
    order)."""
    q0 = posed(hand, 1)
    obs = [KeypointObservation(camera, camera.project(true_points(hand, q0)))]
    options = FitOptions(motion_sigma=(20.0, 10.0))
    problem = KeypointFitProblem(hand, obs, None, options, False, motion_from=q0)
    plain = KeypointFitProblem(hand, obs, None, FitOptions(), False)
    n_plain = plain.residuals(np.append(q0, 1.0), False)[0].size
    r0, _ = problem.residuals(np.append(q0, 1.0), False)
    prior = r0[42 + 21:42 + 21 + hand.n_v]
    assert r0.size == n_plain + hand.n_v and np.allclose(prior, 0.0)
    dv = np.zeros(hand.n_v)
    dv[3:6] = (10.0, -20.0, 40.0)  # the palm moved (mm)
    dv[7] = np.radians(5.0)  # a joint bent 5 degrees
    x = np.append(integrate(hand, q0, dv), 1.0)
    r, J = problem.residuals(x, True)
    prior = r[42 + 21:42 + 21 + hand.n_v]
    np.testing.assert_allclose(prior[3:6], np.array([10.0, -20.0, 40.0]) / 20.0, atol=1e-9)
    assert prior[7] == pytest.approx(0.5)
    eps = 1e-6
    rows = slice(42 + 21, 42 + 21 + hand.n_v)
    for i in range(hand.n_v):
        step = np.zeros(problem.n_v)
        step[i] = eps
        fd = (problem.residuals(problem.retract(x, step), False)[0][rows]
              - problem.residuals(problem.retract(x, -step), False)[0][rows]) / (2 * eps)
        np.testing.assert_allclose(J[rows, i], fd, atol=2e-3 * np.abs(fd).max() + 1e-9)
    # it holds the fit near the start: keypoints of a hand 60 mm farther away
    far = q0.copy()
    far[6] += 60.0
    moved = [KeypointObservation(camera, camera.project(true_points(hand, far)))]
    free = fit_keypoints(hand, moved, options=FitOptions(fit_scale=False), q0=q0)
    held = fit_keypoints(hand, moved, options=FitOptions(fit_scale=False,
                                                         motion_sigma=(1.0, 1.0)), q0=q0)
    assert abs(free.q[6] - far[6]) < 5.0 and abs(held.q[6] - q0[6]) < abs(free.q[6] - q0[6])


def test_a_palm_ippe_puts_behind_the_camera_is_placed_by_sqpnp(hand, camera, posed,
                                                                monkeypatch):
    """When both planar (IPPE) solutions lie behind the camera, as for palms seen nearly
    edge-on on FreiHAND images, the start comes from the general PnP solver, in front of
    the camera and on the keypoints, instead of the fit failing."""
    from digiteyes.detect import model_fit

    q = posed(hand, 0)
    obs = KeypointObservation(camera, camera.project(true_points(hand, q)))
    behind = (2, [np.zeros((3, 1))] * 2, [np.array([[0.0], [0.0], [-300.0]])] * 2, None)
    monkeypatch.setattr(model_fit.cv2, "solvePnPGeneric", lambda *a, **k: behind)
    starts = model_fit.starts_from_image(hand, obs, 1.0)
    assert len(starts) == 1
    palm = camera.to_camera(true_points(hand, starts[0]))[list(PALM)]
    assert (palm[:, 2] > 0).all()
    uv = camera.project(true_points(hand, starts[0]))[list(PALM)]
    assert np.linalg.norm(uv - obs.keypoints[list(PALM)], axis=1).mean() < 15


def test_holding_the_palm_position_fits_the_size_one_camera_cannot_see(hand, camera, posed):
    """A hand 12 % larger than the model, seen by one camera: with the palm held at its
    known position (mm) the fitted scale is the hand's; without it, one camera places
    the model's hand closer instead. The held position's residual and Jacobian (scale
    column included) match finite differences."""
    q = posed(hand, 4)
    truth = true_points(hand, q, 1.12)
    start = q.copy()
    start[4:7] *= 1.12  # the true palm position, mm
    obs = [KeypointObservation(camera, camera.project(truth))]
    held = fit_keypoints(hand, obs, options=FitOptions(fit_scale=True, hold_position_mm=5.0),
                         q0=start)
    assert held.scale == pytest.approx(1.12, abs=0.02)
    gaps = np.linalg.norm(held.keypoints_world - truth, axis=1)
    assert np.median(gaps) < 4.0 and gaps.max() < 10.0  # one view: a finger's depth
    free = fit_keypoints(hand, obs, options=FitOptions(fit_scale=False), q0=start)
    assert np.linalg.norm(free.keypoints_world[9] - truth[9]) > 30.0
    problem = KeypointFitProblem(hand, obs, None, FitOptions(hold_position_mm=5.0), True,
                                 motion_from=start)
    x = np.append(integrate(hand, q, np.linspace(-0.02, 0.03, hand.n_v)), 1.07)
    r, J = problem.residuals(x, True)
    rows = slice(r.size - 4, r.size - 1)  # before the scale's own prior row
    np.testing.assert_allclose(r[rows], (1.07 * x[4:7] - start[4:7]) / 5.0, atol=1e-9)
    eps = 1e-6
    for i in range(problem.n_v):
        step = np.zeros(problem.n_v)
        step[i] = eps
        fd = (problem.residuals(problem.retract(x, step), False)[0][rows]
              - problem.residuals(problem.retract(x, -step), False)[0][rows]) / (2 * eps)
        np.testing.assert_allclose(J[rows, i], fd, atol=1e-6 * np.abs(J[rows]).max())


def test_with_the_active_set_a_fit_against_joint_limits_converges():
    """Keypoints of a hand whose four finger MCPs are hyperextended 0.3 rad beyond their
    limit, a start with three PIPs 0.4 rad off: the fit cannot reach the keypoints, and
    without the active set its steps lean on the limits, are clipped back and rejected,
    so in five iterations it lowers the cost far less than with the MCPs held at their
    limits while the other joints move (docs/solvers.md)."""
    from digiteyes.kinematics import clip_to_limits
    from digiteyes.synth.scenarios import build_scenario

    scenario = build_scenario("desk-1cam", seed=1, n_frames=1)
    model, cam = scenario.model, scenario.rig[0]
    beyond = scenario.states[0].copy()
    for digit in ("index", "middle", "ring", "little"):
        i = model.state_index(f"{digit}.mcp")
        beyond[i] = model.lower[i] - 0.3
    uv = cam.project(true_points(model, beyond))
    start = clip_to_limits(model, beyond)
    for digit in ("index", "middle", "ring"):
        start[model.state_index(f"{digit}.pip")] += 0.4
    fits = {active: fit_keypoints(model, [KeypointObservation(cam, uv)], q0=start,
                                  options=FitOptions(fit_scale=False, iterations=5,
                                                     active_set=active))
            for active in (False, True)}
    assert fits[True].cost < 0.5 * fits[False].cost
    assert np.all(fits[True].q >= model.lower - 1e-12)
    assert np.all(fits[True].q <= model.upper + 1e-12)
