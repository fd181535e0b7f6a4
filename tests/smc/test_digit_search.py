"""The digit-by-digit search (:mod:`digiteyes.smc.digit_search`)."""

import numpy as np

from digiteyes import load_model
from digiteyes.smc.digit_search import DigitSearchOptions, digit_curl_directions, search_digits
from digiteyes.smc.likelihood import FingerGeometry, finger_log_likelihood, observe_edges
from digiteyes.smc.prior import default_configuration_space
from digiteyes.synth import render_views


def test_curl_directions_move_one_digit_each():
    space = default_configuration_space(load_model("cardboard-hand"))
    directions = digit_curl_directions(space)
    assert directions.shape == (5, len(space.joint_names))
    for d, digit in enumerate(("thumb", "index", "middle", "ring", "little")):
        moved = {space.joint_names[j] for j in np.flatnonzero(directions[d])}
        assert moved and all(name.startswith(digit + ".") for name in moved)
    index_pip = space.joint_names.index("index.pip")
    assert np.degrees(directions[1, index_pip]) > 80.0     # curling flexes the PIP


def test_finds_a_single_digit_move_of_a_quadratic_score():
    space = default_configuration_space(load_model("cardboard-hand"))
    directions = digit_curl_directions(space)
    start = space.basis[space.basis_names.index("EEEEE")]
    target = space.to_coordinates(space.to_joints(start) + 0.3 * directions[2])

    def score(X, palm):
        return -np.sum((np.atleast_2d(X) - target) ** 2, axis=1)

    x, palm, new, old = search_digits(space, start, score, DigitSearchOptions(steps=(-0.3, 0.3)))
    assert old < new and np.allclose(x, target, atol=1e-9) and palm == 0
    # nothing better nearby: the start comes back unchanged
    x2, _, new2, old2 = search_digits(space, target, score)
    assert new2 == old2 and np.array_equal(x2, target)


def test_combines_moves_of_two_digits():
    space = default_configuration_space(load_model("cardboard-hand"))
    directions = digit_curl_directions(space)
    # index extended (curl it), little curled (open it): both moves inside the limits
    start = space.basis[space.basis_names.index("EEEEC")]
    joints = space.to_joints(start)
    target = space.to_coordinates(joints + 0.3 * directions[1] - 0.3 * directions[4])

    def score(X, palm):
        return -np.sum((np.atleast_2d(X) - target) ** 2, axis=1)

    x, _, new, _ = search_digits(space, start, score, DigitSearchOptions(steps=(-0.3, 0.3)))
    assert np.allclose(x, target, atol=1e-6) and abs(new) < 1e-9


def test_picks_the_palm_under_which_a_move_scores_best():
    """Three palms: the move to the target pays under palm 2 only (its score has a bonus
    there), so the search returns that palm and that move together."""
    space = default_configuration_space(load_model("cardboard-hand"))
    directions = digit_curl_directions(space)
    start = space.basis[space.basis_names.index("EEEEE")]
    target = space.to_coordinates(space.to_joints(start) + 0.3 * directions[3])
    bonus = np.array([0.0, -1.0, 0.5])

    def score(X, palm):
        return -np.sum((np.atleast_2d(X) - target) ** 2, axis=1) + bonus[palm]

    x, palm, new, old = search_digits(space, start, score, DigitSearchOptions(steps=(0.3,)),
                                      n_palms=3)
    assert palm == 2 and np.allclose(x, target, atol=1e-9)
    assert np.isclose(new, 0.5) and np.isclose(old, score(start[None], np.zeros(1, int))[0])


def test_recovers_a_curled_finger_on_a_rendered_frame():
    """A frame of the open hand; the hypothesis has the index finger 60 % curled. The
    search on the frame's likelihood opens it again to within 10 degrees per joint."""
    from digiteyes.synth.scenarios import build_scenario
    model = load_model("cardboard-hand")
    scenario = build_scenario("natural", n_frames=2)
    states = np.delete(scenario.states, scenario.model.state_index("thumb.mp_abd"), axis=1)
    cam, q = scenario.rig.cameras[0], states[0]
    space = default_configuration_space(model)
    idx = space.joint_indices(model)
    geometry = FingerGeometry.of(model)
    edges = [observe_edges(render_views(model, q, [cam], rng=0)[0].image)]

    def score(X, palm):
        return finger_log_likelihood(model, geometry, space.states(model, q, X), [cam],
                                     edges).log_likelihood

    truth = space.to_coordinates(q[idx])
    wrong = space.to_coordinates(space.to_joints(truth) + 0.6 * digit_curl_directions(space)[1])
    x, _, new, old = search_digits(space, wrong, score)
    assert new > old
    index = [j for j, n in enumerate(space.joint_names) if n.startswith("index.")]
    error = np.degrees(np.abs(space.to_joints(x) - q[idx]))[index]
    assert error.max() < 10.0, np.round(error, 1)
