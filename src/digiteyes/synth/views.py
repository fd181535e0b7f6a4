"""Render a posed model into the images of one or more cameras, with ground truth.

For each camera the posed primitives (:mod:`digiteyes.render.scene`) are moved into the
camera frame and ray cast on its pixel grid (:mod:`digiteyes.render.raster`); the skin is
Lambert shaded, laid over the backdrop (:mod:`digiteyes.synth.backgrounds`), warped by
the lens distortion if any (:mod:`digiteyes.render.distortion`), then blurred, made
noisy and quantised (:mod:`digiteyes.synth.sensor`). Each view carries the depth image,
the label image and the keypoints (:mod:`digiteyes.kinematics.keypoints`) with their
projections and visibility. With ``RenderOptions(appearance="flesh")`` the hand is drawn
as the independent flesh surface instead (:mod:`digiteyes.render.flesh`), sphere traced
(:mod:`digiteyes.render.flesh_raster`); keypoints stay the kinematic joint and tip
centres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.errors import CameraError, StateError
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.render.distortion import camera_canvas
from digiteyes.render.flesh import FleshScene, build_flesh
from digiteyes.render.flesh_raster import FleshMaterial, keypoint_visibility, rasterise_flesh
from digiteyes.render.pixels import PixelGrid
from digiteyes.render.raster import rasterise
from digiteyes.render.scene import Scene, build_scene
from digiteyes.synth.backgrounds import background
from digiteyes.synth.options import RenderOptions
from digiteyes.synth.sensor import expose

_CONTAIN_TOL_MM = 1e-6


@dataclass
class RenderedView:
    """One camera's synthetic image and its ground truth.

    Attributes
    ----------
    image : uint8 (H, W) grey or (H, W, 3) RGB.
    depth : float32 (H, W), camera z (mm) of the surface seen at each pixel centre,
        ``np.inf`` on the background.
    labels : int16 (H, W), index into ``model.links`` of that surface, -1 on background.
        A distal link's far hemisphere carries its tip's label.
    keypoints_3d : (K, 3) world mm, see :func:`~digiteyes.kinematics.keypoints.keypoints`.
    keypoints_2d : (K, 2) pixels, ``camera.project`` of ``keypoints_3d`` (NaN for points
        behind a perspective camera).
    visible : (K,) bool: the keypoint projects inside the image, in front of the camera,
        and nothing hides it: for the model appearance, the surface seen at its (rounded)
        pixel belongs to a link whose solid contains the keypoint (its own link, or a
        neighbour sharing the joint); for the flesh appearance, the first surface along
        its ray lies no more than 5 mm in front of where the ray leaves the keypoint's own
        flesh (a depth test, :func:`~digiteyes.render.flesh_raster.keypoint_visibility`).
    keypoint_names : (K,) names.
    """

    image: np.ndarray
    depth: np.ndarray
    labels: np.ndarray
    keypoints_3d: np.ndarray
    keypoints_2d: np.ndarray
    visible: np.ndarray
    keypoint_names: tuple[str, ...]


def render_views(
    model: KinematicModel,
    q: np.ndarray,
    rig_or_cameras: Rig | Camera | Sequence[Camera],
    options: RenderOptions = RenderOptions(),  # noqa: B008 (immutable default)
    rng: np.random.Generator | int | None = None,
) -> list[RenderedView]:
    """Render state ``q`` (n_q,) of ``model`` for every camera, with ground truth.

    ``rng`` (a Generator or a seed) drives the sensor noise; the procedural backdrops are
    seeded by ``options.background_seed`` (static scene). Raises
    :class:`~digiteyes.errors.StateError` for a bad state and
    :class:`~digiteyes.errors.CameraError` for bad cameras.

    Examples
    --------
    >>> from digiteyes import load_model
    >>> from digiteyes.camera import Camera
    >>> hand = load_model("hand")
    >>> cam = Camera.look_at("c", eye=(0, 60, 450), target=(0, 60, 0), up=(0, 1, 0))
    >>> view = render_views(hand, hand.neutral(), [cam], rng=0)[0]
    >>> view.image.shape, view.labels.max() == len(hand.links) - 1
    ((480, 640), True)
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 1:
        raise StateError(f"render_views takes one state of size {model.n_q}, got shape "
                         f"{q.shape}; render a sequence frame by frame")
    cameras = _cameras(rig_or_cameras)
    rng = np.random.default_rng(rng)
    kin = forward_kinematics(model, q)
    names, points = keypoints(model, kin)
    points = points[0]
    if options.appearance == "flesh":
        flesh = build_flesh(model, kin)
        links = _keypoint_links(model, names)
        return [_render_flesh(flesh, points, names, links, cam, index, options, rng)
                for index, cam in enumerate(cameras)]
    world = build_scene(model, kin)
    owners = _owners(world, points, len(model.links))
    return [_render_camera(world, points, names, owners, cam, index, options, rng)
            for index, cam in enumerate(cameras)]


def _cameras(rig_or_cameras) -> tuple[Camera, ...]:
    if isinstance(rig_or_cameras, Camera):
        return (rig_or_cameras,)
    cameras = tuple(rig_or_cameras.cameras if isinstance(rig_or_cameras, Rig)
                    else rig_or_cameras)
    if not cameras or not all(isinstance(cam, Camera) for cam in cameras):
        raise CameraError("render_views needs a Rig, a Camera or a non-empty sequence of "
                          f"Cameras, got {type(rig_or_cameras).__name__}")
    return cameras


def _owners(world: Scene, points: np.ndarray, n_links: int) -> np.ndarray:
    """(K, L) bool: link l's solid contains keypoint k, or l is keypoint k's own link."""
    owners = np.eye(len(points), n_links, dtype=bool)
    inside = world.distance(points) <= _CONTAIN_TOL_MM  # (K, P)
    for label in np.unique(world.labels):
        owners[:, label] |= inside[:, world.labels == label].any(axis=1)
    return owners


def _light_cam(cam: Camera, options: RenderOptions) -> np.ndarray:
    """Unit direction towards the light in the camera frame (headlight: the camera)."""
    if options.light_dir is None:
        return np.array([0.0, 0.0, -1.0])
    light = np.asarray(options.light_dir, dtype=float)
    return cam.T_cam_world[:3, :3] @ (light / np.linalg.norm(light))


def _keypoint_links(model: KinematicModel, names: tuple[str, ...]) -> np.ndarray:
    """(K,) index into ``model.links`` of each keypoint's link: keypoints are one per link
    but the tracked edges, in model order (:mod:`digiteyes.kinematics.keypoints`)."""
    links = np.array([i for i, link in enumerate(model.links) if link.kind != "edge"])
    if len(links) != len(names):
        raise StateError(f"expected {len(links)} keypoints for model {model.name!r}, got "
                         f"{len(names)}")
    return links


def _render_flesh(world: FleshScene, points: np.ndarray, names: tuple[str, ...],
                  links: np.ndarray, cam: Camera, index: int, options: RenderOptions,
                  rng: np.random.Generator) -> RenderedView:
    scene = world.transformed(cam.T_cam_world)
    light_cam = _light_cam(cam, options)
    material = FleshMaterial(albedo=options.skin_colour, ambient=options.ambient,
                             specular=options.specular, shininess=options.shininess,
                             texture=options.texture, seed=options.skin_seed,
                             shadows=options.shadows)
    alpha, rgb, depth, labels = _draw(
        cam, options, lambda grid: rasterise_flesh(scene, grid, light_cam, material),
        lambda raster: raster.rgb)
    if options.color:
        paint = np.float32(255.0) * rgb
    else:
        paint = np.float32(255.0) * (rgb @ np.array([0.299, 0.587, 0.114], dtype=np.float32))
        if options.skin_tone is None:  # grey images keep the grey albedo's brightness
            luma = float(np.dot([0.299, 0.587, 0.114], options.skin_colour))
            paint *= np.float32(options.skin_grey / luma)
    image = _compose(paint, alpha, options, cam, index, rng)
    pixels, inside = _project(cam, points)
    points_cam = points @ cam.T_cam_world[:3, :3].T + cam.T_cam_world[:3, 3]
    grid0 = PixelGrid.from_camera(cam)
    visible = inside & keypoint_visibility(scene, points_cam, links, grid0.perspective)
    return RenderedView(image, depth, labels, points.copy(), pixels, visible, names)


def _compose(paint: np.ndarray, alpha: np.ndarray, options: RenderOptions, cam: Camera,
             index: int, rng: np.random.Generator) -> np.ndarray:
    """Skin radiance (already times 255 and coverage) over the backdrop, then the sensor."""
    back = background(options, cam.width, cam.height, index)
    if options.color:
        composed = paint + (1.0 - alpha)[..., None] * back
    else:
        composed = paint + (1.0 - alpha) * back
    return expose(composed, options.blur_sigma, options.noise_sigma, rng)


def _project(cam: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (K, 2) of world points (NaN behind a perspective camera) and whether each
    lies in front of the camera and inside the image."""
    in_front = cam.depth(points) > 0 if cam.projection == "perspective" else \
        np.ones(len(points), dtype=bool)
    pixels = np.full((len(points), 2), np.nan)
    pixels[in_front] = cam.project(points[in_front])
    inside = cam.in_image(np.nan_to_num(pixels, nan=-1.0)) & in_front
    return pixels, inside


def _render_camera(world: Scene, points: np.ndarray, names: tuple[str, ...],
                   owners: np.ndarray, cam: Camera, index: int, options: RenderOptions,
                   rng: np.random.Generator) -> RenderedView:
    scene = world.transformed(cam.T_cam_world)
    light_cam = _light_cam(cam, options)
    alpha, lit, depth, labels = _draw(
        cam, options, lambda grid: rasterise(scene, grid, light_cam, options.ambient),
        lambda raster: raster.shade)
    if options.color:
        paint = lit[..., None] * (np.float32(255.0)
                                  * np.asarray(options.skin_colour, dtype=np.float32))
    else:
        paint = lit * np.float32(255.0 * options.skin_grey)
    image = _compose(paint, alpha, options, cam, index, rng)
    pixels, inside = _project(cam, points)
    safe = np.nan_to_num(pixels, nan=0.0)
    u = np.clip(np.rint(safe[:, 0]), 0, cam.width - 1).astype(int)
    v = np.clip(np.rint(safe[:, 1]), 0, cam.height - 1).astype(int)
    seen = labels[v, u].astype(int)
    visible = inside & (seen >= 0) & owners[np.arange(len(points)), np.maximum(seen, 0)]
    return RenderedView(image, depth, labels, points.copy(), pixels, visible, names)


def _draw(cam: Camera, options: RenderOptions, cast, radiance
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Coverage alpha, radiance, depth and labels of one camera: ``cast(grid)`` ray casts
    a pixel grid and ``radiance(raster)`` reads its shade or colour; with supersampling,
    alpha and radiance are block means of a finer cast; lens distortion is applied last."""
    grid, warp = camera_canvas(cam)
    raster = cast(grid)
    if options.supersample > 1:
        ss = options.supersample
        fine = cast(grid.supersampled(ss))
        alpha = _block_mean(fine.hit.astype(np.float32), ss)
        colour = _block_mean(radiance(fine), ss)
    else:
        alpha = raster.hit.astype(np.float32)
        colour = radiance(raster)
    depth, labels = raster.depth, raster.labels
    if warp is not None:
        alpha = warp.warp(alpha, nearest=False, fill=0.0)
        colour = warp.warp(colour, nearest=False, fill=0.0)
        depth = warp.warp(depth, nearest=True, fill=np.inf)
        labels = warp.warp(labels, nearest=True, fill=-1)
    return alpha, colour, depth, labels


def _block_mean(image: np.ndarray, factor: int) -> np.ndarray:
    """Mean of each factor x factor block (OpenCV's area resampling is exactly that for an
    integer factor)."""
    size = (image.shape[1] // factor, image.shape[0] // factor)
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)
