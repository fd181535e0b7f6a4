"""Silhouette consistency of a foreground mask and a model label raster."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.features.silhouette import silhouette_mismatch


def test_fractions_of_overlapping_rectangles():
    labels = np.full((480, 640), -1, np.int16)
    labels[100:300, 200:400] = 3  # 200 x 200 model pixels
    labels[100:150, 200:400] = 5  # of which 50 x 200 are link 5
    fg = np.zeros((480, 640), bool)
    fg[150:300, 200:450] = True  # 150 x 250 foreground
    m = silhouette_mismatch(fg, labels, 8)
    assert m.model_pixels == 40000 and m.foreground_pixels == 37500
    assert m.foreground_only == 150 * 50 and m.model_only == 50 * 200
    assert m.unexplained_foreground == pytest.approx(7500 / 37500)
    assert m.unexplained_model == pytest.approx(10000 / 40000)
    assert m.per_label_outside.tolist() == [0, 0, 0, 0, 0, 10000, 0, 0]
    assert m.per_label_pixels[3] == 30000


def test_empty_and_mismatched_inputs():
    m = silhouette_mismatch(np.zeros((4, 4), np.uint8), np.full((4, 4), -1))
    assert m.unexplained_foreground == 0.0 and m.unexplained_model == 0.0
    with pytest.raises(DigitEyesError, match="same size"):
        silhouette_mismatch(np.zeros((4, 4)), np.zeros((4, 5)))


def test_flesh_against_model_silhouette():
    from digiteyes import load_model
    from digiteyes.benchmarks.render import relaxed_hand_state
    from digiteyes.camera import Camera
    from digiteyes.synth import RenderOptions, render_views

    hand = load_model("hand")
    q = relaxed_hand_state(hand)
    cam = Camera.look_at("c", (-150.0, 40.0, 520.0), (0, 40, 0), up=(0, 1, 0),
                         width=320, height=240, focal_px=400)
    model = render_views(hand, q, cam)[0]
    flesh = render_views(hand, q, cam, RenderOptions(appearance="flesh"))[0]
    same = silhouette_mismatch(model.labels >= 0, model.labels)
    assert same.foreground_only == 0 and same.model_only == 0
    m = silhouette_mismatch(flesh.labels >= 0, model.labels, len(hand.links))
    assert 0.02 < m.unexplained_foreground < 0.5 and m.unexplained_model < 0.3
