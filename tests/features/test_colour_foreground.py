"""The colour model of the silhouette rule over a textured backdrop: learned at the known
first state, it finds the hand again; it refuses a backdrop dressed in the hand's colours
and grey images."""

import numpy as np
import pytest

from digiteyes.features.colour_foreground import (
    MAX_BACKDROP_SHARE,
    colour_bins,
    fit_colour_foreground,
)
from digiteyes.features.foreground import MARGIN_PX, fit_foreground, model_labels
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import forward_kinematics


@pytest.fixture(scope="module")
def clutter(desk_clutter):
    """The shared colour desk view over clutter (tests/conftest.py) with the model's
    labels at the first state: (labels, image)."""
    model, rig, q, image, _ = desk_clutter
    return model_labels(model, forward_kinematics(model, q), rig.cameras[0]), image


def test_the_colour_model_finds_the_hand_over_clutter(clutter):
    labels, image = clutter
    assert fit_foreground(prepare_image(image), labels) is None  # no grey threshold here
    fg = fit_colour_foreground(image, labels, MARGIN_PX)
    assert fg is not None and fg.hand_recall >= 0.9
    assert fg.backdrop_share <= MAX_BACKDROP_SHARE
    mask, hand = fg.mask(image), labels >= 0
    assert (mask & hand).sum() / hand.sum() > 0.85  # the hand's pixels are found
    assert (mask & ~hand).sum() / (~hand).sum() < MAX_BACKDROP_SHARE  # little else


def test_the_mask_reads_the_bins_it_learned(clutter):
    """The mask is the table at each pixel's bin: a pixel whose colour the model calls
    hand is hand wherever it stands."""
    labels, image = clutter
    fg = fit_colour_foreground(image, labels, MARGIN_PX)
    bins = colour_bins(image)
    assert bins.shape == image.shape[:2] and 0 <= bins.min() and bins.max() < fg.is_hand.size
    np.testing.assert_array_equal(fg.mask(image), fg.is_hand[bins])


def test_a_backdrop_in_the_hands_colours_is_refused(clutter):
    labels, image = clutter
    hand = labels >= 0
    dressed = image.copy()
    rng = np.random.default_rng(0)
    colours = image[hand]
    band = np.zeros(hand.shape, bool)
    band[:, : hand.shape[1] // 4] = True  # a quarter of the frame, skin-coloured noise
    band &= ~hand
    dressed[band] = colours[rng.integers(0, len(colours), band.sum())]
    assert fit_colour_foreground(dressed, labels, MARGIN_PX) is None


def test_grey_images_and_empty_splits_give_no_model(clutter):
    labels, image = clutter
    assert fit_colour_foreground(prepare_image(image), labels, MARGIN_PX) is None
    assert fit_colour_foreground(image, np.full(labels.shape, -1), MARGIN_PX) is None
