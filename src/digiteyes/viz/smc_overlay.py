"""Overlay panel of the divide-and-conquer trackers (Huang, Wu & Lin): a sample of the
finger hypotheses as thin axes, shaded by weight, the best hypothesis as the full model
wireframe, and the palm outline's ICP matches (Sec. 4.1) as dots.

Registered for :class:`~digiteyes.trackers.DivideConquerDetails` when
:mod:`digiteyes.viz.track_overlay` is imported.
"""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.trackers import DivideConquerDetails, TrackResult
from digiteyes.viz.model_view import draw_wireframe
from digiteyes.viz.overlay import _Canvas, to_rgb

PARTICLE_RGB = (90, 200, 255)
"""Colour of the best-weighted sampled hypotheses (fading to grey for the least)."""
PALM_MATCH_RGB = (255, 0, 255)


def draw_particles(image: np.ndarray, camera: Camera, model: KinematicModel,
                   states: np.ndarray) -> np.ndarray:
    """Finger link axes of ``states`` (S, n_q), in weight order (best first), projected
    by ``camera`` onto a copy of ``image`` (RGB uint8)."""
    canvas = _Canvas(to_rgb(image).copy(), 1)
    if len(states) == 0:
        return canvas.image
    links = [link for link in model.links if link.kind == "link"]
    T = forward_kinematics(model, np.atleast_2d(states)).T_world_shape
    for rank in range(len(states) - 1, -1, -1):              # best drawn last, on top
        fade = rank / max(len(states) - 1, 1)
        rgb = tuple(round((1 - fade) * c + fade * 140) for c in PARTICLE_RGB)
        a = np.array([T[rank, link.row, :3, 3] for link in links])
        b = a + np.array([link.length * T[rank, link.row, :3, 0] for link in links])
        canvas.lines(camera.project(a), camera.project(b), rgb)
    return canvas.image


def draw_divide_conquer(image: np.ndarray, camera_index: int, camera: Camera,
                        result: TrackResult, model: KinematicModel) -> np.ndarray:
    """One camera's panel for a divide-and-conquer result (RGB uint8)."""
    details: DivideConquerDetails = result.details
    panel = draw_particles(image, camera, model, details.sample_states)
    panel = draw_wireframe(model, result.state, camera, panel)
    if camera_index == 0 and len(details.palm_pixels):       # the palm step's camera
        canvas = _Canvas(panel, 1)
        canvas.dots(details.palm_pixels, PALM_MATCH_RGB, 1.5)
        panel = canvas.image
    return panel
