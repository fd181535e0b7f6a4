"""Configuration space (Huang Sec. 2, eq. 1): PCA, basis configurations, manifolds."""

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.smc.configuration import ConfigurationSpace, PriorError, fit_configuration_space
from digiteyes.smc.manifolds import (
    basis_joint_angles,
    basis_names,
    manifold_pairs,
    project_onto_manifolds,
)
from digiteyes.smc.prior import default_configuration_space, glove_joint_angles


def test_basis_has_28_configurations_without_lone_ring_finger():
    names = basis_names()
    assert len(names) == 28 and len(set(names)) == 28
    assert not any(n[3] == "E" and n[2] == "C" and n[4] == "C" for n in names)
    assert len(manifold_pairs(28)) == 28 * 27 // 2


def test_pca_round_trip_is_exact_with_all_dimensions():
    rng = np.random.default_rng(3)
    names = tuple(f"j{i}" for i in range(6))
    samples = rng.normal(size=(200, 6)) @ rng.normal(size=(6, 6))
    space = fit_configuration_space(samples, names, samples[:3], ("a", "b", "c"),
                                    np.full(6, -np.inf), np.full(6, np.inf), n_dims=6)
    back = space.to_joints(space.to_coordinates(samples))
    np.testing.assert_allclose(back, samples, atol=1e-10)
    np.testing.assert_allclose(space.components @ space.components.T, np.eye(6), atol=1e-12)
    assert space.kept_variance()[-1] == pytest.approx(1.0)


def test_default_prior_keeps_basis_and_is_deterministic(tmp_path):
    model = load_model("cardboard-hand")
    space = default_configuration_space(model)
    assert space.n_dims == 7 and len(space.joint_names) == 20
    assert space.kept_variance()[6] > 0.95
    joints = basis_joint_angles(space.joint_names)
    err = np.abs(space.to_joints(space.basis) - np.clip(joints, space.lower, space.upper))
    assert np.degrees(err.max()) < 2.0
    path = space.save(tmp_path / "prior.npz")
    again = ConfigurationSpace.load(path)
    np.testing.assert_array_equal(again.basis, space.basis)
    assert again.joint_names == space.joint_names
    hand = default_configuration_space(load_model("hand"))
    assert "thumb.mp_abd" in hand.joint_names and len(hand.joint_names) == 21


def test_projection_onto_manifolds_matches_brute_force():
    rng = np.random.default_rng(0)
    basis = rng.normal(size=(6, 3))
    pairs = manifold_pairs(6)
    X = rng.normal(size=(15, 3))
    proj = project_onto_manifolds(X, basis, pairs)
    s = np.linspace(0, 1, 20001)
    for n in range(len(X)):
        best = min(np.min(np.linalg.norm(
            s[:, None] * basis[i] + (1 - s[:, None]) * basis[j] - X[n], axis=1))
            for i, j in pairs)
        assert proj.distance[n] == pytest.approx(best, abs=1e-3)
        i, j = pairs[proj.pair[n]]
        point = proj.s[n] * basis[i] + (1 - proj.s[n]) * basis[j]     # Huang eq. 4
        np.testing.assert_allclose(point, proj.projected[n], atol=1e-12)
    on = 0.3 * basis[1] + 0.7 * basis[4]
    p = project_onto_manifolds(on, basis, pairs)
    assert tuple(pairs[p.pair[0]]) == (1, 4) and p.s[0] == pytest.approx(0.3)


def test_glove_mapping_signs_and_bad_input():
    """The prior reads glove recordings through the scenarios' mapping: flexion turns
    positive, abduction is taken from its median, a joint without a sensor stays 0."""
    from digiteyes.synth.glove import glove_to_states
    model = load_model("hand")
    glove = np.zeros((3, 23))
    glove[:, 4] = -1.0                      # I MCP flexed (glove: negative)
    glove[:, 7] = [0.0, 0.1, 0.2]           # I ABD: median 0.1
    names = ("index.mcp", "index.abd", "thumb.mp_abd")
    out = glove_joint_angles(model, glove, names)
    np.testing.assert_allclose(out[:, 0], 1.0)
    np.testing.assert_allclose(out[:, 1], np.radians(-8.0) - np.array([-0.1, 0.0, 0.1]))
    np.testing.assert_allclose(out[:, 2], 0.0)
    np.testing.assert_array_equal(out, glove_to_states(model, glove)[
        :, [model.state_index(n) for n in names]])
    with pytest.raises(PriorError, match="samples must be"):
        fit_configuration_space(np.zeros((10, 3)), ("a", "b"), np.zeros((1, 2)), ("x",),
                                np.zeros(2), np.ones(2))
