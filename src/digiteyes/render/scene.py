"""The posed model as a list of solid primitives (balls, capsules, boxes) with labels.

Geometry follows the DigitEyes report (Fig. 1: finger links are cylinders, fingertips
hemispheres) and the model file: a cylinder link of radius r and length a becomes a
capsule (a cylinder with hemispherical ends) around its axis segment; a tip becomes a
ball at its shape-frame origin, which is also the far end of the distal link, so the
capsule's far hemisphere and the tip coincide (the capsule's far cap carries the tip's
label); the palm box ``size`` becomes a rounded slab, the Minkowski sum of a flat
rectangle and a ball whose radius is half the box's smallest dimension. That slab is
exactly the union of a box (the rectangle thickened by the ball radius) and four
capsules along the rectangle's edges, so it needs no primitive of its own.

Labels are indices into ``model.links``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from digiteyes.kinematics import KinematicModel, Kinematics
from digiteyes.render import geometry


@dataclass(frozen=True)
class Primitive:
    """One convex solid: ``kind`` is ``"ball"``, ``"capsule"`` or ``"box"``.

    ``a`` is the ball centre, the capsule start or the box centre; ``b`` the capsule end;
    ``radius`` the ball or capsule radius; ``axes`` (3, 3) the box axes as columns and
    ``half`` its half extents (mm, in whatever frame the primitive is expressed).
    ``label`` is the link index; points of a capsule beyond ``b`` get ``far_label``.
    """

    kind: str
    label: int
    a: np.ndarray
    b: np.ndarray | None = None
    radius: float = 0.0
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    half: np.ndarray = field(default_factory=lambda: np.zeros(3))
    far_label: int = -1

    def transformed(self, T: np.ndarray) -> Primitive:
        """The primitive in another frame: ``T`` (4, 4) maps its frame to the new one."""
        R, t = T[:3, :3], T[:3, 3]
        b = None if self.b is None else R @ self.b + t
        return Primitive(self.kind, self.label, R @ self.a + t, b, self.radius,
                         R @ self.axes, self.half, self.far_label)

    def hit(self, o: tuple, d: tuple) -> np.ndarray:
        """Ray parameters of the nearest hits (``np.inf`` on a miss); see
        :mod:`digiteyes.render.geometry`."""
        if self.kind == "ball":
            return geometry.hit_sphere(o, d, self.a, self.radius)
        if self.kind == "capsule":
            return geometry.hit_capsule(o, d, self.a, self.b, self.radius)
        return geometry.hit_box(o, d, self.a, self.axes, self.half)

    def normals(self, p: np.ndarray) -> np.ndarray:
        """Outward unit normals (M, 3) at surface points p (M, 3)."""
        if self.kind == "ball":
            return geometry.sphere_normals(p, self.a)
        if self.kind == "capsule":
            return geometry.capsule_normals(p, self.a, self.b)
        return geometry.box_normals(p, self.a, self.axes, self.half)

    def labels(self, p: np.ndarray) -> np.ndarray:
        """Labels (M,) of surface points p (M, 3): ``far_label`` on a capsule's far cap."""
        out = np.full(len(p), self.label, dtype=np.int16)
        if self.kind == "capsule" and self.far_label != self.label:
            out[geometry.segment_parameter(p, self.a, self.b) > 1.0] = self.far_label
        return out

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Signed distance (M,) from points p (M, 3) to the surface, negative inside."""
        if self.kind == "ball":
            return np.linalg.norm(p - self.a, axis=1) - self.radius
        if self.kind == "capsule":
            s = np.clip(geometry.segment_parameter(p, self.a, self.b), 0.0, 1.0)
            axis_point = self.a + s[:, None] * (self.b - self.a)
            return np.linalg.norm(p - axis_point, axis=1) - self.radius
        q = np.abs((p - self.a) @ self.axes) - self.half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)

    def bounds(self, grid) -> np.ndarray | None:
        """Pixel bounds of the projection on a :class:`~digiteyes.render.pixels.PixelGrid`
        (primitive in that grid's camera frame)."""
        if self.kind == "ball":
            return grid.ball_bounds(self.a[None], self.radius)
        if self.kind == "capsule":
            return grid.ball_bounds(np.stack([self.a, self.b]), self.radius)
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        return grid.point_bounds(self.a + (signs * self.half) @ self.axes.T)


def tip_of_link(model: KinematicModel) -> dict[int, int]:
    """Map from a cylinder link's index to the index of the tip at its far end."""
    row_to_link = {link.row: i for i, link in enumerate(model.links)}
    out = {}
    for i, link in enumerate(model.links):
        if link.kind == "tip" and model.parent[link.row] in row_to_link:
            parent = row_to_link[model.parent[link.row]]
            if model.links[parent].kind == "link":
                out[parent] = i
    return out


def build_scene(model: KinematicModel, kin: Kinematics, index: int = 0) -> list[Primitive]:
    """The primitives of state ``index`` of ``kin``, in world coordinates (mm)."""
    T_shape = kin.T_world_shape[index]
    tips = tip_of_link(model)
    prims: list[Primitive] = []
    for i, link in enumerate(model.links):
        T = T_shape[link.row]
        origin, R = T[:3, 3], T[:3, :3]
        if link.kind == "link":
            end = origin + link.length * R[:, 0]
            prims.append(Primitive("capsule", i, origin, end, link.radius,
                                   far_label=tips.get(i, i)))
        elif link.kind == "tip":
            prims.append(Primitive("ball", i, origin, radius=link.radius))
        else:
            prims += _rounded_slab(i, origin + R @ np.asarray(link.centre), R,
                                   0.5 * np.asarray(link.size, dtype=float))
    return prims


def _rounded_slab(label: int, centre: np.ndarray, axes: np.ndarray,
                  half: np.ndarray) -> list[Primitive]:
    """A box of half extents ``half`` with all edges rounded by half its smallest size:
    one thin box plus capsules (or balls) along the edges of the inner rectangle."""
    thin = int(np.argmin(half))
    rounding = float(half[thin])
    i, j = (k for k in range(3) if k != thin)
    inner = half - rounding
    inner[thin] = 0.0
    prims = []
    if inner[i] > 0.0 and inner[j] > 0.0:
        slab = inner.copy()
        slab[thin] = rounding
        prims.append(Primitive("box", label, centre, axes=axes, half=slab))
    ei, ej = axes[:, i] * inner[i], axes[:, j] * inner[j]
    corners = [centre + ei + ej, centre - ei + ej, centre - ei - ej, centre + ei - ej]
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        if np.linalg.norm(b - a) > 1e-9:
            prims.append(Primitive("capsule", label, a, b, rounding, far_label=label))
        elif k == 0:
            prims.append(Primitive("ball", label, a, radius=rounding))
    return prims
