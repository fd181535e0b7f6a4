"""Synthetic images of posed models with ground truth (depth, labels, keypoints).

``render_views(model, q, cameras, RenderOptions(...), rng)`` ray casts the model (capsule
links, ball tips, rounded palm slab; DigitEyes report Fig. 1) in front of a black cloth,
uniform, cluttered or image backdrop, for perspective, orthographic and scaled-orthographic
cameras with optional lens distortion. ``perturb_model`` draws a "true" model that differs
from the tracking model. See docs/rendering.md.
"""

from digiteyes.render.keypoints import keypoint_names, keypoints
from digiteyes.render.options import BACKGROUNDS, RenderError, RenderOptions
from digiteyes.render.perturb import anchor_chains, perturb_model
from digiteyes.render.views import RenderedView, render_views

__all__ = [
    "BACKGROUNDS", "RenderError", "RenderOptions", "RenderedView", "anchor_chains",
    "keypoint_names", "keypoints", "perturb_model", "render_views",
]
