"""Template planes: where each link's template lies and how it faces a camera (Rehg
thesis Sec. 2.4.1).

Every rigid part of the model carries one template per camera:

* a cylinder link (``kind="link"``): a rectangle in the plane through the link axis that
  is turned about the axis to face the camera; template coordinates ``(a, b)`` are mm
  along the axis (``0..length``) and across it (``-radius..radius``);
* a fingertip sphere (``"tip"``): a disc of the tip's radius through its centre, facing
  the camera; ``(a, b)`` are mm in the disc;
* the palm slab (``"palm"``): the box face that looks towards the camera when the
  template is acquired (palmar ``+z`` or dorsal ``-z``); ``(a, b)`` are mm along the
  shape frame's x and y. This plane does not turn.

A plane is given by its origin and two unit axes in the part's shape frame, so the
template point with coordinates ``(a, b)`` sits at ``origin + a e_a + b e_b`` there. The
facing turn of links and tips is computed once per frame at the predicted state and held
while the solver iterates; the deformation (thesis eq. 2.9-2.11) is then the rigid motion
of these shape-frame points followed by the camera projection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel, Kinematics

TEMPLATE_KINDS = ("link", "tip", "palm")


@dataclass(frozen=True)
class TemplatePart:
    """A model part that carries a template.

    Attributes
    ----------
    link : index into ``model.links``.
    name, kind, row : the link's name, kind (``link``, ``tip``, ``palm``) and frame row.
    length, radius : mm (palm: ``radius`` is half the slab thickness).
    size, centre : palm box size and centre in the shape frame, mm.
    parent : index (into the part list) of the part this one hangs from through one joint,
        -1 for none (used by the revolute-joint rule of thesis Sec. 3.2.2).
    """

    link: int
    name: str
    kind: str
    row: int
    length: float
    radius: float
    size: tuple[float, float, float]
    centre: tuple[float, float, float]
    parent: int


def template_parts(model: KinematicModel) -> tuple[TemplatePart, ...]:
    """The parts of ``model`` that carry templates: cylinder links, tips and the palm, in
    ``model.links`` order, each with the part it is attached to through one joint."""
    chosen = [(i, link) for i, link in enumerate(model.links) if link.kind in TEMPLATE_KINDS]
    row_to_part = {link.row: p for p, (_, link) in enumerate(chosen)}
    parts = []
    for i, link in chosen:
        parent, row = -1, int(model.parent[link.row])
        while row >= 0:
            if row in row_to_part:
                parent = row_to_part[row]
                break
            row = int(model.parent[row])
        parts.append(TemplatePart(i, link.name, link.kind, link.row, float(link.length),
                                  float(link.radius), tuple(map(float, link.size)),
                                  tuple(map(float, link.centre)), parent))
    return tuple(parts)


def towards_camera(camera: Camera, p_world: np.ndarray) -> np.ndarray:
    """Unit world vectors (..., 3) from points towards the camera (for an orthographic
    camera: minus the optical axis)."""
    p_world = np.asarray(p_world, dtype=float)
    if camera.projection == "perspective":
        v = camera.centre_world - p_world
        return v / np.linalg.norm(v, axis=-1, keepdims=True)
    return np.broadcast_to(-camera.T_cam_world[2, :3], p_world.shape).copy()


@dataclass(frozen=True)
class TemplatePlane:
    """One template plane in a shape frame: ``origin``, ``e_a``, ``e_b`` (3,) each, mm and
    unit vectors in the shape frame of ``part.row``."""

    origin: np.ndarray
    e_a: np.ndarray
    e_b: np.ndarray

    def points(self, ab: np.ndarray) -> np.ndarray:
        """Shape-frame points (P, 3) of template coordinates ``ab`` (P, 2), mm."""
        return self.origin + ab[:, :1] * self.e_a + ab[:, 1:2] * self.e_b


def facing_plane(part: TemplatePart, kin: Kinematics, camera: Camera,
                 palm_side: float = 0.0) -> TemplatePlane:
    """The plane of ``part`` turned to face ``camera`` at the state of ``kin`` (one state).

    ``palm_side`` picks the palm face (+1 palmar, -1 dorsal); 0 chooses the face looking
    towards the camera.
    """
    T = kin.T_world_shape[0, part.row]
    R = T[:3, :3]
    if part.kind == "palm":
        centre = np.asarray(part.centre)
        side = palm_side
        if side == 0.0:
            view = R.T @ towards_camera(camera, T[:3, :3] @ centre + T[:3, 3])
            side = 1.0 if view[2] >= 0 else -1.0
        origin = centre + np.array([0.0, 0.0, side * 0.5 * part.size[2]])
        return TemplatePlane(origin, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    if part.kind == "link":
        mid = T[:3, :3] @ np.array([0.5 * part.length, 0.0, 0.0]) + T[:3, 3]
        view = R.T @ towards_camera(camera, mid)
        across = np.array([0.0, -view[2], view[1]])
        norm = np.linalg.norm(across)
        across = np.array([0.0, 1.0, 0.0]) if norm < 1e-9 else across / norm
        return TemplatePlane(np.zeros(3), np.array([1.0, 0.0, 0.0]), across)
    # a tip's disc keeps the camera's image axes (the sphere's shading does not turn
    # with the finger), so only the disc's position follows the state
    view = R.T @ towards_camera(camera, T[:3, 3])
    image_x = R.T @ camera.T_cam_world[0, :3]
    e_a = image_x - (image_x @ view) * view
    norm = np.linalg.norm(e_a)
    if norm < 1e-9:
        e_a = np.cross(view, [1.0, 0.0, 0.0] if abs(view[0]) < 0.9 else [0.0, 1.0, 0.0])
        norm = np.linalg.norm(e_a)
    e_a = e_a / norm
    return TemplatePlane(np.zeros(3), e_a, np.cross(view, e_a))


def template_grid(part: TemplatePart, spacing_mm: float) -> np.ndarray:
    """Template coordinates ``(a, b)`` (P, 2), mm, of the template pixels of ``part`` on a
    square grid of ``spacing_mm`` (pixel centres; discs keep the pixels inside)."""
    def axis(low: float, high: float) -> np.ndarray:
        n = max(1, int(np.ceil((high - low) / spacing_mm)))
        return low + (np.arange(n) + 0.5) * (high - low) / n

    if part.kind == "link":
        a, b = axis(0.0, part.length), axis(-part.radius, part.radius)
    elif part.kind == "tip":
        a = b = axis(-part.radius, part.radius)
    else:
        a = axis(-0.5 * part.size[0], 0.5 * part.size[0])
        b = axis(-0.5 * part.size[1], 0.5 * part.size[1])
    A, B = np.meshgrid(a, b, indexing="ij")
    ab = np.stack([A.ravel(), B.ravel()], axis=1)
    if part.kind == "tip":
        ab = ab[np.hypot(ab[:, 0], ab[:, 1]) <= part.radius]
    return ab


def mm_per_pixel(camera: Camera, p_world: np.ndarray) -> float:
    """Size in mm of one image pixel at a world point (at its depth), for choosing the
    template spacing."""
    f = float(camera.K[0, 0])
    if camera.projection == "perspective":
        return float(camera.depth(p_world)) / f
    if camera.projection == "orthographic":
        return 1.0 / f
    return camera.depth_mm / f
