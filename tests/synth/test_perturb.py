"""perturb_model: a "true" model near the tracking model, reproducible by seed."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.synth import RenderError, anchor_chains, perturb_model, render_views


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


def lengths_and_radii(model):
    return (np.array([link.length for link in model.links]),
            np.array([link.radius for link in model.links]))


def first_joint_origins(model, chains):
    """World origins (neutral state) of the frames that follow each anchor chain."""
    kin = forward_kinematics(model, model.neutral())
    rows = [model.rows[chain[-1]].next[0] for chain in chains]
    return kin.T_world_frame[0, rows, :3, 3]


def test_hand_anchor_chains_are_the_constant_rows_before_each_finger(hand):
    assert anchor_chains(hand) == [(1, 2), (8, 9), (15, 16), (22, 23), (29, 30)]


def test_zero_perturbation_is_the_same_model(hand):
    same = perturb_model(hand, rng=0)
    assert same.links == hand.links
    q = hand.neutral()
    q[7:] = 0.3
    np.testing.assert_allclose(forward_kinematics(same, q).T_world_shape,
                               forward_kinematics(hand, q).T_world_shape, atol=1e-12)
    assert same.state_names == hand.state_names
    np.testing.assert_array_equal(same.lower, hand.lower)


def test_lengths_and_radii_change_within_bounds(hand):
    lengths, radii = lengths_and_radii(hand)
    true = perturb_model(hand, link_length=0.1, radius=0.2, rng=3)
    new_lengths, new_radii = lengths_and_radii(true)
    cyl = np.array([link.kind == "link" for link in hand.links])
    length_ratio = new_lengths[cyl] / lengths[cyl]
    radius_ratio = new_radii / radii
    assert (np.abs(length_ratio - 1) <= 0.1 + 1e-12).all()
    assert (np.abs(radius_ratio - 1) <= 0.2 + 1e-12).all()
    assert np.abs(length_ratio - 1).max() > 0.05, "lengths must actually change"
    assert np.abs(radius_ratio - 1).max() > 0.1
    assert len(set(np.round(length_ratio, 12))) == cyl.sum(), "one factor per link"
    for i, link in enumerate(hand.links):
        if link.kind == "tip":  # a tip keeps matching the distal link it ends
            assert radius_ratio[i] == pytest.approx(radius_ratio[i - 1], abs=1e-12)
    palm, new_palm = hand.link("palm"), true.link("palm")
    size_ratio = np.array(new_palm.size) / np.array(palm.size)
    assert (np.abs(size_ratio[:2] - 1) <= 0.1 + 1e-12).all()
    assert abs(size_ratio[2] - 1) <= 0.2 + 1e-12
    assert new_palm.centre == palm.centre


def test_anchor_shift_is_bounded_and_moves_only_the_first_joints(hand):
    chains = anchor_chains(hand)
    before = first_joint_origins(hand, chains)
    true = perturb_model(hand, anchor_mm=4.0, rng=11)
    after = first_joint_origins(true, chains)
    moved = np.linalg.norm(after - before, axis=1)
    assert (moved <= 4.0 + 1e-9).all()
    assert (moved > 1e-6).all()
    assert lengths_and_radii(true)[0].tolist() == lengths_and_radii(hand)[0].tolist()
    # each finger keeps its shape: the offsets from its first joint to its tip are unchanged
    kin_a = forward_kinematics(hand, hand.neutral())
    kin_b = forward_kinematics(true, hand.neutral())
    tips_a, _ = kin_a.tip_centres()
    tips_b, _ = kin_b.tip_centres()
    np.testing.assert_allclose(tips_b - after, tips_a - before, atol=1e-9)


def test_same_seed_same_model_other_seed_other_model(hand):
    a = perturb_model(hand, link_length=0.05, radius=0.05, anchor_mm=3.0, rng=5)
    b = perturb_model(hand, link_length=0.05, radius=0.05, anchor_mm=3.0,
                      rng=np.random.default_rng(5))
    c = perturb_model(hand, link_length=0.05, radius=0.05, anchor_mm=3.0, rng=6)
    assert a.links == b.links and a.links != c.links
    assert a.spec.frames == b.spec.frames
    # the draws do not depend on the fractions: radii-only and lengths-only agree per link
    radii_only = perturb_model(hand, radius=0.05, rng=5)
    assert lengths_and_radii(radii_only)[1].tolist() == lengths_and_radii(a)[1].tolist()


def test_perturbed_model_renders(hand):
    true = perturb_model(hand, link_length=0.1, radius=0.1, anchor_mm=5.0, rng=1)
    cam = Camera.look_at("c", (0.0, 60.0, 450.0), (0.0, 60.0, 0.0), up=(0, 1, 0),
                         width=160, height=120, focal_px=200.0)
    view = render_views(true, hand.neutral(), cam)[0]
    assert (view.labels >= 0).sum() > 500


@pytest.mark.parametrize("kwargs, match", [
    ({"link_length": 1.0}, "link_length"), ({"radius": -0.1}, "radius"),
    ({"anchor_mm": -1.0}, "anchor_mm"), ({"anchor_mm": float("inf")}, "anchor_mm"),
])
def test_bad_fractions_raise(hand, kwargs, match):
    with pytest.raises(RenderError, match=match):
        perturb_model(hand, **kwargs)
