"""Layered templates: acquisition, refresh and the layered template error with its
region and boundary derivatives (Rehg thesis Sec. 2.4, 3.3, 4.4).

Per camera, every part (:func:`~digiteyes.occlusion.parts.template_parts`) carries a
template: grey levels of the LoG-filtered image (Sec. 2.4.2) at template pixels on the
part's template plane. With ``f_k(q, s)`` the deformation of part k's pixel ``s``
(:mod:`digiteyes.templates.deformation`) and the parts in visibility order
(:mod:`digiteyes.occlusion.visibility`), the *layered template error* is

    E(q) = 1/2 sum_k sum_s V_k(q, s) [I(f_k(q, s)) - T_k(s)]^2,
    V_k(q, s) = prod_{j occludes k} [1 - M_j(q, f_k(q, s))],

the template-coordinate form of thesis eq. 3.7 (each image pixel is counted by the
template that owns it in the window tree, eq. 3.9; pixels of a template hidden behind
the windows ``M_j`` of its occluders drop out). Its gradient has the two parts of thesis
Sec. 3.3.3:

* region terms ``sum V r dr/dq``, ``dr/dq = grad I^T df/dq`` (eq. 3.10, 2.13);
* boundary terms ``sum r^2 / 2 dV/dq``: the occluders' windows moving over the pixel
  (and the pixel moving under them), the covering and revealing of eq. 3.12. With unit
  windows (Sec. 4.4.2) they vanish almost everywhere; smooth windows give them a
  width (``tau``).

*What hiding costs* (ours; ``TemplateOptions.hidden_residual`` ``h``): in this form a
pixel hidden behind an occluder's window simply leaves the sum, so a link whose pixels
do not match can lower ``E`` by slipping behind another part (a finger that reopened
stays folded under its own proximal phalanx and the palm, the desk pair of
docs/templates.md). With ``h > 0`` each hidden pixel is charged as a seen one with
residual ``h``:

    E_h(q) = E(q) + 1/2 sum_k sum_s [1 - V_k(q, s)] h^2,

so hiding pays only where the residual exceeds ``h``; its gradient is the boundary term
with ``r^2 - h^2`` in place of ``r^2``. ``h = 0`` is the thesis's error.

Gauss-Newton (eq. 2.22) uses ``H = sum V J^T J`` of the region terms and the full
gradient; gradient descent (eq. 2.12) uses the gradient alone.

Acquisition needs no label image: the templates are sampled from a frame with a known
state where the model's own visibility order says the part is seen (``V = 1``).
Refresh (tracking on) blends the observed grey levels of well-seen pixels into the
template at a small rate when the frame fitted well, and pulls every template back
towards its reference by another small rate, so slow appearance changes are followed
while a bad frame cannot rewrite a template and errors cannot accumulate without bound.
With one camera the rate of each part is also scaled by how far the part has turned
against the camera since its template was last written (``refresh_turn_deg``): a part
that holds still keeps its template, and the estimate's error along the line of sight,
which one camera cannot see, is not written into it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import Kinematics
from digiteyes.kinematics.rotations import matrix_angle
from digiteyes.occlusion.parts import (
    TemplatePart,
    TemplatePlane,
    facing_plane,
    mm_per_pixel,
    template_grid,
)
from digiteyes.occlusion.visibility import VisibilityOrder, predict_visibility
from digiteyes.occlusion.windows import ImageWindows, image_windows
from digiteyes.templates._kernels import layered_kernel, transform_kernel
from digiteyes.templates.deformation import part_twists
from digiteyes.templates.filtering import LogFilter, TemplateError

WINDOWS = ("unit", "smooth")
JOINT_DEPTH_TIE_MM = 1.0
"""With ``pixel_depth_at_joints``: where the two links of a joint lie within this many mm
of each other along a pixel's ray (at the joint, where their surfaces meet) the joint
rule decides which one is seen."""
HIDDEN_RESIDUAL_RIG = 16.0
"""``TemplateOptions.hidden_residual`` on rigs of two cameras or more, grey levels: about
three times the visible residual's RMS of a frame that fits (4.8-5.5 on the desk pair of
``bench accuracy``)."""


@dataclass(frozen=True)
class TemplateOptions:
    """How templates are made, compared and refreshed.

    Attributes
    ----------
    log : the LoG filter of images and templates (thesis Sec. 2.4.2). The thesis used
        13 x 13 (Sec. 4.4.2); at 640 x 480 a 7 x 7 kernel tracked better here
        (docs/templates.md), so that is the default, contrast-normalised over 2 px
        (:mod:`digiteyes.templates.filtering`; the shading of curved links otherwise
        moves the error's minimum off the truth).
    spacing_px : template pixel spacing in image pixels at acquisition (1: one template
        pixel per image pixel; 2 quarters the work).
    window : ``"unit"`` (thesis Sec. 4.4.2) or ``"smooth"`` (logistic windows).
    window_px : width ``tau`` of the smooth windows, px.
    refresh_rate : fraction of a well-seen pixel's observed value blended into the
        template per frame (0: never refresh).
    reference_pull : fraction by which every template moves back to its reference per
        refreshed frame (the drift guard).
    refresh_max_rms : refresh only frames whose visible-pixel residual RMS is below this
        (grey levels of the filtered image).
    refresh_min_visibility : a pixel is well seen when its ``V`` is at least this.
    refresh_turn_deg : None refreshes every part at ``refresh_rate``; a number gates each
        part's refresh by how far the part has turned against the camera since its
        template was last written (the rotation of its shape frame in the camera frame):
        the rate is ``refresh_rate * min(1, turn / refresh_turn_deg)``, and the written
        orientation follows by the same fraction (every part's, seen in the frame or not:
        a part that turns while hidden is not refreshed faster when it reappears, a
        simplification). A part that does not turn keeps its
        template, so the refresh cannot make it drift (docs/templates.md, "Refresh and
        drift").
    refresh_turn_cameras : the gate applies to rigs of at most this many cameras (1: one
        camera, which cannot see a still part's drift along its line of sight; a second
        view pins it, and there the ungated refresh tracked better).
    occlusion_margin_px : occluding outlines are grown by this much (px) in the layered
        error (about the LoG's reach), and parts this close count as overlapping.
    filter_pad_px : after the first frame, images are filtered only within this many px
        of the box around the hand's windows at the predicted state (the template pixels
        a frame's iterations can reach); None filters whole images.
    pixel_depth_at_joints : the two links of a revolute joint occlude each other pixel by
        pixel (where the other's surface lies nearer the camera along the pixel's ray)
        instead of by the joint rule of Sec. 3.2.2 over their whole overlap
        (docs/templates.md, "Joints ordered pixel by pixel"); None (default): on rigs of
        two cameras or more, which fix the links' depths, off with one camera, where it
        cost the two-finger index joints (:meth:`for_rig`).
    hidden_residual : a template pixel that a window hides costs what a seen one with this
        residual costs (grey levels of the filtered image), so that a link cannot lower
        the error by slipping behind another part where the image does not match it
        (docs/templates.md, "What hiding costs"). 0 is the thesis's error (eq. 3.7); None
        (default): :data:`HIDDEN_RESIDUAL_RIG` on rigs of two cameras or more, 0 with one
        camera, where the cost held the two-finger index back from occluding
        (:meth:`for_rig`).
    """

    log: LogFilter = field(default_factory=lambda: LogFilter(size=7, contrast_px=2.0))
    spacing_px: float = 2.0
    window: str = "smooth"
    window_px: float = 1.0
    refresh_rate: float = 0.3
    reference_pull: float = 0.02
    refresh_max_rms: float = 12.0
    refresh_min_visibility: float = 0.99
    refresh_turn_deg: float | None = 3.0
    refresh_turn_cameras: int = 1
    occlusion_margin_px: float = 3.0
    filter_pad_px: float | None = 40.0
    pixel_depth_at_joints: bool | None = None
    hidden_residual: float | None = None

    def __post_init__(self) -> None:
        if self.window not in WINDOWS:
            raise TemplateError(f"window must be 'unit' or 'smooth', got {self.window!r}")
        if not self.spacing_px > 0:
            raise TemplateError(f"spacing_px must be positive, got {self.spacing_px!r}")
        if not self.window_px > 0:
            raise TemplateError(f"window_px must be positive, got {self.window_px!r}")
        if self.refresh_turn_deg is not None and not self.refresh_turn_deg > 0:
            raise TemplateError(f"refresh_turn_deg must be None or positive, got "
                                f"{self.refresh_turn_deg!r}")
        if isinstance(self.refresh_turn_cameras, bool) or \
                not isinstance(self.refresh_turn_cameras, int) or self.refresh_turn_cameras < 1:
            raise TemplateError(f"refresh_turn_cameras must be a positive integer, got "
                                f"{self.refresh_turn_cameras!r}")
        if self.hidden_residual is not None and not self.hidden_residual >= 0:
            raise TemplateError(f"hidden_residual must be None or not negative, got "
                                f"{self.hidden_residual!r}")
        if self.filter_pad_px is not None and not self.filter_pad_px >= 0:
            raise TemplateError(f"filter_pad_px must be None or not negative, got "
                                f"{self.filter_pad_px!r}")
        for name in ("refresh_rate", "reference_pull", "refresh_min_visibility"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise TemplateError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")

    def for_rig(self, n_cameras: int) -> TemplateOptions:
        """These settings as a rig of ``n_cameras`` uses them: the refresh ungated
        (``refresh_turn_deg`` None) beyond ``refresh_turn_cameras`` cameras, and
        ``pixel_depth_at_joints`` and ``hidden_residual`` decided (on with two cameras or
        more unless set)."""
        rig = self
        if self.pixel_depth_at_joints is None:
            rig = replace(rig, pixel_depth_at_joints=n_cameras >= 2)
        if self.hidden_residual is None:
            rig = replace(rig, hidden_residual=HIDDEN_RESIDUAL_RIG if n_cameras >= 2 else 0.0)
        if self.refresh_turn_deg is None or n_cameras <= self.refresh_turn_cameras:
            return rig
        return replace(rig, refresh_turn_deg=None)

    @property
    def tau(self) -> float:
        """Window width passed to the kernels (0 for unit windows), px."""
        return 0.0 if self.window == "unit" else float(self.window_px)


@dataclass
class CameraTemplates:
    """The templates of all parts for one camera.

    Attributes
    ----------
    parts : the parts, in model order.
    ab : (P, 2) template coordinates of all template pixels, mm, part after part.
    part_of : (P,) part index of each pixel; ``slices`` the pixel range of each part.
    values, reference : (P,) current and reference template grey levels (filtered).
    weights : (P,) 1 where the pixel has been seen (acquired), else 0.
    palm_side : (K,) the palm face each palm template lies on (+1 palmar, -1 dorsal).
    views : (K, 3, 3) each part's orientation in the camera frame (``R_cam_shape``) when
        its template was written (acquisition, then refreshes), for
        ``TemplateOptions.refresh_turn_deg``.
    radii : (K,) the parts' radii, mm (derived from ``parts``; the pixel order at joints).
    """

    parts: tuple[TemplatePart, ...]
    ab: np.ndarray
    part_of: np.ndarray
    slices: list[slice]
    values: np.ndarray
    reference: np.ndarray
    weights: np.ndarray
    palm_side: np.ndarray
    views: np.ndarray
    radii: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.radii = np.array([part.radius for part in self.parts], dtype=float)

    def planes(self, kin: Kinematics, camera: Camera) -> list[TemplatePlane]:
        """Every part's template plane facing ``camera`` at the state of ``kin``."""
        return [facing_plane(p, kin, camera, float(self.palm_side[k]))
                for k, p in enumerate(self.parts)]

    def shape_points(self, planes: list[TemplatePlane]) -> np.ndarray:
        """Shape-frame points (P, 3) of all template pixels on ``planes``, mm."""
        out = np.empty((len(self.ab), 3))
        for plane, sl in zip(planes, self.slices, strict=True):
            out[sl] = plane.points(self.ab[sl])
        return out


@dataclass
class LayeredEvaluation:
    """The layered template error of one camera at one state.

    Attributes
    ----------
    energy : ``E`` (grey levels squared).
    H, gradient : (n_v, n_v) Gauss-Newton matrix of the region terms and the full
        gradient ``dE/dv`` (region + boundary); None when evaluated without derivatives.
    gradient_region, gradient_boundary : the two parts of the gradient (eq. 3.10, 3.12);
        None without derivatives.
    residuals, visibility, pixels : (P,) ``r``, (P,) ``V`` and (P, 2) image positions of
        the template pixels.
    windows, order : the windows and the visibility order used.
    rows_region, rows_visibility : (P, n_v) ``dr/dv`` and ``dV/dv`` when asked for.
    """

    energy: float
    H: np.ndarray | None
    gradient: np.ndarray | None
    gradient_region: np.ndarray | None
    gradient_boundary: np.ndarray | None
    residuals: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray
    windows: ImageWindows
    order: VisibilityOrder
    rows_region: np.ndarray | None = None
    rows_visibility: np.ndarray | None = None

    @property
    def visible_rms(self) -> float:
        """RMS of the residuals weighted by visibility (grey levels); NaN if none."""
        v = self.visibility
        total = float(v.sum())
        return float(np.sqrt((v * self.residuals ** 2).sum() / total)) if total > 0 else np.nan


def world_points(templates: CameraTemplates, kin: Kinematics,
                 p_shape: np.ndarray) -> np.ndarray:
    """World positions (P, 3) of the template pixels ``p_shape`` at the state of ``kin``."""
    frames = np.ascontiguousarray(kin.T_world_shape[0][[p.row for p in templates.parts]])
    out = np.empty_like(p_shape)
    transform_kernel(frames, templates.part_of, p_shape, out)
    return out


def evaluate_layered(templates: CameraTemplates, image: np.ndarray, camera: Camera,
                     kin: Kinematics, planes: list[TemplatePlane],
                     order: VisibilityOrder | None, tau: float,
                     form_rows: bool = False, p_shape: np.ndarray | None = None,
                     margin: float = 0.0, twists: np.ndarray | None = None,
                     derivatives: bool = True,
                     pixel_depth_at_joints: bool = False,
                     hidden_residual: float = 0.0) -> LayeredEvaluation:
    """The layered template error and its derivatives (module docstring) for one camera.

    Parameters
    ----------
    templates : the camera's templates.
    image : (H, W) float32 LoG-filtered image.
    camera : the camera.
    kin : forward kinematics at the state (one state).
    planes : the template planes (held fixed over a frame's iterations).
    order : the visibility order to use; None predicts it at this state.
    tau : window width, px (0: unit windows).
    form_rows : also return the per-pixel rows ``dr/dv`` and ``dV/dv``.
    p_shape : the shape-frame pixel points of ``planes`` if already computed.
    margin : occluder outlines are grown by this many pixels (px): the LoG filter
        spreads an occluder's edge over its neighbourhood, so template pixels that close
        to an occluding outline no longer look like the template.
    twists : the parts' twists (:func:`~digiteyes.templates.deformation.part_twists`) at
        this state if already computed (they do not depend on the camera).
    derivatives : False computes only the error, residuals and visibility (``H`` and the
        gradients None): what a state's final check and the template refresh need.
    pixel_depth_at_joints : when ``order`` is None, predict it with the joints' links
        ordered pixel by pixel
        (:func:`~digiteyes.occlusion.visibility.visibility_order`).
    hidden_residual : a hidden template pixel costs what a seen one with this residual
        costs (grey levels; ``TemplateOptions.hidden_residual``; module docstring). 0 is
        the thesis's error.
    """
    if form_rows and not derivatives:
        raise ValueError("form_rows needs derivatives")
    if p_shape is None:
        p_shape = templates.shape_points(planes)
    parts = templates.parts
    windows = image_windows(parts, planes, kin, camera)
    if order is None:
        order = predict_visibility(parts, windows, camera, margin, pixel_depth_at_joints)
    occ_start, occ_index, occ_tested = order.csr()
    K, P = len(parts), len(p_shape)
    p_world = world_points(templates, kin, p_shape)
    eye = _eyes(camera, p_world) if occ_tested.any() else p_world
    if derivatives:
        if twists is None:
            twists = part_twists(parts, kin)
        w, Jp = camera.project_with_jacobian(p_world)
    else:  # placeholders the kernel does not read
        twists, Jp = np.zeros((K, 6, 0)), np.zeros((0, 2, 3))
        w = camera.project(p_world)
    n_v = twists.shape[2]
    H6 = np.zeros((K, 6, 6))
    g6 = np.zeros((K, 6))
    b6 = np.zeros((K, 6))
    b_pts = np.zeros((K, 4, 2))
    b_r = np.zeros(K)
    r = np.empty(P)
    V = np.empty(P)
    rows_r = np.zeros((P if form_rows else 0, n_v))
    rows_v = np.zeros((P if form_rows else 0, n_v))
    energy = layered_kernel(image, templates.part_of, p_world, w, Jp, templates.values,
                            templates.weights, twists, occ_start, occ_index, occ_tested,
                            windows.kind, windows.points, windows.radius, windows.d_points,
                            windows.d_radius, windows.world, templates.radii, eye,
                            float(JOINT_DEPTH_TIE_MM), float(tau), float(margin),
                            float(hidden_residual) ** 2, H6, g6, b6, b_pts, b_r, r, V, rows_r,
                            rows_v, form_rows, derivatives)
    if not derivatives:
        return LayeredEvaluation(float(energy), None, None, None, None, r, V, w, windows, order)
    g_boundary = (np.einsum("kan,ka->n", twists, b6)
                  + np.einsum("kqcn,kqc->n", windows.d_points, b_pts)
                  + b_r @ windows.d_radius)
    H6 = np.triu(H6) + np.triu(H6, 1).transpose(0, 2, 1)
    # H = sum_k twists_k^T H6_k twists_k as one (n_v, 6K) x (6K, n_v) product
    stacked = twists.reshape(6 * K, n_v)
    H = stacked.T @ (H6 @ twists).reshape(6 * K, n_v)
    g_region = stacked.T @ g6.reshape(6 * K)
    return LayeredEvaluation(float(energy), H, g_region + g_boundary, g_region, g_boundary,
                             r, V, w, windows, order,
                             rows_r if form_rows else None, rows_v if form_rows else None)


def _eyes(camera: Camera, p_world: np.ndarray) -> np.ndarray:
    """(P, 3) world points the rays to ``p_world`` (P, 3) start from, mm: the camera's
    centre, or for an orthographic camera a point far back along its optical axis."""
    if camera.projection == "perspective":
        return np.ascontiguousarray(np.broadcast_to(np.asarray(camera.centre_world,
                                                               dtype=float), p_world.shape))
    return p_world - 1e6 * np.asarray(camera.T_cam_world)[2, :3]


def acquire_templates(parts: tuple[TemplatePart, ...], image: np.ndarray, camera: Camera,
                      kin: Kinematics, spacing_px: float = 1.0,
                      margin: float = 0.0,
                      pixel_depth_at_joints: bool = False) -> CameraTemplates:
    """Templates of ``parts`` from a filtered ``image`` seen at the known state of
    ``kin`` (thesis Sec. 2.4.1; no label image needed).

    Each part's pixel grid has a spacing of ``spacing_px`` image pixels at the part's
    depth. A template pixel is kept (weight 1) where the model's own visibility order
    says it is seen (occluders grown by ``margin`` px) and it falls inside the image;
    the others wait for a refresh. ``pixel_depth_at_joints``: that order's joints decided
    pixel by pixel (:func:`~digiteyes.occlusion.visibility.visibility_order`).
    """
    planes = []
    abs_, part_of, slices, sides = [], [], [], []
    start = 0
    T = kin.T_world_shape[0]
    for k, part in enumerate(parts):
        plane = facing_plane(part, kin, camera)
        sides.append(float(np.sign(plane.origin[2])) if part.kind == "palm" else 0.0)
        centre = T[part.row, :3, 3] + T[part.row, :3, :3] @ (
            np.asarray(part.centre) if part.kind == "palm" else
            np.array([0.5 * part.length, 0.0, 0.0]))
        ab = template_grid(part, spacing_px * mm_per_pixel(camera, centre))
        planes.append(plane)
        abs_.append(ab)
        part_of.append(np.full(len(ab), k, dtype=np.int64))
        slices.append(slice(start, start + len(ab)))
        start += len(ab)
    P = start
    templates = CameraTemplates(parts, np.concatenate(abs_), np.concatenate(part_of), slices,
                                np.zeros(P, dtype=np.float32), np.zeros(P, dtype=np.float32),
                                np.ones(P, dtype=np.float32), np.array(sides),
                                part_views(parts, kin, camera))
    ev = evaluate_layered(templates, image, camera, kin, planes, None, 0.0, margin=margin,
                          derivatives=False, pixel_depth_at_joints=pixel_depth_at_joints)
    seen = ev.visibility >= 1.0
    observed = (ev.residuals + templates.values).astype(np.float32)
    templates.values[:] = np.where(seen, observed, 0.0)
    templates.reference[:] = templates.values
    templates.weights[:] = seen
    return templates


def part_views(parts: tuple[TemplatePart, ...], kin: Kinematics, camera: Camera
               ) -> np.ndarray:
    """Each part's orientation in ``camera``'s frame at the state of ``kin``: (K, 3, 3)
    ``R_cam_shape``."""
    R_cam_world = np.asarray(camera.T_cam_world)[:3, :3]
    rows = [part.row for part in parts]
    return R_cam_world @ kin.T_world_shape[0, rows, :3, :3]


def _turn_fraction(written: np.ndarray, now: np.ndarray, turn_deg: float) -> np.ndarray:
    """Per part, ``min(1, angle(written -> now) / turn_deg)`` of (K, 3, 3) rotations."""
    return np.minimum(1.0, np.degrees(matrix_angle(written, now)) / turn_deg)


def refresh_templates(templates: CameraTemplates, evaluation: LayeredEvaluation,
                      options: TemplateOptions, kin: Kinematics | None = None,
                      camera: Camera | None = None) -> int:
    """Blend the observed grey levels of well-seen pixels into the templates (module
    docstring); returns how many pixels were refreshed (0 when the frame fitted badly).

    Pixels never seen before are adopted outright (value and reference). With
    ``options.refresh_turn_deg``, ``kin`` (the frame's solved state) and ``camera`` gate
    each part's rate by how far it has turned since its template was written.
    """
    rms = evaluation.visible_rms
    if options.refresh_rate == 0.0 or not np.isfinite(rms) or rms > options.refresh_max_rms:
        return 0
    observed = evaluation.residuals + templates.values
    visible = evaluation.visibility >= options.refresh_min_visibility
    inside = (evaluation.pixels >= 0).all(axis=1)
    new = visible & inside & (templates.weights == 0)
    known = visible & (templates.weights > 0)
    rate: float | np.ndarray = options.refresh_rate
    if options.refresh_turn_deg is not None:
        if kin is None or camera is None:
            raise TemplateError("refresh_turn_deg needs the frame's kinematics and camera")
        views = part_views(templates.parts, kin, camera)
        fraction = _turn_fraction(templates.views, views, options.refresh_turn_deg)
        # the written orientation follows the refresh (the blend projected onto rotations)
        u, _, vt = np.linalg.svd(templates.views
                                 + fraction[:, None, None] * (views - templates.views))
        u[:, :, 2] *= np.linalg.det(u @ vt)[:, None]
        templates.views[:] = u @ vt
        rate = options.refresh_rate * fraction[templates.part_of[known]]
    values = templates.values
    values[known] += rate * (observed[known] - values[known])
    values += options.reference_pull * (templates.reference - values) * (templates.weights > 0)
    values[new] = observed[new]
    templates.reference[new] = observed[new]
    templates.weights[new] = 1.0
    return int(known.sum() + new.sum())
