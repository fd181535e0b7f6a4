"""Edge likelihood (Huang Sec. 5.2) on a rendered frame, with the occlusion map."""

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics
from digiteyes.smc.likelihood import (
    FingerGeometry,
    LikelihoodOptions,
    edge_lookup,
    finger_log_likelihood,
    observe_edges,
)
from digiteyes.smc.prior import default_configuration_space
from digiteyes.synth import render_views


@pytest.mark.parametrize("search", ["distance", "normal"])
def test_true_pose_beats_perturbed_ones(natural_cardboard, search):
    model, cam, states = natural_cardboard
    q = states[30]
    geometry = FingerGeometry.of(model)
    edges = observe_edges(render_views(model, q, [cam], rng=1)[0].image)
    idx = default_configuration_space(model).joint_indices(model)
    rng = np.random.default_rng(0)
    Q = np.repeat(q[None], 400, axis=0)
    Q[1:, idx] += rng.normal(0.0, np.radians(15.0), (399, len(idx)))
    options = LikelihoodOptions(search=search)
    result = finger_log_likelihood(model, geometry, Q, [cam], [edges], options)
    assert np.argmax(result.log_likelihood) == 0
    assert result.rms_px[0] < 1.5
    assert result.with_edge[0] > 0.9 * result.visible[0]
    # Larger errors, lower likelihood (on average).
    err = np.abs(Q[:, idx] - q[idx]).mean(axis=1)
    assert np.corrcoef(err, result.log_likelihood)[0, 1] < -0.3


def test_occlusion_map_drops_hidden_points(natural_cardboard):
    model, cam, states = natural_cardboard
    geometry = FingerGeometry.of(model)
    edges = np.zeros((cam.height, cam.width), np.uint8)
    q_open = states[0].copy()
    q_fist = q_open.copy()
    for finger in ("index", "middle", "ring", "little"):
        for joint, deg in (("mcp", 85), ("pip", 100), ("dip", 70)):
            q_fist[model.state_index(f"{finger}.{joint}")] = np.radians(deg)
    r = finger_log_likelihood(model, geometry, np.stack([q_open, q_fist]), [cam], [edges])
    assert r.visible[1] < r.visible[0]                    # curled fingers hide each other
    np.testing.assert_array_equal(r.log_likelihood, 0.0)  # no edges: factor 1 everywhere


def test_distance_lookup_ranks_like_the_normal_search(natural_cardboard):
    model, cam, states = natural_cardboard
    q = states[30]
    geometry = FingerGeometry.of(model)
    edges = observe_edges(render_views(model, q, [cam], rng=1)[0].image)
    idx = default_configuration_space(model).joint_indices(model)
    Q = np.repeat(q[None], 200, axis=0)
    Q[1:, idx] += np.random.default_rng(1).normal(0.0, np.radians(10.0), (199, len(idx)))
    by = {s: finger_log_likelihood(model, geometry, Q, [cam], [edges],
                                   LikelihoodOptions(search=s)) for s in ("distance", "normal")}
    np.testing.assert_array_equal(by["distance"].visible, by["normal"].visible)
    assert np.corrcoef(by["distance"].log_likelihood, by["normal"].log_likelihood)[0, 1] > 0.9
    with pytest.raises(DigitEyesError, match="search"):
        LikelihoodOptions(search="along")


def _reference_log_likelihood(model, geometry, q, cam, edges, options):
    """Huang Sec. 5.2 written plainly (normal search, occlusion by every other patch and
    the palm quad), for one state: the compiled kernel must agree with it."""

    shapes = forward_kinematics(model, q[None]).T_world_shape[0]
    T = shapes[geometry.link_rows]
    starts = T[:, :3, 3]
    ends = starts + T[:, :3, 0] * geometry.lengths[:, None]
    P = shapes[geometry.palm_row]
    palm = geometry.palm_outline @ P[:3, :3].T + P[:3, 3]
    a, b, pq = cam.project(starts), cam.project(ends), cam.project(palm)
    za, zb, zp = cam.depth(starts), cam.depth(ends), cam.depth(palm)
    fx, margin, hw = cam.K[0, 0], options.occlusion_margin_mm, int(options.search_px)
    h, w = edges.shape

    def palm_depth(p):
        for i, j in ((1, 2), (2, 3)):
            m = np.array([[pq[i, 0] - pq[0, 0], pq[j, 0] - pq[0, 0]],
                          [pq[i, 1] - pq[0, 1], pq[j, 1] - pq[0, 1]]])
            if abs(np.linalg.det(m)) < 1e-12:
                continue
            s, t = np.linalg.solve(m, p - pq[0])
            if s >= 0 and t >= 0 and s + t <= 1:
                return zp[0] + s * (zp[i] - zp[0]) + t * (zp[j] - zp[0])
        return np.inf

    def hidden(li, p, cz):
        if palm_depth(p) < cz - margin:
            return True
        for m in range(len(starts)):
            if geometry.skip[li, m]:
                continue
            e = b[m] - a[m]
            tau = np.clip((p - a[m]) @ e / max(e @ e, 1e-300), 0.0, 1.0)
            mz = za[m] + tau * (zb[m] - za[m])
            if 0 < mz < cz - margin and np.linalg.norm(a[m] + tau * e - p) < \
                    geometry.radii[m] * fx / mz:
                return True
        return False

    gauss = np.exp(-np.arange(hw + 1) ** 2 / (2 * options.sigma_px ** 2))
    total, visible = 0.0, 0
    ts = (np.arange(options.points_per_link) + 0.5) / options.points_per_link
    for li in range(len(starts)):
        d = b[li] - a[li]
        if np.linalg.norm(d) < 1e-6:
            continue
        n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        for t in ts:
            c, cz = a[li] + t * d, za[li] + t * (zb[li] - za[li])
            for sign in (1.0, -1.0):
                p = c + sign * geometry.radii[li] * fx / cz * n
                if not (0 <= p[0] <= w - 1 and 0 <= p[1] <= h - 1) or hidden(li, p, cz):
                    continue
                visible += 1
                acc = 0.0
                for o in range(-hw, hw + 1):
                    ix, iy = int(p[0] + o * n[0] + 0.5), int(p[1] + o * n[1] + 0.5)
                    if 0 <= ix < w and 0 <= iy < h and edges[iy, ix]:
                        acc += gauss[abs(o)]
                total += np.log1p(acc * options.inverse_clutter)
    return total, visible


@pytest.mark.parametrize("with_lookup", [False, True])
def test_the_compiled_likelihood_matches_a_plain_reference(natural_cardboard, with_lookup):
    """The kernel's shortcuts (occluders chosen per particle from image boxes, a branch-free
    search, unchecked reads where the whole search lies inside the image and, given the
    frame's lookup, no search from a point far from every edge) change nothing:
    log-likelihood and visible points as the plain loops give, for a hand half out of
    the frame too."""
    model, cam, states = natural_cardboard
    assert cam.projection == "perspective"
    geometry = FingerGeometry.of(model)
    options = LikelihoodOptions()
    edges = observe_edges(render_views(model, states[30], [cam], rng=1)[0].image)
    edges[:, :3] = 255  # a read past the right border would find the next row's edges
    idx = default_configuration_space(model).joint_indices(model)
    Q = np.repeat(states[30][None], 7, axis=0)
    Q[1:, idx] += np.random.default_rng(2).normal(0.0, np.radians(25.0), (6, len(idx)))
    Q[5, idx] = np.radians(80.0)  # a fist: fingers hide each other and the palm
    Q[6, model.state_index("palm.x")] -= 150.0  # the fingers run off the right border
    lookups = [edge_lookup(edges, options)] if with_lookup else None
    result = finger_log_likelihood(model, geometry, Q, [cam], [edges], options, lookups)
    right = cam.project(forward_kinematics(model, Q[6:]).T_world_shape[0][:, :3, 3])[:, 0]
    assert right.max() > cam.width > right.min()
    for k, q in enumerate(Q):
        total, visible = _reference_log_likelihood(model, geometry, q, cam, edges, options)
        assert result.visible[k] == visible
        assert result.log_likelihood[k] == pytest.approx(total, rel=1e-9, abs=1e-9)


def test_finger_width_fit_finds_a_thinner_drawing():
    """Edges drawn from the model with every finger patch 20 % thinner: the fit finds
    0.8 (to its 0.05 grid); the model's own drawing gives 1."""
    import dataclasses

    from digiteyes import load_model
    from digiteyes.kinematics import KinematicModel
    from digiteyes.kinematics.model_file import ShapeSpec
    from digiteyes.smc.likelihood import FingerGeometry, fit_finger_width
    from digiteyes.synth.scenarios import build_scenario

    scenario = build_scenario("natural", n_frames=1)
    model = load_model("cardboard-hand")
    q = np.delete(scenario.states[0], scenario.model.state_index("thumb.mp_abd"))
    cam = scenario.rig.cameras[0]
    geometry = FingerGeometry.of(model)
    own = [observe_edges(render_views(model, q, [cam], rng=0)[0].image)]
    assert fit_finger_width(model, geometry, q, [cam], own) == 1.0
    frames = tuple(dataclasses.replace(row, shape=ShapeSpec("cyl", (0.8 * row.shape.params[0],)))
                   if row.shape is not None and row.shape.kind == "cyl" else row
                   for row in model.spec.frames)
    thin = KinematicModel(dataclasses.replace(model.spec, frames=frames))
    edges = [observe_edges(render_views(thin, q, [cam], rng=0)[0].image)]
    assert abs(fit_finger_width(model, geometry, q, [cam], edges) - 0.8) <= 0.051
