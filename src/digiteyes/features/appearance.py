"""What the edge detector sees of the model: shading, and the edge bias it causes.

Skin darkens towards a finger's silhouette where its surface turns away from the light.
The intensity derivative then peaks inside the silhouette rather than on it, so the
measured side lines of a link sit inwards of the projected contour: measured widths are
too narrow, one camera reads the finger as farther away, and the joints bend to match
(docs/features.md, "Width residual"; ``digiteyes bench tracker`` section (e)).

The cure here is analysis by synthesis, in the spirit of the thesis's appearance
templates (Ch. 3): predict the image of the model, run the same feature search on it,
and subtract the residuals the search reports there from the residuals on the real image.
Whatever the detector does to a shaded edge it does to both, so the difference measures
the geometry alone.

The prediction is the model's primitives (:mod:`digiteyes.render.scene`) under a
:class:`ShadingModel`: Lambert skin under one distant light plus ambient light, in front
of the backdrop that a static camera saw around the model in the first frame.
:func:`fit_shading` estimates it from one image and a state known to match it (the first
frame and the initial state): given the surface normal ``n`` of every model pixel, the
grey level ``I = a + d max(0, n . l)`` is linear in ``a`` and ``d l`` once the pixels
facing the light are known, so the fit alternates a linear least squares with
re-selecting those pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.errors import StateError
from digiteyes.features.measure import FeatureOptions, measure_features
from digiteyes.features.residuals import feature_residuals
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics
from digiteyes.render.distortion import camera_canvas
from digiteyes.render.raster import Raster, paint, rasterise
from digiteyes.render.scene import Scene, build_scene

_FIT_ROUNDS = 10
"""Rounds of the active-set least squares in :func:`fit_shading` (it settles in 2-4)."""

_INTERIOR_PX = 3
"""Model pixels this close to the silhouette are left out of the fit: they mix skin and
backdrop when the state is a little off."""

_FILL_SIGMAS_PX = (4.0, 16.0, 64.0)
"""Widths (Gaussian standard deviations) of the neighbourhoods that fill the model's place
in a backdrop, narrowest first."""

_BACKDROP_SMOOTH_PX = 4.0
"""Standard deviation (px) of the blur whose residue measures a backdrop's texture."""

_BACKDROP_PX = 25
"""The backdrop level is the median of the pixels within this distance of the model's
silhouette (but not closer than :data:`_INTERIOR_PX`)."""


@dataclass(frozen=True, eq=False)
class ShadingModel:
    """Lambert skin under one distant light, in front of a static backdrop.

    A model point with outward unit normal ``n`` (world frame) has the grey level
    ``ambient_level + diffuse_level * max(0, n . light_world)``; around the model each
    camera sees its backdrop image, or the uniform ``background_level`` when it has none.
    Grey levels on the 0-255 scale of 8-bit images.

    Attributes
    ----------
    light_world : (3,) unit vector towards the light, world frame.
    ambient_level : grey level of skin that the light does not reach.
    diffuse_level : grey level added by the light where it falls head on.
    background_level : grey level of the backdrop for cameras without a backdrop image.
    backdrops : camera name -> (H, W) float32 grey image of the scene without the model.
    blur_sigma : optical blur of the cameras, px (Gaussian standard deviation; 0 for none).
    backdrop_texture : RMS grey-level detail of the backdrop around the model (what a
        blur of :data:`_BACKDROP_SMOOTH_PX` px removes): about the sensor noise on a
        plain cloth, ten or more grey levels in clutter.
    """

    light_world: np.ndarray
    ambient_level: float
    diffuse_level: float
    background_level: float
    backdrops: dict[str, np.ndarray] = field(default_factory=dict)
    blur_sigma: float = 0.0
    backdrop_texture: float = 0.0

    def render(self, kin: Kinematics, camera: Camera) -> np.ndarray:
        """The predicted grey image (H, W) float32 of the posed model ``kin`` (one state)
        in ``camera``."""
        scene = build_scene(kin.model, kin)
        light_cam = camera.T_cam_world[:3, :3] @ self.light_world
        backdrop = self.backdrops.get(camera.name)
        image = np.full((camera.height, camera.width), self.background_level, np.float32) \
            if backdrop is None else backdrop.copy()
        grid, warp = camera_canvas(camera)
        if warp is None:
            paint(scene.transformed(camera.T_cam_world), grid, light_cam, self.ambient_level,
                  self.diffuse_level, image)
        else:
            raster = _rasterise(scene, camera, light_cam)
            hit = raster.labels >= 0
            image[hit] = self.ambient_level + self.diffuse_level * raster.shade[hit]
        if self.blur_sigma > 0.0:
            image = cv2.GaussianBlur(image, (0, 0), self.blur_sigma,
                                     borderType=cv2.BORDER_REFLECT)
        return image


def _rasterise(scene: Scene, camera: Camera, light_cam: np.ndarray) -> Raster:
    """Ray cast the world ``scene`` in ``camera`` with shade ``max(0, n . light_cam)`` (no
    ambient term), warped through the lens distortion if the camera has any."""
    grid, warp = camera_canvas(camera)
    raster = rasterise(scene.transformed(camera.T_cam_world), grid, light_cam, 0.0)
    if warp is None:
        return raster
    return Raster(warp.warp(raster.depth, nearest=True, fill=np.inf),
                  warp.warp(raster.labels, nearest=True, fill=-1),
                  warp.warp(raster.shade, nearest=False, fill=0.0))


def fit_shading(images: Sequence[np.ndarray], rig: Rig, model: KinematicModel,
                q: np.ndarray, blur_sigma: float = 0.0,
                static_backdrop: bool = True) -> ShadingModel:
    """Estimate the :class:`ShadingModel` from one image per camera of ``rig`` showing the
    model at state ``q`` (n_q,), e.g. the first frame and the initial state.

    The skin levels and the light come from the model pixels at least
    :data:`_INTERIOR_PX` px inside the silhouette, the uniform backdrop level from a band
    around it. With ``static_backdrop`` (cameras that do not move) each camera's backdrop
    is its image with the model's silhouette (grown by :data:`_INTERIOR_PX` px) filled in
    from its surroundings (:func:`_fill`). Raises
    :class:`~digiteyes.errors.StateError` when the model covers too few pixels to fit.
    """
    scene = build_scene(model, forward_kinematics(model, np.asarray(q, dtype=float)))
    normals, levels, backdrop, detail = [], [], [], []
    backdrops: dict[str, np.ndarray] = {}
    for camera, image in zip(rig.cameras, images, strict=True):
        gray = prepare_image(image).astype(np.float32)
        n_cam, hit = _normals(scene, camera)
        mask = hit.astype(np.uint8)
        interior = cv2.erode(mask, _disc(_INTERIOR_PX)).astype(bool)
        outside = ~cv2.dilate(mask, _disc(_INTERIOR_PX)).astype(bool)
        ring = cv2.dilate(mask, _disc(_BACKDROP_PX)).astype(bool) & outside
        normals.append(n_cam[interior] @ camera.T_cam_world[:3, :3])  # rows n_world^T
        levels.append(gray[interior].astype(float))
        backdrop.append(gray[ring].astype(float))
        smooth, _ = _local_mean(gray, outside, _BACKDROP_SMOOTH_PX)
        detail.append(gray[ring] - smooth[ring])
        if static_backdrop:
            backdrops[camera.name] = _fill(gray, outside)
    n, level = np.concatenate(normals), np.concatenate(levels)
    if len(level) < 50:
        raise StateError(f"fit_shading: the model at this state covers only {len(level)} "
                         "interior pixels of the images; it needs at least 50")
    ambient, light = _fit_lambert(n, level)
    diffuse = float(np.linalg.norm(light))
    light_world = light / diffuse if diffuse > 0 else np.array([0.0, 0.0, 1.0])
    ring_levels = np.concatenate(backdrop)
    background = float(np.median(ring_levels)) if len(ring_levels) else 0.0
    for image in backdrops.values():
        image[~np.isfinite(image)] = background
    texture = np.concatenate(detail)
    return ShadingModel(light_world, ambient, diffuse, background, backdrops,
                        float(blur_sigma),
                        float(np.sqrt(np.mean(texture**2))) if len(texture) else 0.0)


def _fill(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``image`` with the pixels outside ``known`` filled by normalised convolution: the
    Gaussian-weighted mean of the known pixels around them, over ever wider
    neighbourhoods (:data:`_FILL_SIGMAS_PX`) until each has known pixels; NaN where none
    is known within the widest."""
    out = np.where(known, image, np.float32(np.nan))
    todo = ~known
    for sigma in _FILL_SIGMAS_PX:
        if not todo.any():
            break
        mean, mass = _local_mean(image, known, sigma)
        ready = todo & (mass > 1e-3)
        out[ready] = mean[ready]
        todo &= ~ready
    return out


def _local_mean(image: np.ndarray, known: np.ndarray, sigma: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian-weighted mean (H, W) of the ``known`` pixels of ``image`` around every
    pixel (normalised convolution, standard deviation ``sigma`` px), and the weight of
    known pixels it rests on; the mean is NaN where that weight is 0."""
    weight = known.astype(np.float32)
    mass = cv2.GaussianBlur(weight, (0, 0), sigma)
    total = cv2.GaussianBlur(image * weight, (0, 0), sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / mass, mass


def _fit_lambert(normals: np.ndarray, levels: np.ndarray) -> tuple[float, np.ndarray]:
    """Least-squares ``a`` and ``L`` in ``level = a + max(0, n . L)`` (normals (N, 3)):
    fit the lit pixels linearly, re-select the lit pixels, until they stop changing."""
    lit = np.ones(len(levels), dtype=bool)
    a, L = float(np.mean(levels)), np.zeros(3)
    for _ in range(_FIT_ROUNDS):
        design = np.column_stack([np.ones(len(levels)), normals * lit[:, None]])
        solution = np.linalg.lstsq(design, levels, rcond=None)[0]
        a, L = float(solution[0]), solution[1:]
        now_lit = normals @ L > 0
        if np.array_equal(now_lit, lit):
            break
        lit = now_lit
    return a, L


def _normals(scene: Scene, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (H, W, 3) of the visible surface in the camera frame, and the
    (H, W) mask of model pixels: with no ambient light, the shade under a light along
    ``+e`` minus the shade under one along ``-e`` is ``n . e``."""
    axes = np.eye(3)
    rasters = [(_rasterise(scene, camera, e), _rasterise(scene, camera, -e)) for e in axes]
    n = np.stack([plus.shade - minus.shade for plus, minus in rasters], axis=-1)
    return n, rasters[0][0].labels >= 0


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


@dataclass(frozen=True)
class EdgeBias:
    """Residuals of the feature search on the predicted image of one camera, at the state
    it was predicted for: what the detector reports where the geometry fits exactly.

    ``table[kind_code, link_index, component]`` (3, n_links, C) px, zero for features
    the search did not find there (see :class:`~digiteyes.features.ResidualLayout`).
    """

    table: np.ndarray

    def of_rows(self, kind_code: np.ndarray, link_index: np.ndarray,
                component: np.ndarray) -> np.ndarray:
        """(M,) bias of each residual row, px."""
        return self.table[kind_code, link_index, component]


def edge_bias(shading: ShadingModel, model: KinematicModel, q: np.ndarray, camera: Camera,
              options: FeatureOptions, link_names: Sequence[str] | None = None,
              tip_names: Sequence[str] | None = None,
              *, axis_points: int = 2, width_weight: float = 0.0,
              max_width_error: float = 0.15) -> EdgeBias:
    """The :class:`EdgeBias` of ``camera`` at state ``q``: render the model under
    ``shading``, measure the features there with ``options`` and take their residuals
    (same settings as :func:`~digiteyes.features.feature_residuals`) at ``q``. Links
    and tips as in :func:`~digiteyes.features.measure_features` (None: all)."""
    q = np.asarray(q, dtype=float)
    if q.shape != (model.n_q,):
        raise StateError(f"edge_bias needs one state of {model.n_q} numbers for model "
                         f"{model.name!r}, got shape {q.shape}")
    kin = forward_kinematics(model, q)
    predicted = shading.render(kin, camera)
    meas = measure_features(predicted, camera, model, kin, options, link_names, tip_names)
    r, _, layout = feature_residuals(meas, camera, kin, jacobian=False,
                                     axis_points=axis_points, width_weight=width_weight,
                                     max_width_error=max_width_error)
    table = np.zeros((3, len(model.links), max(axis_points, 2)))
    table[layout.kind_code, layout.link_index, layout.component] = r
    return EdgeBias(table)
