"""The deformation's Jacobian: part twists against the kinematic point Jacobian, and the
pixel motion of template points against finite differences through ``integrate``."""

import numpy as np

from digiteyes.kinematics import forward_kinematics, integrate, load_model, point_jacobian
from digiteyes.occlusion.parts import facing_plane, template_grid, template_parts
from digiteyes.templates.deformation import part_twists
from digiteyes.templates.layered import world_points


def _random_hand_state(model, rng):
    q = model.neutral()
    q[:4] = rng.normal(size=4)
    q[:4] /= np.linalg.norm(q[:4])
    q[4:7] = rng.uniform(-50, 50, 3)
    joints = np.array([k == "angle" for k in model.state_kinds])
    q[joints] = rng.uniform(-0.6, 0.6, joints.sum())
    return q


def test_twists_reproduce_point_jacobian_on_the_hand():
    hand = load_model("hand")
    rng = np.random.default_rng(3)
    parts = template_parts(hand)
    kin = forward_kinematics(hand, _random_hand_state(hand, rng))
    tw = part_twists(parts, kin)
    for k, part in enumerate(parts):
        p_shape = rng.uniform(-30, 30, (5, 3))
        p, J = point_jacobian(kin, np.full(5, part.row), p_shape)
        from_twist = np.cross(tw[k, :3].T[None], p[:, None, :]).transpose(0, 2, 1) \
            + tw[k, 3:][None]
        np.testing.assert_allclose(from_twist, J, atol=1e-9 * max(1.0, np.abs(J).max()))


def test_template_pixel_motion_matches_finite_differences():
    from digiteyes.synth.scenarios import build_scenario

    scenario = build_scenario("natural", n_frames=1)
    hand, cam = scenario.model, scenario.rig[0]
    q = scenario.states[0]
    kin = forward_kinematics(hand, q)
    parts = template_parts(hand)
    part = parts[3]
    plane = facing_plane(part, kin, cam)
    p_shape = plane.points(template_grid(part, 4.0))
    rows = np.full(len(p_shape), part.row)
    p, J = point_jacobian(kin, rows, p_shape)
    _, Jp = cam.project_with_jacobian(p)
    analytic = np.einsum("pij,pjk->pik", Jp, J)
    h = 1e-6
    for c in range(hand.n_v):
        e = np.zeros(hand.n_v)
        e[c] = h
        plus = cam.project(point_jacobian(forward_kinematics(hand, integrate(hand, q, e)),
                                          rows, p_shape)[0])
        minus = cam.project(point_jacobian(forward_kinematics(hand, integrate(hand, q, -e)),
                                           rows, p_shape)[0])
        np.testing.assert_allclose((plus - minus) / (2 * h), analytic[:, :, c],
                                   atol=1e-4 * max(1.0, np.abs(analytic).max()))


def test_world_points_follow_the_shape_frames():
    hand = load_model("hand")
    kin = forward_kinematics(hand, _random_hand_state(hand, np.random.default_rng(1)))
    from digiteyes.templates.layered import CameraTemplates

    parts = template_parts(hand)[:3]
    ab = np.zeros((6, 2))
    part_of = np.repeat(np.arange(3), 2)
    templates = CameraTemplates(parts, ab, part_of, [slice(0, 2), slice(2, 4), slice(4, 6)],
                                np.zeros(6, np.float32), np.zeros(6, np.float32),
                                np.ones(6, np.float32), np.zeros(3), np.tile(np.eye(3), (3, 1, 1)))
    p_shape = np.random.default_rng(2).normal(size=(6, 3))
    expected = point_jacobian(kin, np.array([parts[k].row for k in part_of]), p_shape)[0]
    np.testing.assert_allclose(world_points(templates, kin, p_shape), expected, atol=1e-9)
