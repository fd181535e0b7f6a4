"""Pictures of a posed model from any viewpoint (thesis Fig. 4.6), shaded or wireframe.

``write_model_png(model, q, path, view="oblique")`` places a camera around the posed
model's bounding spheres and writes a PNG: ``"shaded"`` ray casts the model with the
renderer (colour skin on a light grey backdrop), ``"wireframe"`` draws each capsule's
outline and axis, the tips and the palm box edges with anti-aliased lines.

Views are directions in the world frame, named for the neutral hand (fingers along +y,
palmar side +z, thumb side +x): ``front`` looks at the palm (camera on +z, fingers up),
``back`` at the back of the hand, ``side`` from the thumb side, ``top`` down the fingers
from beyond the fingertips, ``bottom`` from the wrist, ``oblique`` from front-right and
above. ``"az,el[,dist]"`` gives azimuth and elevation in degrees and an optional distance
in mm: the camera sits at ``cos(el) (sin(az) x + cos(az) z) + sin(el) y`` from the model's
centre (az = 0, el = 0 is ``front``; az = 90 is ``side``; el = 90 is ``top``). Without a
distance the camera stands at 2.5 bounding radii and its focal length frames the model
(90 % of the image); with one, the focal length is the image's larger side in pixels.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.render.scene import BALL, CAPSULE, Scene, build_scene
from digiteyes.synth import RenderOptions, render_views

NAMED_VIEWS = {
    "front": (0.0, 0.0),
    "back": (180.0, 0.0),
    "side": (90.0, 0.0),
    "top": (0.0, 90.0),
    "bottom": (0.0, -90.0),
    "oblique": (35.0, 25.0),
}
"""Named views as (azimuth, elevation) in degrees."""

STYLES = ("shaded", "wireframe")
_FILL = 0.9  # fraction of the image the auto-framed model spans
_BACKGROUND_LEVEL = 0.85
_LINE_RGB = (40, 40, 40)
_AXIS_RGB = (200, 40, 40)


class ViewError(DigitEyesError, ValueError):
    """A bad view or style for :func:`write_model_png` (says what was expected)."""


def parse_view(view: str) -> tuple[float, float, float | None]:
    """Azimuth, elevation (degrees) and distance (mm or None) of a view string."""
    key = view.strip().lower()
    if key in NAMED_VIEWS:
        return (*NAMED_VIEWS[key], None)
    expected = (f"view must be one of {', '.join(NAMED_VIEWS)} or 'az,el[,dist]' "
                f"(degrees, mm); got {view!r}")
    parts = key.split(",")
    if len(parts) not in (2, 3):
        raise ViewError(expected)
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ViewError(expected) from None
    if not all(math.isfinite(v) for v in values):
        raise ViewError(expected)
    if not -90.0 <= values[1] <= 90.0:
        raise ViewError(f"elevation must lie in [-90, 90] degrees; got {values[1]:g}")
    if len(values) == 3 and not values[2] > 0.0:
        raise ViewError(f"view distance must be positive (mm); got {values[2]:g}")
    return values[0], values[1], values[2] if len(values) == 3 else None


def view_camera(model: KinematicModel, q: np.ndarray, view: str = "front", *,
                width: int = 640, height: int = 480) -> Camera:
    """A perspective camera that sees the posed model from ``view`` (see module doc)."""
    az, el, dist = parse_view(view)
    centres, radii = _bounding_balls(build_scene(model, forward_kinematics(model, q)))
    low, high = (centres - radii[:, None]).min(axis=0), (centres + radii[:, None]).max(axis=0)
    target = 0.5 * (low + high)
    bound = float(np.max(np.linalg.norm(centres - target, axis=1) + radii))
    a, e = math.radians(az), math.radians(el)
    horizontal = np.array([math.sin(a), 0.0, math.cos(a)])
    direction = math.cos(e) * horizontal + math.sin(e) * np.array([0.0, 1.0, 0.0])
    up = -math.sin(e) * horizontal + math.cos(e) * np.array([0.0, 1.0, 0.0])
    eye = target + (2.5 * bound if dist is None else dist) * direction
    cam = Camera.look_at("view", eye, target, up, width=width, height=height,
                         focal_px=float(max(width, height)))
    if dist is not None:
        return cam
    p = cam.to_camera(centres)
    x_lo, x_hi, y_lo, y_hi = _normalised_bounds(p, radii)
    focal = _FILL * min(width / (x_hi - x_lo), height / (y_hi - y_lo))
    K = np.array([[focal, 0.0, (width - 1) / 2 - focal * (x_lo + x_hi) / 2],
                  [0.0, focal, (height - 1) / 2 - focal * (y_lo + y_hi) / 2],
                  [0.0, 0.0, 1.0]])
    return Camera.create("view", K, width, height, cam.T_cam_world)


def write_model_png(model: KinematicModel, q: np.ndarray, path: str | Path, *,
                    view: str = "front", style: str = "shaded", width: int = 640,
                    height: int = 480, mirrored: bool = False) -> Path:
    """Draw the model at state ``q`` from ``view`` and write it as a PNG; returns the path.
    ``mirrored``: ``q`` is the mirror image's right hand of a tracked left hand
    (:mod:`digiteyes.camera.mirror`); the picture is flipped left to right, which shows
    the left hand (seen from the reflected viewpoint).

    Raises :class:`ViewError` for a bad view or style,
    :class:`~digiteyes.errors.StateError` for a bad state and
    :class:`~digiteyes.errors.DigitEyesError` if the file cannot be written.
    """
    if style not in STYLES:
        raise ViewError(f"style must be one of {', '.join(STYLES)}; got {style!r}")
    q = np.asarray(q, dtype=float)
    cam = view_camera(model, q, view, width=width, height=height)
    if style == "shaded":
        x_cam, y_cam, z_cam = cam.T_world_cam[:3, :3].T  # camera axes in the world
        light = -z_cam - 0.5 * y_cam + 0.3 * x_cam  # a headlight from above right
        options = RenderOptions(color=True, background="uniform",
                                background_level=_BACKGROUND_LEVEL, light_dir=tuple(light),
                                ambient=0.3, supersample=3)
        image = render_views(model, q, [cam], options, rng=0)[0].image
    else:
        image = draw_wireframe(model, q, cam)
    from digiteyes.io.safe_paths import write_png

    return write_png(path, np.ascontiguousarray(image[:, ::-1]) if mirrored else image)


def draw_wireframe(model: KinematicModel, q: np.ndarray, cam: Camera,
                   image: np.ndarray | None = None) -> np.ndarray:
    """RGB uint8 line drawing of the posed model in ``cam``: capsule outlines with their
    axes, tip circles and palm box edges (no hidden-line removal), drawn on a copy of
    ``image`` ((H, W, 3) RGB uint8 of the camera's size) or on a plain grey ground."""
    if image is None:
        image = np.full((cam.height, cam.width, 3), int(255 * _BACKGROUND_LEVEL),
                        dtype=np.uint8)
    else:
        image = np.array(image, dtype=np.uint8, copy=True)
    T_shape = forward_kinematics(model, q).T_world_shape[0]
    signs = np.array([[i, j, m] for i in (-1, 1) for j in (-1, 1) for m in (-1, 1)])
    for link in model.links:
        T = T_shape[link.row]
        origin, R = T[:3, 3], T[:3, :3]
        if link.kind == "palm":
            corners = cam.project(origin + (np.asarray(link.centre) + 0.5 * signs
                                            * np.asarray(link.size)) @ R.T)
            for a in range(8):
                for b in range(a + 1, 8):
                    if np.abs(signs[a] - signs[b]).sum() == 2:  # corners sharing an edge
                        _line(image, corners[a], corners[b], _LINE_RGB)
        elif link.kind == "tip":
            radius = _pixel_radius(cam, origin[None], link.radius)[0]
            _arc(image, cam.project(origin), radius, 0.0, 360.0, _AXIS_RGB)
        elif link.kind == "link":
            _capsule_outline(image, cam, origin, origin + link.length * R[:, 0], link.radius)
    return image


def _capsule_outline(image: np.ndarray, cam: Camera, a: np.ndarray, b: np.ndarray,
                     radius: float) -> None:
    """Two side lines, two end arcs and the axis of a capsule's projection."""
    ends = cam.project(np.stack([a, b]))
    radii = _pixel_radius(cam, np.stack([a, b]), radius)
    axis = ends[1] - ends[0]
    length = float(np.linalg.norm(axis))
    if length > 1e-9:
        normal = np.array([-axis[1], axis[0]]) / length
        for side in (-1.0, 1.0):
            _line(image, ends[0] + side * radii[0] * normal,
                  ends[1] + side * radii[1] * normal, _LINE_RGB)
    angle = math.degrees(math.atan2(axis[1], axis[0]))
    _arc(image, ends[0], radii[0], angle + 90.0, angle + 270.0, _LINE_RGB)
    _arc(image, ends[1], radii[1], angle - 90.0, angle + 90.0, _LINE_RGB)
    _line(image, ends[0], ends[1], _AXIS_RGB)


def _bounding_balls(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Centres (M, 3) and radii (M,) of balls (points for box corners) whose convex hull
    holds every primitive."""
    P = scene.params
    centres, radii = [], []
    for k, kind in enumerate(scene.kinds):
        if kind == BALL:
            centres.append(P[k, 0:3])
            radii.append(P[k, 3])
        elif kind == CAPSULE:
            centres += [P[k, 0:3], P[k, 3:6]]
            radii += [P[k, 6], P[k, 6]]
        else:  # a box: its corners
            signs = np.array([[i, j, m] for i in (-1, 1) for j in (-1, 1) for m in (-1, 1)])
            centres += list(P[k, 0:3] + (signs * P[k, 12:15]) @ P[k, 3:12].reshape(3, 3))
            radii += [0.0] * 8
    return np.array(centres), np.array(radii)


def _normalised_bounds(p: np.ndarray, r: np.ndarray) -> tuple[float, float, float, float]:
    """Bounds of x/z and y/z over balls (camera frame) in front of the camera: the tangent
    slopes ``(c_x c_z +- r sqrt(c_x^2 + c_z^2 - r^2)) / (c_z^2 - r^2)``."""
    denom = p[:, 2] ** 2 - r ** 2
    sx = r * np.sqrt(p[:, 0] ** 2 + denom)
    sy = r * np.sqrt(p[:, 1] ** 2 + denom)
    return (float(((p[:, 0] * p[:, 2] - sx) / denom).min()),
            float(((p[:, 0] * p[:, 2] + sx) / denom).max()),
            float(((p[:, 1] * p[:, 2] - sy) / denom).min()),
            float(((p[:, 1] * p[:, 2] + sy) / denom).max()))


def _pixel_radius(cam: Camera, centres: np.ndarray, radius: float) -> np.ndarray:
    """Approximate image radius (px) of balls of ``radius`` mm at world ``centres``."""
    return cam.K[1, 1] * radius / cam.depth(centres)


def _fixed(point) -> tuple[int, ...]:
    """Pixel coordinates in cv2's fixed point with 4 fractional bits (``shift=4``)."""
    return tuple(np.rint(16.0 * np.asarray(point, dtype=float)).astype(int).tolist())


def _line(image: np.ndarray, p0: np.ndarray, p1: np.ndarray, rgb: tuple) -> None:
    cv2.line(image, _fixed(p0), _fixed(p1), rgb, 1, cv2.LINE_AA, shift=4)


def _arc(image: np.ndarray, centre: np.ndarray, radius: float, start: float, end: float,
         rgb: tuple) -> None:
    r = _fixed([radius])[0]
    cv2.ellipse(image, _fixed(centre), (r, r), 0.0, start, end, rgb, 1, cv2.LINE_AA, shift=4)
