"""The overlay frame of a tracked frame: each camera's image with what the tracker
measured drawn on it, cameras side by side (report Fig. 4, thesis Fig. 4.2).

What is drawn depends on the type of :attr:`TrackResult.details`: every tracker type
registers one drawer for its details with :func:`register_overlay` (the feature
tracker's :class:`~digiteyes.trackers.FeatureDetails` is registered here and drawn by
:func:`~digiteyes.viz.overlay.draw_features`, the template trackers'
:class:`~digiteyes.trackers.TemplateDetails` by
:func:`~digiteyes.viz.templates.draw_templates`). Details of a type nobody registered, and
``None``, still get the projected model at the estimated state
(:func:`~digiteyes.viz.model_view.draw_wireframe`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.camera.mirror import mirror_images
from digiteyes.detect.hand21 import BONES
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.trackers import FeatureDetails, KeypointDetails, TemplateDetails, TrackResult
from digiteyes.viz.model_view import draw_wireframe
from digiteyes.viz.overlay import draw_features, to_rgb
from digiteyes.viz.templates import draw_templates

DETECTION_RGB = (255, 220, 0)
"""Colour of a detector's keypoints in the overlay."""

DetailsDrawer = Callable[[np.ndarray, int, Camera, TrackResult, KinematicModel], np.ndarray]
"""``draw(image, camera_index, camera, result, model) -> (H, W, 3) RGB uint8``: one
camera's panel; ``result.details`` is of the registered type."""

_DRAWERS: dict[type, DetailsDrawer] = {}


def register_overlay(details_type: type, draw: DetailsDrawer) -> None:
    """Draw results whose ``details`` are ``details_type`` (or a subclass) with ``draw``."""
    _DRAWERS[details_type] = draw


def drawer_for(details: Any) -> DetailsDrawer:
    """The drawer registered for the type of ``details`` (nearest base class first), or
    :func:`draw_model` when there is none."""
    for cls in type(details).__mro__:
        if cls in _DRAWERS:
            return _DRAWERS[cls]
    return draw_model


def draw_model(image: np.ndarray, camera_index: int, camera: Camera, result: TrackResult,
               model: KinematicModel) -> np.ndarray:
    """The fallback panel: the model projected at the estimated state over the image."""
    return draw_wireframe(model_of_size(model, result.hand_scale), result.state, camera,
                          to_rgb(image))


def draw_result(image: np.ndarray, camera_index: int, camera: Camera, result: TrackResult,
                model: KinematicModel) -> np.ndarray:
    """One camera's panel for ``result`` (RGB uint8), drawn by the details' drawer."""
    return drawer_for(result.details)(image, camera_index, camera, result, model)


def overlay_image(images: Sequence[np.ndarray], result: TrackResult, rig: Rig,
                  model: KinematicModel) -> np.ndarray:
    """Cameras side by side, each panel drawn by :func:`draw_result` (RGB uint8, padded
    to an even size for H.264); a mirrored rig's panels (a left hand,
    :mod:`digiteyes.camera.mirror`) are flipped back to the real images."""
    panels = [draw_result(image, index, camera, result, model)
              for index, (image, camera) in enumerate(zip(images, rig, strict=True))]
    if rig.mirrored:
        panels = mirror_images(panels)
    height = max(p.shape[0] for p in panels)
    height += height % 2
    width = sum(p.shape[1] for p in panels)
    tiled = np.zeros((height, width + width % 2, 3), dtype=np.uint8)
    left = 0
    for panel in panels:
        tiled[:panel.shape[0], left:left + panel.shape[1]] = panel
        left += panel.shape[1]
    return tiled


def _draw_feature_details(image: np.ndarray, camera_index: int, camera: Camera,
                          result: TrackResult, model: KinematicModel) -> np.ndarray:
    details: FeatureDetails = result.details
    return draw_features(image, details.measurements[camera_index], camera,
                         details.residual_layouts[camera_index])


register_overlay(FeatureDetails, _draw_feature_details)


def _draw_template_details(image: np.ndarray, camera_index: int, camera: Camera,
                           result: TrackResult, model: KinematicModel) -> np.ndarray:
    details: TemplateDetails = result.details
    return draw_templates(image, details.evaluations[camera_index].windows,
                          details.orders[camera_index],
                          details.segmentations[camera_index])


register_overlay(TemplateDetails, _draw_template_details)


def _draw_keypoint_details(image: np.ndarray, camera_index: int, camera: Camera,
                           result: TrackResult, model: KinematicModel) -> np.ndarray:
    """The fitted model's wireframe and the detector's 21 keypoints (yellow dots, joined
    along the hand's bones)."""
    panel = draw_wireframe(model_of_size(model, result.hand_scale), result.state, camera,
                           to_rgb(image))
    candidate = result.details.candidates[camera_index]
    if candidate is not None:
        points = np.round(candidate.keypoints).astype(np.int32)
        for a, b in BONES:
            cv2.line(panel, tuple(points[a]), tuple(points[b]), DETECTION_RGB, 1, cv2.LINE_AA)
        for point in points:
            cv2.circle(panel, tuple(point), 3, DETECTION_RGB, -1, cv2.LINE_AA)
    return panel


register_overlay(KeypointDetails, _draw_keypoint_details)


def _register_tracker_drawers() -> None:
    """Register the drawers that live in their own modules (imported here, after
    :func:`register_overlay` exists, so that importing this module registers them all)."""
    from digiteyes.trackers import DivideConquerDetails
    from digiteyes.viz.smc_overlay import draw_divide_conquer

    register_overlay(DivideConquerDetails, draw_divide_conquer)


_register_tracker_drawers()
