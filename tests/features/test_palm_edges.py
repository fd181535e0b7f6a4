"""Tracked body edges (shape ``edge``): the hand's palm sides are measured, never drawn."""

from __future__ import annotations

import numpy as np

from digiteyes import forward_kinematics, load_model
from digiteyes.camera import Camera
from digiteyes.features import feature_residuals, measure_features
from digiteyes.kinematics.keypoints import keypoint_names
from digiteyes.synth import render_views

EDGES = ("palm.radial_edge", "palm.ulnar_edge", "palm.wrist_edge")


def test_palm_edges_are_links_of_kind_edge_on_the_slab_border() -> None:
    hand = load_model("hand")
    kin = forward_kinematics(hand, hand.neutral())
    palm = hand.link("palm")
    half = 0.5 * np.array(palm.size)
    for name in EDGES:
        edge = hand.link(name)
        assert edge.kind == "edge" and edge.radius == half[2]
        start = kin.T_world_shape[0, edge.row, :3, 3]
        end = start + edge.length * kin.T_world_shape[0, edge.row, :3, 0]
        for point in (start, end):  # axis ends sit one radius inside the slab's outline
            inset = half[:2] - np.abs(point[:2] - np.array(palm.centre[:2]))
            assert np.isclose(inset.min(), edge.radius) and abs(point[2]) < 1e-9
    assert not set(EDGES) & {n.removesuffix(".base") for n in keypoint_names(hand)}


def test_palm_edges_are_measured_at_the_true_state_and_never_labelled() -> None:
    hand = load_model("hand")
    q = hand.neutral()
    q[7:] = np.radians(10.0) * (hand.upper[7:] > 0)
    cam = Camera.look_at("c", eye=(120, -250, 420), target=(0, 30, 0), up=(0, 1, 0))
    view = render_views(hand, q, cam)[0]
    edge_ids = [i for i, link in enumerate(hand.links) if link.kind == "edge"]
    assert not np.isin(view.labels, edge_ids).any()
    kin = forward_kinematics(hand, q)
    meas = measure_features(view.image, cam, hand, kin, links=EDGES, tips=())
    assert meas.link_valid.sum() >= 2, meas.link_reason
    r, _, _ = feature_residuals(meas, cam, kin)
    assert np.sqrt(np.mean(r**2)) < 1.5
