"""Edge likelihood (Huang Sec. 5.2) on a rendered frame, with the occlusion map."""

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.smc.likelihood import (
    FingerGeometry,
    LikelihoodOptions,
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
