"""Per-digit resampling: each digit's joints drawn by its own share of the likelihood."""

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.smc.digit_resampling import best_of_each_digit, digit_of, digit_resample
from digiteyes.smc.likelihood import (
    FingerGeometry,
    LikelihoodOptions,
    finger_log_likelihood,
    observe_edges,
)
from digiteyes.smc.prior import default_configuration_space
from digiteyes.synth import render_views


@pytest.mark.parametrize("search", ["normal", "distance"])
def test_each_patch_share_sums_to_the_likelihood_and_stays_with_its_digit(
        natural_cardboard, search):
    """``per_link`` adds up to ``log p(Z | X)``; bending the index of the open hand (no
    patch hides another) changes the index patches' shares only."""
    model, cam, states = natural_cardboard
    geometry = FingerGeometry.of(model)
    q = states[0]
    edges = observe_edges(render_views(model, q, [cam], rng=1)[0].image)
    Q = np.repeat(q[None], 2, axis=0)
    Q[1, model.state_index("index.pip")] += np.radians(30.0)
    options = LikelihoodOptions(search=search)
    result = finger_log_likelihood(model, geometry, Q, [cam], [edges], options,
                                   per_link=True)
    plain = finger_log_likelihood(model, geometry, Q, [cam], [edges], options)
    assert plain.per_link is None
    np.testing.assert_allclose(result.per_link.sum(axis=1), result.log_likelihood,
                               rtol=1e-9)
    np.testing.assert_array_equal(result.log_likelihood, plain.log_likelihood)
    index = digit_of(geometry.link_names) == DIGITS.index("index")
    np.testing.assert_array_equal(result.per_link[0, ~index], result.per_link[1, ~index])
    assert result.per_link[1, index].sum() < result.per_link[0, index].sum() - 5.0


def test_each_digit_comes_from_the_hypothesis_that_explains_it(natural_cardboard):
    """Five digits, three hypotheses: digit d's factor strongly favours hypothesis d % 3,
    so every new particle carries each digit's joints from that hypothesis, and so does
    the best of each digit."""
    model = natural_cardboard[0]
    space = default_configuration_space(model)
    X = np.random.default_rng(0).normal(0.0, 0.5, (3, space.n_dims))
    factors = np.zeros((3, len(DIGITS)))
    for d in range(len(DIGITS)):
        factors[d % 3, d] = 60.0
    out = digit_resample(space, X, factors, np.random.default_rng(1), 8)
    joints = space.to_joints(X)
    expected = np.empty(joints.shape[1])
    digit = digit_of(space.joint_names)
    for d in range(len(DIGITS)):
        expected[digit == d] = joints[d % 3, digit == d]
    assert out.shape == (8, space.n_dims)
    np.testing.assert_allclose(out, np.repeat(space.to_coordinates(expected)[None], 8, 0),
                               atol=1e-12)
    again = digit_resample(space, X, factors, np.random.default_rng(1), 8)
    np.testing.assert_array_equal(out, again)  # a pure function of its inputs
    np.testing.assert_allclose(best_of_each_digit(space, X, factors),
                               space.to_coordinates(expected), atol=1e-12)


def test_bad_inputs_say_what_was_expected(natural_cardboard):
    space = default_configuration_space(natural_cardboard[0])
    with pytest.raises(DigitEyesError, match=r"expected \(4, 5\)"):
        digit_resample(space, np.zeros((4, space.n_dims)), np.zeros((4, 3)),
                       np.random.default_rng(0), 4)
    with pytest.raises(DigitEyesError, match="belongs to no digit"):
        digit_of(["wrist.flex"])
