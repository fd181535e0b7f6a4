"""Resampling statistics and the manifold proposal (Huang eq. 3-6), seeded."""

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.smc.manifolds import manifold_pairs, project_onto_manifolds
from digiteyes.smc.proposal import ProposalOptions, propose_on_manifolds
from digiteyes.smc.resample import (
    effective_sample_size,
    normalised_weights,
    systematic_resample,
)


def test_systematic_resampling_counts_follow_weights():
    rng = np.random.default_rng(7)
    w = rng.uniform(size=40) ** 3
    w /= w.sum()
    for _ in range(20):
        idx = systematic_resample(w, rng, 1000)
        counts = np.bincount(idx, minlength=40)
        assert np.all(np.abs(counts - 1000 * w) <= 1.0 + 1e-9)
    # Pure function of (weights, rng state).
    a = systematic_resample(w, np.random.default_rng(1))
    b = systematic_resample(w, np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)
    # Unbiased over draws: mean count approaches N w.
    rng = np.random.default_rng(2)
    mean = np.mean([np.bincount(systematic_resample(w, rng, 40), minlength=40)
                    for _ in range(4000)], axis=0)
    np.testing.assert_allclose(mean, 40 * w, atol=0.05)


def test_weights_and_errors():
    w = normalised_weights(np.array([0.0, -np.inf, 1000.0]))
    np.testing.assert_allclose(w, [0.0, 0.0, 1.0])
    assert effective_sample_size(np.full(10, 0.1)) == pytest.approx(10)
    with pytest.raises(DigitEyesError):
        systematic_resample(np.array([0.5, -0.1]), np.random.default_rng(0))
    with pytest.raises(DigitEyesError):
        normalised_weights(np.array([np.nan, -np.inf]))


def test_manifold_proposal_stays_near_manifolds_and_mixes_at_basis():
    rng = np.random.default_rng(4)
    basis = rng.normal(size=(5, 3)) * 2
    pairs = manifold_pairs(5)
    opt = ProposalOptions(sigma_s=0.1, walk_sigma=0.01, basis_radius=0.05)
    start = np.repeat((0.4 * basis[0] + 0.6 * basis[2])[None], 4000, axis=0)
    prop = propose_on_manifolds(start, basis, rng, opt, pairs)
    assert set(pairs[np.unique(prop.pair)].ravel()) == {0, 2}
    assert prop.s_from == pytest.approx(0.4)
    assert np.std(prop.s_to - prop.s_from) == pytest.approx(0.1, rel=0.05)
    assert np.all(project_onto_manifolds(prop.X, basis, pairs).distance < 0.06)
    # At a basis state every manifold through it is used, about equally often.
    at = np.repeat(basis[3][None], 8000, axis=0)
    prop = propose_on_manifolds(at, basis, rng, opt, pairs)
    used = np.bincount(prop.pair, minlength=len(pairs))
    through = np.flatnonzero((pairs == 3).any(axis=1))
    assert set(np.flatnonzero(used)) == set(through)
    np.testing.assert_allclose(used[through] / 8000, 0.25, atol=0.03)
    # Same generator state, same draws.
    a = propose_on_manifolds(start[:5], basis, np.random.default_rng(9), opt, pairs)
    b = propose_on_manifolds(start[:5], basis, np.random.default_rng(9), opt, pairs)
    np.testing.assert_array_equal(a.X, b.X)
