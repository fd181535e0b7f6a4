"""Window outlines and their Jacobians against finite differences through ``integrate``."""

import numpy as np

from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.occlusion.parts import facing_plane, template_parts
from digiteyes.occlusion.windows import CAPSULE, POLYGON, image_windows
from digiteyes.synth.scenarios import build_scenario


def test_window_jacobians_match_finite_differences():
    scenario = build_scenario("natural", n_frames=40)
    model, cam = scenario.model, scenario.rig[1]
    q = scenario.states[35]
    kin = forward_kinematics(model, q)
    parts = template_parts(model)
    planes = [facing_plane(p, kin, cam) for p in parts]
    w = image_windows(parts, planes, kin, cam)
    assert set(w.kind) == {CAPSULE, POLYGON}
    h = 1e-6
    for c in range(model.n_v):
        e = np.zeros(model.n_v)
        e[c] = h
        plus = image_windows(parts, planes, forward_kinematics(model, integrate(model, q, e)),
                             cam)
        minus = image_windows(parts, planes,
                              forward_kinematics(model, integrate(model, q, -e)), cam)
        np.testing.assert_allclose((plus.points - minus.points) / (2 * h),
                                   w.d_points[..., c], atol=1e-4 * np.abs(w.d_points).max())
        np.testing.assert_allclose((plus.radius - minus.radius) / (2 * h), w.d_radius[:, c],
                                   atol=1e-6 * max(1.0, np.abs(w.d_radius).max()))


def test_capsule_radius_is_the_projected_link_radius():
    scenario = build_scenario("two-finger-occlusion", n_frames=1)
    model, cam = scenario.model, scenario.rig[0]
    kin = forward_kinematics(model, scenario.states[0])
    parts = template_parts(model)
    w = image_windows(parts, [facing_plane(p, kin, cam) for p in parts], kin, cam)
    k = next(i for i, p in enumerate(parts) if p.name == "index.proximal")
    z = w.depth[k, :2].mean()
    assert abs(w.radius[k] - parts[k].radius * cam.K[0, 0] / z) < 1e-9
