"""Link and tip feature measurement: the DigitEyes local trackers (report Sec. 4).

For each tracked cylinder link the predicted axis is projected into the image and
``slices_per_link`` slices are laid across it (skipping ``end_margin`` of the link length at
each end, where joints and neighbouring links meet). On each side of the axis the
predicted silhouette edge lies at the projected cylinder contour; the edge is searched
within ``+-window_px / 2`` of it (thesis Table 4.2: a 20 px feature window). The strongest
derivative peak of the correct sign (a bright finger on a dark background gets brighter
when crossing the left contour towards the right, darker at the right contour) above
``min_contrast`` grey levels is the edge, refined to subpixel precision.

A robust line is fitted to each side's edge points; the link feature (report Sec. 3.2) is
the bisector of the two side lines. When only one side is usable, its edge points are moved
towards the axis by their predicted contour offsets and a line through them is the
feature (one-edge fallback, report Sec. 4). Tips are measured on three slices along the
finger axis, beyond the distal link: the end of the silhouette, moved back by the
projected tip radius, gives the tip centre; the lateral position comes from the measured
axis line of the distal link when it is valid.

Every link and tip carries a validity flag and a reason (see :data:`LINK_REASONS`), so
trackers can exclude bad features from the residual and detect track loss.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import CameraError, StateError
from digiteyes.features.edges import KERNEL_HALF_WIDTH, edge_response, strongest_peaks
from digiteyes.features.lines import bisector, fit_lines, orient_lines, weighted_line
from digiteyes.features.slices import (
    cylinder_contour_offsets,
    perpendicular,
    prepare_image,
    sample_profiles,
    sphere_extent,
)
from digiteyes.kinematics import KinematicModel, Kinematics

LINK_REASONS = {
    "ok": "measured",
    "behind-camera": "the link is not in front of the camera",
    "foreshortened": "the projected axis is shorter than min_axis_px",
    "off-image": "fewer than min_edge_points slices inside the image",
    "few-edges": "no side has min_edge_points edge points",
    "fit-residual": "no side line fits its edge points within max_fit_rms_px",
    "outside-window": "the measured axis leaves the search window",
}
TIP_REASONS = {
    "ok": "measured",
    "behind-camera": "the tip is not in front of the camera",
    "foreshortened": "the finger axis points at the camera (sin < 0.2)",
    "few-edges": "fewer than min_tip_edges tip slices found the silhouette end",
    "inconsistent": "the tip slices disagree by more than max_tip_spread_px",
}
TIP_LATERAL = np.array([-0.5, 0.0, 0.5])  # tip slice offsets, fractions of the tip radius
MIN_TIP_SIN = 0.2


@dataclass(frozen=True)
class FeatureOptions:
    """Settings of the feature trackers (all lengths in pixels).

    Attributes
    ----------
    window_px : length of the search range around each predicted silhouette edge: edges
        are searched within ``+-window_px / 2`` of the projected contour (thesis Table 4.2).
    slices_per_link : slices across each link.
    min_contrast : smallest accepted edge, grey levels (height of the intensity step).
    min_edge_points : inlier edge points a side needs for its line to count.
    robust : line-fit loss, ``"tukey"``, ``"huber"`` or ``"none"`` (see ``lines.py``).
    tip_search_px : length of the search range along the axis around the predicted end of
        the finger silhouette (``+-tip_search_px / 2``).
    bright_object : the hand is brighter than the background (False flips the edge signs).
    end_margin : fraction of the link length skipped at each end.
    step_px : sampling step along slices.
    max_fit_rms_px : a side line whose inliers are farther than this (RMS) is rejected.
    max_side_angle_deg : when the two side lines differ by more than this, only the side
        with more inliers is used (one-edge fallback).
    min_axis_px : links whose projected axis is shorter are not measured.
    min_tip_edges : tip slices (of 3) that must find the silhouette end.
    max_tip_spread_px : largest disagreement of the tip slices' estimates.
    tip_end : shape of the finger end. ``"capsule"`` (default): the distal link is a
        capsule whose far cap covers the tip sphere, so the silhouette ends
        ``max(tip radius, link radius)`` beyond the tip centre (the renderer's geometry,
        and closer to real fingers than a thin tip on a thick cylinder); ``"sphere"``: the
        tip sphere alone (report Fig. 3).
    """

    window_px: float = 20.0
    slices_per_link: int = 10
    min_contrast: float = 8.0
    min_edge_points: int = 3
    robust: str = "tukey"
    tip_search_px: float = 20.0
    bright_object: bool = True
    end_margin: float = 0.15
    step_px: float = 1.0
    max_fit_rms_px: float = 1.5
    max_side_angle_deg: float = 20.0
    min_axis_px: float = 5.0
    min_tip_edges: int = 2
    max_tip_spread_px: float = 3.0
    tip_end: str = "capsule"

    def __post_init__(self) -> None:
        positive = ("window_px", "tip_search_px", "step_px", "max_fit_rms_px",
                    "max_side_angle_deg", "max_tip_spread_px")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"FeatureOptions.{name} must be positive, got {value!r}")
        if not (self.min_contrast >= 0 and self.min_axis_px >= 0):
            raise ValueError(
                f"FeatureOptions.min_contrast and min_axis_px must be >= 0, got "
                f"{self.min_contrast!r} and {self.min_axis_px!r}"
            )
        if self.slices_per_link < 2:
            raise ValueError(
                f"FeatureOptions.slices_per_link must be >= 2, got {self.slices_per_link}"
            )
        if not 2 <= self.min_edge_points <= self.slices_per_link:
            raise ValueError(
                "FeatureOptions.min_edge_points must be in 2..slices_per_link, got "
                f"{self.min_edge_points}"
            )
        if not 1 <= self.min_tip_edges <= len(TIP_LATERAL):
            raise ValueError(
                f"FeatureOptions.min_tip_edges must be in 1..3, got {self.min_tip_edges}"
            )
        if not 0.0 <= self.end_margin < 0.5:
            raise ValueError(f"FeatureOptions.end_margin must be in [0, 0.5), got "
                             f"{self.end_margin}")
        if self.tip_end not in ("capsule", "sphere"):
            raise ValueError(
                f"FeatureOptions.tip_end must be 'capsule' or 'sphere', got {self.tip_end!r}"
            )
        if self.robust not in ("tukey", "huber", "none"):
            raise ValueError(
                f"FeatureOptions.robust must be 'tukey', 'huber' or 'none', got {self.robust!r}"
            )


@dataclass(frozen=True)
class FeatureMeasurement:
    """Link lines and tip points measured in one image, with everything needed to draw them.

    L links with S slices each, T tips, K = 3 tip slices. Pixels throughout.

    Attributes
    ----------
    camera : name of the camera the image came from.
    link_ids : (L,) indices into ``model.links`` of the tracked cylinder links.
    predicted_axis : (L, 2, 2) projected start and end of each link axis.
    line : (L, 3) measured axis line ``(a, b, rho)``, ``a x + b y = rho``, ``a^2 + b^2 = 1``,
        normal oriented like the slice normal; NaN where invalid.
    link_valid : (L,) bool.
    link_reason : (L,) str, a key of :data:`LINK_REASONS`.
    n_edges : (L, 2) inlier edge points per side (side 0: negative slice offsets).
    side_lines : (L, 2, 3) fitted silhouette lines per side (NaN if not fitted).
    edge_points : (L, 2, S, 2) detected edge points, NaN where none was found.
    edge_inlier : (L, 2, S) bool, edge points kept by the robust fit.
    slice_centres : (L, S, 2) slice centres on the projected axis.
    slice_normal : (L, 2) unit image normal of each projected axis (slice direction).
    slice_ends : (L, S, 2, 2) ends of each slice's searched span (both sides' ranges).
    contour_offsets : (L, S, 2) predicted silhouette offsets along the normal (side 0 < 0).
    tip_ids : (T,) indices into ``model.links`` of the tracked tips.
    predicted_tip : (T, 2) projected tip centres.
    measured_tip : (T, 2) measured tip centres, NaN where invalid.
    tip_valid : (T,) bool.
    tip_reason : (T,) str, a key of :data:`TIP_REASONS`.
    tip_direction : (T, 2) unit image direction of the finger axis at the tip (outward).
    tip_slice_ends : (T, K, 2, 2) ends of the tip slices' search ranges.
    tip_edge_points : (T, K, 2) silhouette ends found on the tip slices, NaN if none.
    """

    camera: str
    link_ids: np.ndarray
    predicted_axis: np.ndarray
    line: np.ndarray
    link_valid: np.ndarray
    link_reason: np.ndarray
    n_edges: np.ndarray
    side_lines: np.ndarray
    edge_points: np.ndarray
    edge_inlier: np.ndarray
    slice_centres: np.ndarray
    slice_normal: np.ndarray
    slice_ends: np.ndarray
    contour_offsets: np.ndarray
    tip_ids: np.ndarray
    predicted_tip: np.ndarray
    measured_tip: np.ndarray
    tip_valid: np.ndarray
    tip_reason: np.ndarray
    tip_direction: np.ndarray
    tip_slice_ends: np.ndarray
    tip_edge_points: np.ndarray

    @property
    def n_valid(self) -> int:
        """Number of valid features (links plus tips)."""
        return int(self.link_valid.sum() + self.tip_valid.sum())


def select_links(model: KinematicModel, names: Sequence[str] | None, kind: str) -> np.ndarray:
    """Indices into ``model.links`` of the named links of one kind (all of them if None)."""
    if names is None:
        return np.array([i for i, link in enumerate(model.links) if link.kind == kind], dtype=int)
    index = {link.name: i for i, link in enumerate(model.links)}
    out = []
    for name in names:
        if name not in index:
            raise KeyError(f"model {model.name!r} has no link {name!r}")
        if model.links[index[name]].kind != kind:
            raise ValueError(
                f"{name!r} is a {model.links[index[name]].kind!r}, expected a {kind!r}"
            )
        out.append(index[name])
    return np.array(out, dtype=int)


def _single_state_shapes(kin: Kinematics) -> np.ndarray:
    if kin.T_world_shape.shape[0] != 1:
        raise StateError(
            f"measure_features needs the kinematics of one state, got {kin.T_world_shape.shape[0]}"
        )
    return kin.T_world_shape[0]


def _sample_grid(half: float, step: float) -> np.ndarray:
    n = math.ceil(half / step) + KERNEL_HALF_WIDTH + 1
    return np.arange(-n, n + 1) * step


def measure_features(
    image: np.ndarray,
    camera: Camera,
    model: KinematicModel,
    kin: Kinematics,
    options: FeatureOptions = FeatureOptions(),
    links: Sequence[str] | None = None,
    tips: Sequence[str] | None = None,
) -> FeatureMeasurement:
    """Measure link lines and tip points in one image around the model's prediction.

    Parameters
    ----------
    image : (H, W) grey or (H, W, 3) RGB image, uint8 or float (see
        :func:`~digiteyes.features.slices.prepare_image`; pass its result to avoid
        converting the same frame again in every iteration).
    camera : the camera that took the image.
    model : kinematic model.
    kin : forward kinematics of ONE state (the prediction that places the trackers).
    options : tracker settings.
    links, tips : names of the cylinder links and tips to track (default: all of them).

    Returns
    -------
    FeatureMeasurement
    """
    gray = prepare_image(image)
    if gray.shape != (camera.height, camera.width):
        raise CameraError(
            f"camera {camera.name!r} expects {camera.width}x{camera.height} images, got "
            f"{gray.shape[1]}x{gray.shape[0]}"
        )
    shapes = _single_state_shapes(kin)
    link_ids = select_links(model, links, "link")
    tip_ids = select_links(model, tips, "tip")
    link_part = _measure_links(gray, camera, model, shapes, link_ids, options)
    tip_part = _measure_tips(gray, camera, model, shapes, tip_ids, link_ids, link_part, options)
    return FeatureMeasurement(camera=camera.name, link_ids=link_ids, tip_ids=tip_ids,
                              **link_part, **tip_part)


def _measure_links(gray, camera, model, shapes, link_ids, opt) -> dict:
    n_links, n_slices = len(link_ids), opt.slices_per_link
    rows = np.array([model.links[i].row for i in link_ids], dtype=int)
    lengths = np.array([model.links[i].length for i in link_ids], dtype=float)
    radii = np.array([model.links[i].radius for i in link_ids], dtype=float)
    T = shapes[rows]
    start, axis = T[:, :3, 3], T[:, :3, 0]
    end = start + axis * lengths[:, None]
    t = np.linspace(opt.end_margin, 1.0 - opt.end_margin, n_slices)
    p_slices = start[:, None] + t[None, :, None] * (end - start)[:, None]
    w_ends = camera.project(np.stack([start, end], axis=1))
    w_slices = camera.project(p_slices)
    direction = w_ends[:, 1] - w_ends[:, 0]
    length_px = np.linalg.norm(direction, axis=-1)
    u = np.where(length_px[:, None] > 0, direction / np.maximum(length_px, 1e-12)[:, None],
                 [1.0, 0.0])
    normal = perpendicular(u)
    minus, plus = cylinder_contour_offsets(
        camera, p_slices, np.broadcast_to(axis[:, None], p_slices.shape), radii[:, None],
        w_slices, normal[:, None])

    reason = np.full(n_links, "ok", dtype=object)
    if camera.projection == "perspective":
        depth = camera.depth(np.stack([start, end], axis=1))
        behind = (depth <= radii[:, None]).any(axis=1)
    else:
        behind = np.zeros(n_links, dtype=bool)
    behind |= ~np.isfinite(minus).all(axis=1) | ~np.isfinite(plus).all(axis=1)
    short = (length_px < opt.min_axis_px) & ~behind
    centres_inside = camera.in_image(w_slices).sum(axis=1)
    off_image = (centres_inside < opt.min_edge_points) & ~behind & ~short
    reason[behind] = "behind-camera"
    reason[short] = "foreshortened"
    reason[off_image] = "off-image"
    usable_link = ~(behind | short | off_image)
    contour = np.stack([np.where(usable_link[:, None], minus, 0.0),
                        np.where(usable_link[:, None], plus, 0.0)], axis=-1)
    w_slices_safe = np.where(usable_link[:, None, None], w_slices, -1e4)

    # One bilinear lookup for every slice of every link (L, S, J).
    reach = np.abs(contour).max() if n_links else 0.0
    offsets = _sample_grid(reach + 0.5 * opt.window_px, opt.step_px)
    profiles, inside = sample_profiles(gray, w_slices_safe, normal[:, None], offsets)
    response = edge_response(profiles)
    polarity = 1.0 if opt.bright_object else -1.0
    strength = np.stack([polarity * response, -polarity * response], axis=1)  # (L, 2, S, J)
    contour_sides = np.moveaxis(contour, -1, 1)  # (L, 2, S)
    in_window = np.abs(offsets - contour_sides[..., None]) <= 0.5 * opt.window_px
    allowed = in_window & inside[:, None] & usable_link[:, None, None, None]
    position, found, _ = strongest_peaks(strength, allowed, opt.min_contrast)
    edge_offset = offsets[0] + position * opt.step_px  # (L, 2, S)
    edge_points = w_slices[:, None] + edge_offset[..., None] * normal[:, None, None]
    edge_points = np.where(found[..., None], edge_points, np.nan)

    side_normal = np.broadcast_to(normal[:, None], (n_links, 2, 2))
    fit = fit_lines(edge_points, found, robust=opt.robust, normal=side_normal)
    # One-edge fallback: move each side's edge points onto the predicted axis.
    axis_points = w_slices[:, None] + (edge_offset - contour_sides)[..., None] * normal[:, None,
                                                                                       None]
    shifted = orient_lines(weighted_line(axis_points, fit.inlier.astype(float)), side_normal)

    side_ok = (fit.count >= opt.min_edge_points) & (fit.rms <= opt.max_fit_rms_px)
    cos_sides = np.abs(np.sum(fit.line[:, 0, :2] * fit.line[:, 1, :2], axis=-1))
    parallel = cos_sides >= math.cos(math.radians(opt.max_side_angle_deg))
    both = side_ok.all(axis=1) & parallel
    prefer_one = fit.count[:, 1] > fit.count[:, 0]
    prefer_one |= (fit.count[:, 1] == fit.count[:, 0]) & (fit.rms[:, 1] < fit.rms[:, 0])
    one_side = np.where(side_ok[:, 0] & side_ok[:, 1], prefer_one.astype(int),
                        side_ok[:, 1].astype(int))
    single = np.take_along_axis(shifted, one_side[:, None, None], axis=1)[:, 0]
    line = np.where(both[:, None], bisector(fit.line[:, 0], fit.line[:, 1]), single)
    any_side = side_ok.any(axis=1)

    end_slices = w_slices[:, [0, -1]]
    distance = np.abs(np.sum(line[:, None, :2] * end_slices, axis=-1) - line[:, None, 2])
    outside = ~(distance <= 0.5 * opt.window_px).all(axis=1)
    enough = (fit.count >= opt.min_edge_points).any(axis=1)
    pending = usable_link.copy()
    reason[pending & ~enough] = "few-edges"
    reason[pending & enough & ~any_side] = "fit-residual"
    reason[pending & any_side & outside] = "outside-window"
    valid = reason == "ok"
    side_lines = np.where(side_ok[..., None], fit.line, np.nan)
    return {
        "predicted_axis": w_ends,
        "line": np.where(valid[:, None], line, np.nan),
        "link_valid": valid,
        "link_reason": reason.astype(str),
        "n_edges": fit.count,
        "side_lines": side_lines,
        "edge_points": edge_points,
        "edge_inlier": fit.inlier,
        "slice_centres": w_slices,
        "slice_normal": normal,
        "slice_ends": w_slices[..., None, :] + np.stack(
            [contour[..., 0] - 0.5 * opt.window_px, contour[..., 1] + 0.5 * opt.window_px],
            axis=-1)[..., None] * normal[:, None, None],
        "contour_offsets": contour,
    }


def _tip_axes(model: KinematicModel, shapes: np.ndarray, tip_ids: np.ndarray):
    """3D outward axis of each tip (its parent cylinder's axis, else its own x axis) and
    the index into ``model.links`` of that parent cylinder (-1 if none)."""
    row_to_link = {link.row: i for i, link in enumerate(model.links) if link.kind == "link"}
    parents, axes = [], []
    for i in tip_ids:
        row = model.links[i].row
        parent = row_to_link.get(int(model.parent[row]), -1)
        parents.append(parent)
        axis_row = model.links[parent].row if parent >= 0 else row
        axes.append(shapes[axis_row, :3, 0])
    return np.array(parents, dtype=int), np.array(axes, dtype=float).reshape(-1, 3)


def _measure_tips(gray, camera, model, shapes, tip_ids, link_ids, link_part, opt) -> dict:
    n_tips = len(tip_ids)
    rows = np.array([model.links[i].row for i in tip_ids], dtype=int)
    radii = np.array([model.links[i].radius for i in tip_ids], dtype=float)
    centre3 = shapes[rows, :3, 3]
    parents, axis3 = _tip_axes(model, shapes, tip_ids)
    if opt.tip_end == "capsule":
        parent_radii = np.array([model.links[p].radius if p >= 0 else 0.0 for p in parents])
        radii = np.maximum(radii, parent_radii)
    w_c, u, along, across, sin_view = sphere_extent(camera, centre3, axis3, radii)

    reason = np.full(n_tips, "ok", dtype=object)
    behind = ~np.isfinite(along) | ~np.isfinite(across)
    if camera.projection == "perspective":
        behind |= camera.depth(centre3) <= radii
    short = ~behind & ~(sin_view >= MIN_TIP_SIN)
    reason[behind] = "behind-camera"
    reason[short] = "foreshortened"
    usable = ~(behind | short)
    u = np.where(usable[:, None], u, [1.0, 0.0])
    along = np.where(usable, along, 0.0)
    across = np.where(usable, across, 0.0)

    # Lateral position from the measured axis of the parent link, when there is one.
    base, direction = w_c.copy(), u.copy()
    position_of = {int(link): k for k, link in enumerate(link_ids)}
    for t, parent in enumerate(parents):
        k = position_of.get(int(parent), -1)
        if k >= 0 and link_part["link_valid"][k] and usable[t]:
            m, rho = link_part["line"][k, :2], link_part["line"][k, 2]
            base[t] = w_c[t] - (m @ w_c[t] - rho) * m
            along_line = np.array([m[1], -m[0]])
            direction[t] = along_line if along_line @ u[t] >= 0 else -along_line
    lateral = perpendicular(direction)
    expected_end = along[:, None] * np.sqrt(1.0 - TIP_LATERAL**2)[None, :]  # (T, K)
    origins = (base[:, None] + (TIP_LATERAL[None, :] * across[:, None])[..., None]
               * lateral[:, None] + expected_end[..., None] * direction[:, None])
    origins = np.where(usable[:, None, None], origins, -1e4)
    half = 0.5 * opt.tip_search_px
    offsets = _sample_grid(half, opt.step_px)
    profiles, inside = sample_profiles(gray, origins, direction[:, None], offsets)
    polarity = 1.0 if opt.bright_object else -1.0
    strength = -polarity * edge_response(profiles)
    allowed = inside & (np.abs(offsets) <= half) & usable[:, None, None]
    position, found, _ = strongest_peaks(strength, allowed, opt.min_contrast)
    shift = offsets[0] + position * opt.step_px  # (T, K): end moved along the axis
    edge_points = np.where(found[..., None], origins + shift[..., None] * direction[:, None],
                           np.nan)
    count = found.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_shift = np.where(found, shift, 0.0).sum(axis=1) / count
    spread = (np.where(found, shift, -np.inf).max(axis=1)
              - np.where(found, shift, np.inf).min(axis=1))
    few = usable & (count < opt.min_tip_edges)
    reason[few] = "few-edges"
    reason[usable & ~few & (spread > opt.max_tip_spread_px)] = "inconsistent"
    valid = reason == "ok"
    measured = base + mean_shift[:, None] * direction
    ends = np.stack([origins - half * direction[:, None], origins + half * direction[:, None]],
                    axis=-2)
    return {
        "predicted_tip": w_c,
        "measured_tip": np.where(valid[:, None], measured, np.nan),
        "tip_valid": valid,
        "tip_reason": reason.astype(str),
        "tip_direction": direction,
        "tip_slice_ends": ends,
        "tip_edge_points": edge_points,
    }
