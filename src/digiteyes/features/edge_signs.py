"""Which way each link side's silhouette edge goes, learned on the first frame.

The report's and the thesis's edge search (Sec. 4.3.1) looks for an edge of one sign: a
hand brighter than its backdrop, as on the black cloth of their experiments. Over a grey
wall, or for a dark hand, the shaded side of a finger can be darker than the backdrop
while its lit side is brighter, and a search for the wrong sign finds no edge there, or
the neighbouring finger's. :func:`learn_side_signs` measures the first frame at its known
state twice, with the usual signs and with every sign flipped, and lets a link side keep
the flipped sign where the usual one finds too few edges and the flipped one enough, lying
where the state puts that side's silhouette (their median offset from it at most
:data:`NEAR_PX`): a start that does not fit the image (an automatic start some
millimetres off) finds edges of either sign where it has no side, and learns nothing
from them.

Only in a camera where the hand's darkest pixels reach into the backdrop's grey levels
(the darkest 5 % of the pixels well inside the model's silhouette below the backdrop's
median plus :data:`BAND_SPREADS` robust spreads): where the whole hand is brighter than
the backdrop, a side the usual sign misses is hidden or touching a neighbour, and an edge
of the other sign there is the neighbour's (on black cloth one such flip cost the flesh
hand's desk pair 8 mm; docs/accuracy.md, "Renders the trackers were not developed on").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from digiteyes.camera import Camera
from digiteyes.features.foreground import hand_and_backdrop, model_labels, robust_level
from digiteyes.features.measure import (
    LINE_KINDS,
    FeatureMeasurement,
    FeatureOptions,
    measure_features,
    select_links,
    usual_side_signs,
)
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, Kinematics

BAND_SPREADS = 5.0
"""Robust spreads (1.4826 MAD) above the backdrop's median that count as its band."""

NEAR_PX = 3.0
"""Largest median distance (px, along the slices) of a flipped side's edge points from the
silhouette the start state predicts for that side."""


def mixed_contrast(image: np.ndarray, camera: Camera, model: KinematicModel,
                   kin: Kinematics) -> bool:
    """Whether the hand drawn at the state of ``kin`` has pixels as dark as the backdrop
    of the grey ``image`` (module docstring); False when either region is too small to
    tell."""
    regions = hand_and_backdrop(model_labels(model, kin, camera))
    if regions is None:
        return False
    inside, outside = regions
    grey = prepare_image(image).astype(np.float32, copy=False)
    level, spread = robust_level(grey[outside])
    return float(np.percentile(grey[inside], 5)) < level + BAND_SPREADS * spread


def learn_side_signs(image: np.ndarray, camera: Camera, model: KinematicModel,
                     kin: Kinematics, options: FeatureOptions | None = None,
                     links: Sequence[str] | None = None, tips: Sequence[str] | None = None
                     ) -> np.ndarray:
    """(L, 2) edge signs for :func:`~digiteyes.features.measure_features` (its
    ``side_signs``) from a frame whose state (that of ``kin``) is known: the usual
    ``(+1, -1)`` (flipped without ``bright_object``), each side flipped where the module
    docstring says."""
    options = FeatureOptions() if options is None else options
    signs = usual_side_signs(len(select_links(model, links, LINE_KINDS)), options)
    if not mixed_contrast(image, camera, model, kin):
        return signs
    usual = measure_features(image, camera, model, kin, options, links, tips)
    flipped = measure_features(image, camera, model, kin, options, links, tips, -signs)
    enough = options.min_edge_points
    flip = ((usual.n_edges < enough) & (flipped.n_edges >= enough)
            & (flipped.n_edges > usual.n_edges) & (side_offsets(flipped) <= NEAR_PX))
    return np.where(flip, -signs, signs)


def side_offsets(measurement: FeatureMeasurement) -> np.ndarray:
    """(L, 2) median distance (px, along the slice normal) of each link side's inlier edge
    points from the silhouette its measurement predicted (``inf`` where none)."""
    found = measurement.edge_points - measurement.slice_centres[:, None]  # (L, 2, S, 2)
    along = np.einsum("lksc,lc->lks", found, measurement.slice_normal)
    predicted = np.moveaxis(measurement.contour_offsets, 2, 1)  # (L, 2, S)
    distance = np.where(measurement.edge_inlier, np.abs(along - predicted), np.nan)
    out = np.full(distance.shape[:2], np.inf)
    seen = np.isfinite(distance).any(axis=2)
    out[seen] = np.nanmedian(distance[seen], axis=1)
    return out
