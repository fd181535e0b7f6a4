"""The colour model of the silhouette rule over a textured backdrop: learned at the known
first state, it finds the hand again; it refuses a backdrop dressed in the hand's colours
and grey images."""

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.features.colour_foreground import (
    MAX_BACKDROP_SHARE,
    colour_bins,
    fit_colour_foreground,
)
from digiteyes.features.foreground import MARGIN_PX, fit_foreground, model_labels
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import forward_kinematics
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario


@pytest.fixture(scope="module")
def clutter():
    """The desk view, one camera: the flesh hand in colour over clutter at two states
    (the index straight, then curled): (model, camera, state, labels, image, image of
    the curled index)."""
    scenario = build_scenario("desk-1cam", seed=0, n_frames=2)
    model, rig = scenario.model, Rig(scenario.rig.cameras[:1])
    q = np.array(scenario.states[0])
    curled = q.copy()
    for joint, angle in (("mcp", 80.0), ("pip", 95.0), ("dip", 60.0)):
        curled[model.state_index(f"index.{joint}")] = np.radians(angle)
    options = RenderOptions(appearance="flesh", noise_sigma=2.0, color=True,
                            background="clutter", background_seed=3)
    image = render_views(model, q, rig, options, rng=0)[0].image
    image_curled = render_views(model, curled, rig, options, rng=1)[0].image
    labels = model_labels(model, forward_kinematics(model, q), rig.cameras[0])
    return model, rig.cameras[0], q, curled, labels, image, image_curled


def test_the_colour_model_finds_the_hand_over_clutter(clutter):
    _, _, _, _, labels, image, _ = clutter
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
    _, _, _, _, labels, image, _ = clutter
    fg = fit_colour_foreground(image, labels, MARGIN_PX)
    bins = colour_bins(image)
    assert bins.shape == image.shape[:2] and 0 <= bins.min() and bins.max() < fg.is_hand.size
    np.testing.assert_array_equal(fg.mask(image), fg.is_hand[bins])


def test_a_backdrop_in_the_hands_colours_is_refused(clutter):
    _, _, _, _, labels, image, _ = clutter
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
    _, _, _, _, labels, image, _ = clutter
    assert fit_colour_foreground(prepare_image(image), labels, MARGIN_PX) is None
    assert fit_colour_foreground(image, np.full(labels.shape, -1), MARGIN_PX) is None
