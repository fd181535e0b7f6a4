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
the bisector of the two side lines, provided they agree with each other and with the
model (angle, width). When only one side is usable, its edge points are moved towards the
axis by their predicted contour offsets and a line through them is the feature (one-edge
fallback, report Sec. 4), provided the other side's search ranges show the finger's own
intensity (it merged with another part of the hand) rather than background. Tips are
measured on three slices along the finger axis, beyond the distal link: the end of the
silhouette, moved back by the projected radius of the finger end, gives the tip centre;
the lateral position comes from the measured axis line of the distal link when it is
valid.

Every link and tip carries a validity flag and a reason (:data:`LINK_REASONS`,
:data:`TIP_REASONS`), so trackers can exclude bad features from the residual and detect
track loss. All model points are projected with one ``camera.project`` call; all slices of
all links are sampled with one ``cv2.remap`` call (docs/features.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import CameraError, StateError
from digiteyes.features.edges import KERNEL_HALF_WIDTH, find_edges
from digiteyes.features.lines import bisector, fit_lines
from digiteyes.features.slices import (
    cylinder_tangent_points,
    perpendicular,
    prepare_image,
    sample_profiles,
    sphere_tangent_points,
)
from digiteyes.kinematics import KinematicModel, Kinematics

LINK_REASONS = {
    "ok": "measured",
    "behind-camera": "the link is not in front of the camera",
    "foreshortened": "the projected axis is shorter than min_axis_px",
    "off-image": "fewer than min_edge_points slices inside the image",
    "few-edges": "no side has min_edge_points edge points",
    "fit-residual": "no side line fits its edge points within max_fit_rms_px",
    "inconsistent-sides": "the two side lines disagree in angle or in width",
    "background-side": "one side found, but the other side's window shows background",
    "outside-window": "the measured axis leaves the search window",
}
_LINK_CODES = np.array(list(LINK_REASONS))  # reason of each code, checked in priority order
TIP_REASONS = {
    "ok": "measured",
    "behind-camera": "the tip is not in front of the camera",
    "foreshortened": "the finger axis points at the camera (sin < 0.2)",
    "few-edges": "fewer than min_tip_edges tip slices found the silhouette end",
    "inconsistent": "the tip slices disagree by more than max_tip_spread_px",
}
_TIP_CODES = np.array(list(TIP_REASONS))
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
    max_side_angle_deg : largest angle between the two side lines of a link.
    max_width_error : largest difference between the measured distance of the two side
        lines and the predicted width of the link, as a fraction of the predicted width.
        Sides that disagree (in angle or width) mean that one of them followed something
        else (a neighbouring finger, a shading ramp): the link is then invalid rather
        than measured wrongly.
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
    max_width_error: float = 0.35
    min_axis_px: float = 5.0
    min_tip_edges: int = 2
    max_tip_spread_px: float = 3.0
    tip_end: str = "capsule"

    def __post_init__(self) -> None:
        positive = ("window_px", "tip_search_px", "step_px", "max_fit_rms_px",
                    "max_side_angle_deg", "max_tip_spread_px", "max_width_error")
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
    tracked = _tracked(model, None if links is None else tuple(links),
                       None if tips is None else tuple(tips), options.tip_end)
    # All model points of this camera (link axes, contour tangents, tip silhouettes) are
    # projected in one call.
    link_3d, link_depth = _link_points(camera, shapes, tracked, options)
    tip_3d, sin_view = _tip_points(camera, shapes, tracked)
    w = camera.project(np.concatenate([link_3d.reshape(-1, 3), tip_3d.reshape(-1, 3)]))
    n = link_3d.shape[0] * link_3d.shape[1]
    behind_link = behind_tip = False
    if camera.projection == "perspective":
        depth = camera.depth(np.concatenate([link_depth.reshape(-1, 3), tip_3d[:, 0]]))
        behind_link = (depth[:link_depth.shape[0] * 2].reshape(-1, 2)
                       <= tracked.link_radii[:, None]).any(axis=1)
        behind_tip = depth[link_depth.shape[0] * 2:] <= tracked.tip_radii
    link_part = _measure_links(gray, camera, w[:n].reshape((*link_3d.shape[:2], 2)),
                               behind_link, tracked, options)
    tip_part = _measure_tips(gray, w[n:].reshape(-1, 3, 2), sin_view, behind_tip, tracked,
                             link_part, options)
    return FeatureMeasurement(camera=camera.name, link_ids=tracked.link_ids,
                              tip_ids=tracked.tip_ids, **link_part, **tip_part)


@dataclass(frozen=True)
class _Tracked:
    """What a tracker set needs from the model, computed once per (model, selection)."""

    link_ids: np.ndarray
    link_rows: np.ndarray
    link_lengths: np.ndarray
    link_radii: np.ndarray
    tip_ids: np.ndarray
    tip_rows: np.ndarray
    tip_axis_rows: np.ndarray  # row whose shape-frame x axis is the finger axis at the tip
    tip_radii: np.ndarray  # radius of the finger end (see FeatureOptions.tip_end)
    tip_parent: np.ndarray  # position of the tip's parent link in link_ids, -1 if none


@lru_cache(maxsize=64)
def _tracked(model: KinematicModel, links: tuple[str, ...] | None,
             tips: tuple[str, ...] | None, tip_end: str) -> _Tracked:
    link_ids = select_links(model, links, "link")
    tip_ids = select_links(model, tips, "tip")
    row_to_link = {link.row: i for i, link in enumerate(model.links) if link.kind == "link"}
    parents = [row_to_link.get(int(model.parent[model.links[i].row]), -1) for i in tip_ids]
    position = {int(link): k for k, link in enumerate(link_ids)}
    tip_radii = [model.links[i].radius for i in tip_ids]
    if tip_end == "capsule":
        tip_radii = [max(r, model.links[p].radius) if p >= 0 else r
                     for r, p in zip(tip_radii, parents, strict=True)]
    tracked = _Tracked(
        link_ids=link_ids,
        link_rows=np.array([model.links[i].row for i in link_ids], dtype=int),
        link_lengths=np.array([model.links[i].length for i in link_ids], dtype=float),
        link_radii=np.array([model.links[i].radius for i in link_ids], dtype=float),
        tip_ids=tip_ids,
        tip_rows=np.array([model.links[i].row for i in tip_ids], dtype=int),
        tip_axis_rows=np.array([model.links[p].row if p >= 0 else model.links[i].row
                                for i, p in zip(tip_ids, parents, strict=True)], dtype=int),
        tip_radii=np.array(tip_radii, dtype=float),
        tip_parent=np.array([position.get(p, -1) for p in parents], dtype=int),
    )
    for field in fields(tracked):
        getattr(tracked, field.name).setflags(write=False)  # shared through the cache
    return tracked


@lru_cache(maxsize=16)
def _fractions(end_margin: float, n_slices: int) -> np.ndarray:
    """Axis fractions of the link start, end and slice positions."""
    t = np.concatenate([[0.0, 1.0], np.linspace(end_margin, 1.0 - end_margin, n_slices)])
    t.setflags(write=False)
    return t


def _link_points(camera, shapes, tracked, opt) -> tuple[np.ndarray, np.ndarray]:
    """World points to project per link (L, 2 + 3 S, 3): axis start and end, slice centres,
    contour tangent points; and the axis ends (L, 2, 3) for the depth test."""
    T = shapes[tracked.link_rows]
    start, axis = T[:, :3, 3], T[:, :3, 0]
    t = _fractions(opt.end_margin, opt.slices_per_link)
    p_axis = start[:, None] + (t[:, None] * tracked.link_lengths[:, None, None]) * axis[:, None]
    tangent = cylinder_tangent_points(camera, p_axis[:, 2:], axis[:, None],
                                      tracked.link_radii[:, None])
    n_links = len(tracked.link_ids)
    return np.concatenate([p_axis, tangent.reshape(n_links, -1, 3)], axis=1), p_axis[:, :2]


def _tip_points(camera, shapes, tracked) -> tuple[np.ndarray, np.ndarray]:
    """World points to project per tip (T, 3, 3): centre, silhouette along and beside the
    finger axis; and the sine of the axis' angle to the viewing ray (T,)."""
    centre = shapes[tracked.tip_rows, :3, 3]
    axis = shapes[tracked.tip_axis_rows, :3, 0]
    tangent, sin_view = sphere_tangent_points(camera, centre, axis, tracked.tip_radii)
    return np.concatenate([centre[:, None], tangent], axis=1), sin_view


def _first_reason(conditions: list[np.ndarray]) -> np.ndarray:
    """Code of the first true condition per feature (1-based; 0 if none)."""
    code = np.zeros(len(conditions[0]), dtype=int)
    for k in range(len(conditions), 0, -1):
        code[conditions[k - 1]] = k
    return code


def _unit2(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit image vectors (..., 2) (``(1, 0)`` for zero vectors) and their lengths."""
    length = np.sqrt(np.sum(v * v, axis=-1))
    safe = np.where(length > 0, length, 1.0)[..., None]
    return np.where(length[..., None] > 0, v / safe, [1.0, 0.0]), length


def _measure_links(gray, camera, w, behind, tracked, opt) -> dict:
    n_links, n_slices = len(tracked.link_ids), opt.slices_per_link
    w_ends = w[:, :2]
    w_slices = w[:, 2:2 + n_slices]
    u, length_px = _unit2(w_ends[:, 1] - w_ends[:, 0])
    normal = perpendicular(u)
    w_tangent = w[:, 2 + n_slices:].reshape(n_links, n_slices, 2, 2)
    contour = np.sort(np.sum((w_tangent - w_slices[:, :, None]) * normal[:, None, None],
                             axis=-1), axis=-1)  # (L, S, 2): side 0 < 0 < side 1

    behind = behind | ~np.isfinite(contour).all(axis=(1, 2))
    short = length_px < opt.min_axis_px
    off_image = camera.in_image(w_slices).sum(axis=1) < opt.min_edge_points
    usable = ~(behind | short | off_image)
    contour = np.where(usable[:, None, None], contour, np.nan)

    # One bilinear lookup for every slice of every link: profiles (L * S, J).
    reach = np.nanmax(np.abs(contour)) if usable.any() else 0.0
    offsets = _sample_grid(reach + 0.5 * opt.window_px, opt.step_px)
    origins = np.where(usable[:, None, None], w_slices, -1e4)
    profiles, inside = sample_profiles(gray, origins.reshape(-1, 2),
                                       np.repeat(normal, n_slices, axis=0), offsets)
    polarity = 1.0 if opt.bright_object else -1.0
    edges = find_edges(profiles, inside, contour.reshape(-1, 2), np.array([polarity, -polarity]),
                       offsets, 0.5 * opt.window_px, opt.min_contrast)

    def per_side(a: np.ndarray) -> np.ndarray:  # (L * S, 2) -> (L, 2, S)
        return a.reshape(n_links, n_slices, 2).transpose(0, 2, 1)

    position = per_side(edges.position)
    found = np.isfinite(position)
    edge_points = w_slices[:, None] + position[..., None] * normal[:, None, None]
    side_normal = normal[:, None]
    fit = fit_lines(edge_points, found, robust=opt.robust, normal=side_normal)
    side_ok = (fit.count >= opt.min_edge_points) & (fit.rms <= opt.max_fit_rms_px)
    both = side_ok[:, 0] & side_ok[:, 1]
    one = side_ok[:, 0] != side_ok[:, 1]
    middle = w_slices[:, n_slices // 2]
    offset_middle = np.sum(fit.line[..., :2] * middle[:, None], axis=-1) - fit.line[..., 2]
    width = offset_middle[:, 0] - offset_middle[:, 1]
    predicted_width = contour[:, n_slices // 2, 1] - contour[:, n_slices // 2, 0]
    cos_sides = np.abs(np.sum(fit.line[:, 0, :2] * fit.line[:, 1, :2], axis=-1))
    agree = (cos_sides >= math.cos(math.radians(opt.max_side_angle_deg))) & (
        np.abs(width - predicted_width) <= opt.max_width_error * predicted_width)
    line = bisector(fit.line[:, 0], fit.line[:, 1])
    merged = np.zeros(n_links, dtype=bool)
    if one.any():
        # One-edge fallback: the usable side's inliers moved onto the predicted axis by
        # their predicted contour offsets, then one line through them.
        contour_sides = contour.transpose(0, 2, 1)
        axis_points = w_slices[:, None] + (position - contour_sides)[..., None] \
            * normal[:, None, None]
        shifted = fit_lines(axis_points, fit.inlier, robust="none", normal=side_normal).line
        line = np.where(both[:, None], line,
                        np.where(side_ok[:, 1:], shifted[:, 1], shifted[:, 0]))
        merged = _missing_side_is_object(edges, fit.inlier, side_ok, per_side, polarity)
    end_slices = w_slices[:, [0, -1]]
    distance = np.abs(np.sum(line[:, None, :2] * end_slices, axis=-1) - line[:, None, 2])
    outside = ~(distance <= 0.5 * opt.window_px).all(axis=1)
    enough = (fit.count >= opt.min_edge_points).any(axis=1)

    code = _first_reason([behind, short, off_image, ~enough, ~(both | one), both & ~agree,
                          one & ~merged, outside])
    valid = code == 0
    half = 0.5 * opt.window_px
    span = np.stack([contour[..., 0] - half, contour[..., 1] + half], axis=-1)
    return {
        "predicted_axis": w_ends,
        "line": np.where(valid[:, None], line, np.nan),
        "link_valid": valid,
        "link_reason": _LINK_CODES[code],
        "n_edges": fit.count,
        "side_lines": np.where(side_ok[..., None], fit.line, np.nan),
        "edge_points": edge_points,
        "edge_inlier": fit.inlier,
        "slice_centres": w_slices,
        "slice_normal": normal,
        "slice_ends": w_slices[..., None, :] + span[..., None] * normal[:, None, None],
        "contour_offsets": contour,
    }


def _missing_side_is_object(edges, inlier, side_ok, per_side, polarity) -> np.ndarray:
    """Whether the side without a usable line looks like the finger, per link (L,).

    The one-edge fallback is right when the other silhouette edge vanished into a region
    as bright as the finger (another finger, the palm). If the other side's search ranges
    show background instead, the found "edges" cannot be the finger's silhouette (the
    missing edge would lie in those ranges): they are shading ramps or clutter seen from a
    prediction that is off the finger. The finger and background levels are read 3 px
    inside and outside the found side's inlier edges.
    """
    before, after = per_side(edges.before), per_side(edges.after)
    inner = np.stack([after[:, 0], before[:, 1]], axis=1)  # side 0 edges face +normal
    outer = np.stack([before[:, 0], after[:, 1]], axis=1)
    use = inlier & side_ok[..., None]
    count = np.maximum(use.sum(axis=(1, 2)), 1)
    finger = np.sum(np.where(use, inner, 0.0), axis=(1, 2)) / count
    background = np.sum(np.where(use, outer, 0.0), axis=(1, 2)) / count
    window = per_side(edges.window_mean)
    seen_mask = ~side_ok[..., None] & np.isfinite(window)
    seen = np.sum(np.where(seen_mask, window, 0.0), axis=(1, 2)) / np.maximum(
        seen_mask.sum(axis=(1, 2)), 1)
    return polarity * (seen - 0.5 * (finger + background)) > 0.0


def _measure_tips(gray, w, sin_view, behind, tracked, link_part, opt) -> dict:
    n_tips = len(tracked.tip_ids)
    w_c = w[:, 0]
    u, along = _unit2(w[:, 1] - w_c)
    across = np.sqrt(np.sum((w[:, 2] - w_c) ** 2, axis=-1))
    behind = behind | ~(np.isfinite(along) & np.isfinite(across))
    short = ~behind & ~(sin_view >= MIN_TIP_SIN)
    usable = ~(behind | short)

    # Lateral position and direction from the measured axis of the parent link, if valid.
    k = tracked.tip_parent
    has_line = (k >= 0) & usable
    has_line[has_line] = link_part["link_valid"][k[has_line]]
    line = (link_part["line"][np.maximum(k, 0)] if len(tracked.link_ids)
            else np.zeros((n_tips, 3)))
    m = line[:, :2]
    base = np.where(has_line[:, None],
                    w_c - (np.sum(m * w_c, axis=-1) - line[:, 2])[:, None] * m, w_c)
    along_line = np.stack([m[:, 1], -m[:, 0]], axis=-1)
    along_line *= np.where(np.sum(along_line * u, axis=-1) < 0, -1.0, 1.0)[:, None]
    direction = np.where(has_line[:, None], along_line, u)
    lateral = perpendicular(direction)

    expected_end = along[:, None] * np.sqrt(1.0 - TIP_LATERAL**2)[None, :]  # (T, K)
    origins = (base[:, None] + (TIP_LATERAL[None, :] * across[:, None])[..., None]
               * lateral[:, None] + expected_end[..., None] * direction[:, None])
    origins = np.where(usable[:, None, None], origins, -1e4)
    half = 0.5 * opt.tip_search_px
    offsets = _sample_grid(half, opt.step_px)
    profiles, inside = sample_profiles(gray, origins, direction[:, None], offsets)
    polarity = 1.0 if opt.bright_object else -1.0
    centre = np.where(usable[:, None], 0.0, np.nan) * np.ones((1, len(TIP_LATERAL)))
    shift = find_edges(profiles.reshape(-1, len(offsets)), inside.reshape(-1, len(offsets)),
                       centre.reshape(-1, 1), np.array([-polarity]), offsets, half,
                       opt.min_contrast).position
    shift = shift.reshape(n_tips, len(TIP_LATERAL))  # (T, K): end moved along the axis
    found = np.isfinite(shift)
    edge_points = origins + shift[..., None] * direction[:, None]
    count = found.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_shift = np.where(found, shift, 0.0).sum(axis=1) / count
    spread = (np.where(found, shift, -np.inf).max(axis=1, initial=-np.inf)
              - np.where(found, shift, np.inf).min(axis=1, initial=np.inf))
    few = count < opt.min_tip_edges
    code = _first_reason([behind, short, few, spread > opt.max_tip_spread_px])
    valid = code == 0
    measured = base + mean_shift[:, None] * direction
    ends = np.stack([origins - half * direction[:, None], origins + half * direction[:, None]],
                    axis=-2)
    return {
        "predicted_tip": w_c,
        "measured_tip": np.where(valid[:, None], measured, np.nan),
        "tip_valid": valid,
        "tip_reason": _TIP_CODES[code],
        "tip_direction": direction,
        "tip_slice_ends": ends,
        "tip_edge_points": edge_points,
    }


def project_features(
    camera: Camera,
    model: KinematicModel,
    kin: Kinematics,
    links: Sequence[str] | None = None,
    tips: Sequence[str] | None = None,
) -> FeatureMeasurement:
    """The features a perfect measurement would return for the state of ``kin``.

    Link lines are the projected axes, tips the projected tip centres; features behind a
    perspective camera or with a degenerate (zero-length) projected axis are invalid.
    No image is involved, so the slice and edge arrays are empty (S = 0). Use it to test
    solvers on exact data and as the zero-residual reference of
    :func:`~digiteyes.features.feature_residuals`.
    """
    shapes = _single_state_shapes(kin)
    link_ids = select_links(model, links, "link")
    tip_ids = select_links(model, tips, "tip")
    rows = np.array([model.links[i].row for i in link_ids], dtype=int)
    lengths = np.array([model.links[i].length for i in link_ids], dtype=float)
    start = shapes[rows, :3, 3]
    end = start + shapes[rows, :3, 0] * lengths[:, None]
    w_ends = camera.project(np.stack([start, end], axis=1)).reshape(-1, 2, 2)
    u, length_px = _unit2(w_ends[:, 1] - w_ends[:, 0])
    normal = perpendicular(u)
    rho = np.sum(normal * w_ends[:, 0], axis=-1)
    tip_rows = np.array([model.links[i].row for i in tip_ids], dtype=int)
    centre3 = shapes[tip_rows, :3, 3]
    w_tip = camera.project(centre3).reshape(-1, 2)
    link_ok = (length_px > 0) & np.isfinite(w_ends).all(axis=(1, 2))
    tip_ok = np.isfinite(w_tip).all(axis=1)
    if camera.projection == "perspective":
        link_ok &= (camera.depth(np.stack([start, end], axis=1)) > 0).all(axis=1)
        tip_ok &= camera.depth(centre3) > 0
    n_links, n_tips = len(link_ids), len(tip_ids)
    k = len(TIP_LATERAL)
    return FeatureMeasurement(
        camera=camera.name, link_ids=link_ids, predicted_axis=w_ends,
        line=np.where(link_ok[:, None], np.column_stack([normal, rho]), np.nan),
        link_valid=link_ok, link_reason=np.where(link_ok, "ok", "behind-camera"),
        n_edges=np.zeros((n_links, 2), dtype=int), side_lines=np.full((n_links, 2, 3), np.nan),
        edge_points=np.zeros((n_links, 2, 0, 2)), edge_inlier=np.zeros((n_links, 2, 0), bool),
        slice_centres=np.zeros((n_links, 0, 2)), slice_normal=normal,
        slice_ends=np.zeros((n_links, 0, 2, 2)), contour_offsets=np.zeros((n_links, 0, 2)),
        tip_ids=tip_ids, predicted_tip=w_tip, measured_tip=np.where(tip_ok[:, None], w_tip, np.nan),
        tip_valid=tip_ok, tip_reason=np.where(tip_ok, "ok", "behind-camera"),
        tip_direction=np.tile([1.0, 0.0], (n_tips, 1)),
        tip_slice_ends=np.full((n_tips, k, 2, 2), np.nan),
        tip_edge_points=np.full((n_tips, k, 2), np.nan),
    )
