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
track loss. The work per camera runs in two compiled loops, one over the links and one over the tips
(``features/_kernels.py``, docs/features.md "Performance").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import CameraError, DigitEyesError, StateError
from digiteyes.features._kernels import TIP_LATERAL, links_kernel, tips_kernel
from digiteyes.features.lines import ROBUST_LOSSES
from digiteyes.features.slices import perpendicular, prepare_image, view_of
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
    slice_fractions : (S,) where the slices cross each link, as fractions of its length from
        its base (the same for every link).
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
    slice_fractions: np.ndarray
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


LINE_KINDS = ("link", "edge")  # measured as lines: cylinder links and tracked body edges


def select_links(model: KinematicModel, names: Sequence[str] | None,
                 kinds: tuple[str, ...]) -> np.ndarray:
    """Indices into ``model.links`` of the named links of the given kinds (all of them if
    None)."""
    if names is None:
        return np.array([i for i, link in enumerate(model.links) if link.kind in kinds],
                        dtype=int)
    index = {link.name: i for i, link in enumerate(model.links)}
    out = []
    for name in names:
        if name not in index:
            raise KeyError(f"model {model.name!r} has no link {name!r}")
        if model.links[index[name]].kind not in kinds:
            raise ValueError(
                f"{name!r} is a {model.links[index[name]].kind!r}, expected one of "
                f"{', '.join(kinds)}"
            )
        out.append(index[name])
    return np.array(out, dtype=int)


def _single_state_shapes(kin: Kinematics) -> np.ndarray:
    if kin.T_world_shape.shape[0] != 1:
        raise StateError(
            f"measure_features needs the kinematics of one state, got {kin.T_world_shape.shape[0]}"
        )
    return kin.T_world_shape[0]


def usual_side_signs(n_links: int, options: FeatureOptions = FeatureOptions()) -> np.ndarray:
    """(n_links, 2) edge signs of the thesis's search (Sec. 4.3.1): ``(+1, -1)`` for a hand
    brighter than its backdrop, ``(-1, +1)`` without ``bright_object``."""
    polarity = 1.0 if options.bright_object else -1.0
    return np.tile([polarity, -polarity], (n_links, 1))


def measure_features(
    image: np.ndarray,
    camera: Camera,
    model: KinematicModel,
    kin: Kinematics,
    options: FeatureOptions = FeatureOptions(),
    links: Sequence[str] | None = None,
    tips: Sequence[str] | None = None,
    side_signs: np.ndarray | None = None,
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
    side_signs : (L, 2) the edge sign each side of each measured link looks for, in the
        order of the returned ``link_ids`` (:func:`~digiteyes.features.edge_signs.
        learn_side_signs`); None: ``(+1, -1)`` for every link, flipped without
        ``bright_object``.

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
    view, perspective = view_of(camera)
    params = camera.projection_params
    polarity = 1.0 if options.bright_object else -1.0  # the tips' search keeps one sign
    n_tracked = len(tracked.link_ids)
    if side_signs is None:
        side_signs = usual_side_signs(n_tracked, options)
    side_signs = np.asarray(side_signs, dtype=float)
    if side_signs.shape != (n_tracked, 2):
        raise DigitEyesError(f"side_signs must be ({n_tracked}, 2), one sign per side of "
                             f"each measured link, got shape {side_signs.shape}")
    side_samples = round(3.0 / options.step_px)  # intensities 3 px either side of an edge
    n_links, n_slices = len(tracked.link_ids), options.slices_per_link
    link = {
        "predicted_axis": np.empty((n_links, 2, 2)),
        "slice_centres": np.empty((n_links, n_slices, 2)),
        "slice_normal": np.empty((n_links, 2)),
        "contour_offsets": np.empty((n_links, n_slices, 2)),
        "line": np.empty((n_links, 3)),
        "code": np.empty(n_links, dtype=np.int64),
        "n_edges": np.empty((n_links, 2), dtype=np.int64),
        "side_lines": np.empty((n_links, 2, 3)),
        "edge_points": np.empty((n_links, 2, n_slices, 2)),
        "edge_inlier": np.empty((n_links, 2, n_slices), dtype=bool),
        "slice_ends": np.empty((n_links, n_slices, 2, 2)),
    }
    links_kernel(gray, params, view, perspective, shapes, tracked.link_rows,
                 tracked.link_lengths, tracked.link_radii,
                 _fractions(options.end_margin, n_slices), options.min_axis_px,
                 options.min_edge_points, 0.5 * options.window_px, options.step_px,
                 options.min_contrast, side_signs, ROBUST_LOSSES.index(options.robust),
                 options.max_fit_rms_px, math.cos(math.radians(options.max_side_angle_deg)),
                 options.max_width_error, side_samples, *link.values())
    link_code = link.pop("code")
    n_tips = len(tracked.tip_ids)
    tip = {
        "predicted_tip": np.empty((n_tips, 2)),
        "measured_tip": np.empty((n_tips, 2)),
        "code": np.empty(n_tips, dtype=np.int64),
        "tip_direction": np.empty((n_tips, 2)),
        "tip_slice_ends": np.empty((n_tips, len(TIP_LATERAL), 2, 2)),
        "tip_edge_points": np.empty((n_tips, len(TIP_LATERAL), 2)),
    }
    tips_kernel(gray, params, view, perspective, shapes, tracked.tip_rows,
                tracked.tip_axis_rows, tracked.tip_radii, tracked.tip_parent, link["line"],
                link_code, 0.5 * options.tip_search_px, options.step_px, options.min_contrast,
                polarity, options.min_tip_edges, options.max_tip_spread_px, side_samples,
                *tip.values())
    tip_code = tip.pop("code")
    return FeatureMeasurement(
        camera=camera.name, link_ids=tracked.link_ids,
        slice_fractions=_fractions(options.end_margin, n_slices)[2:], link_valid=link_code == 0,
        link_reason=_LINK_CODES[link_code], tip_ids=tracked.tip_ids, tip_valid=tip_code == 0,
        tip_reason=_TIP_CODES[tip_code], **link, **tip)


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
    link_ids = select_links(model, links, LINE_KINDS)
    tip_ids = select_links(model, tips, ("tip",))
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


def _unit2(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit image vectors (..., 2) (``(1, 0)`` for zero vectors) and their lengths."""
    length = np.sqrt(np.sum(v * v, axis=-1))
    safe = np.where(length > 0, length, 1.0)[..., None]
    return np.where(length[..., None] > 0, v / safe, [1.0, 0.0]), length


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
    link_ids = select_links(model, links, LINE_KINDS)
    tip_ids = select_links(model, tips, ("tip",))
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
        slice_centres=np.zeros((n_links, 0, 2)), slice_fractions=np.zeros(0),
        slice_normal=normal,
        slice_ends=np.zeros((n_links, 0, 2, 2)), contour_offsets=np.zeros((n_links, 0, 2)),
        tip_ids=tip_ids, predicted_tip=w_tip, measured_tip=np.where(tip_ok[:, None], w_tip, np.nan),
        tip_valid=tip_ok, tip_reason=np.where(tip_ok, "ok", "behind-camera"),
        tip_direction=np.tile([1.0, 0.0], (n_tips, 1)),
        tip_slice_ends=np.full((n_tips, k, 2, 2), np.nan),
        tip_edge_points=np.full((n_tips, k, 2), np.nan),
    )
