"""Synthetic sequences with ground truth: scenarios, motion, backdrops, sensor, perturbation.

``render_views(model, q, cameras, RenderOptions(...), rng)`` draws the model with the
rasteriser of :mod:`digiteyes.render` (capsule links, ball tips, rounded palm slab;
DigitEyes report Fig. 1) in front of a black cloth, uniform, cluttered or image backdrop,
through the sensor model, and returns each view with depth, labels and keypoints.
``perturb_model`` draws a "true" model that differs from the tracking model; scenarios
(:mod:`digiteyes.synth.scenarios`) give whole sequences. See docs/rendering.md and
docs/scenarios.md.
"""

from digiteyes.synth.options import BACKGROUNDS, RenderError, RenderOptions
from digiteyes.synth.perturb import anchor_chains, perturb_model
from digiteyes.synth.scenarios import SCENARIOS
from digiteyes.synth.setups import SETUP_SCENARIOS
from digiteyes.synth.views import RenderedView, render_views

# The camera-setup scenarios (built on synth.scenarios) join the scenario table here, where
# both modules are loaded, so that neither imports the other back.
SCENARIOS.update(SETUP_SCENARIOS)

__all__ = [
    "BACKGROUNDS", "RenderError", "RenderOptions", "RenderedView", "anchor_chains",
    "perturb_model", "render_views",
]
