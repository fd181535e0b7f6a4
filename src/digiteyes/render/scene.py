"""The posed model as solid primitives (balls, capsules, boxes) with link labels.

Geometry follows the DigitEyes report (Fig. 1: finger links are cylinders, fingertips
hemispheres) and the model file: a cylinder link of radius r and length a becomes a
capsule (a cylinder with hemispherical ends) around its axis segment; a tip becomes a
ball at its shape-frame origin, which is also the far end of the distal link, so the
tip and the capsule's far hemisphere coincide (that hemisphere carries the tip's label);
the palm box becomes a rounded slab, the Minkowski sum of a flat rectangle and a ball
whose radius is half the box's smallest size. That slab is exactly the union of a box
(the rectangle thickened by the ball radius) and four capsules along the rectangle's
edges, so it needs no primitive of its own.

Labels are indices into ``model.links``. Parameters are packed as in
:mod:`digiteyes.render._kernels` (one row of 15 numbers per primitive).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from digiteyes.kinematics import KinematicModel, Kinematics
from digiteyes.render._kernels import BALL, BOX, CAPSULE, N_PARAMS


@dataclass(frozen=True)
class Scene:
    """Primitives in one frame (world or camera), mm.

    ``kinds`` (P,) int8 (ball 0, capsule 1, box 2), ``labels`` (P,) int16 link indices,
    ``far_labels`` (P,) int16 label of a capsule's far hemisphere, ``params`` (P, 15).
    """

    kinds: np.ndarray
    labels: np.ndarray
    far_labels: np.ndarray
    params: np.ndarray

    def transformed(self, T: np.ndarray) -> Scene:
        """The scene in another frame: ``T`` (4, 4) maps this scene's frame to the new one."""
        R, t = T[:3, :3], T[:3, 3]
        params = self.params.copy()
        params[:, 0:3] = self.params[:, 0:3] @ R.T + t
        capsule = self.kinds == CAPSULE
        params[capsule, 3:6] = self.params[capsule, 3:6] @ R.T + t
        box = self.kinds == BOX
        axes = self.params[box, 3:12].reshape(-1, 3, 3)  # (B, axis, xyz)
        params[box, 3:12] = (axes @ R.T).reshape(-1, 9)
        return Scene(self.kinds, self.labels, self.far_labels, params)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distances (M, P) from points (M, 3) to each primitive, negative inside."""
        p = np.asarray(points, dtype=float)[:, None, :]  # (M, 1, 3)
        out = np.empty((p.shape[0], len(self.kinds)))
        P = self.params
        ball = self.kinds == BALL
        out[:, ball] = np.linalg.norm(p - P[ball, 0:3], axis=2) - P[ball, 3]
        capsule = self.kinds == CAPSULE
        a, b = P[capsule, 0:3], P[capsule, 3:6]
        s = np.clip(np.einsum("mpk,pk->mp", p - a, b - a) / np.sum((b - a) ** 2, axis=1),
                    0.0, 1.0)
        closest = a + s[..., None] * (b - a)
        out[:, capsule] = np.linalg.norm(p - closest, axis=2) - P[capsule, 6]
        box = self.kinds == BOX
        axes = P[box, 3:12].reshape(-1, 3, 3)
        local = np.abs(np.einsum("mpk,pik->mpi", p - P[box, 0:3], axes)) - P[box, 12:15]
        out[:, box] = (np.linalg.norm(np.maximum(local, 0.0), axis=2)
                       + np.minimum(local.max(axis=2), 0.0))
        return out


def tip_of_link(model: KinematicModel) -> dict[int, int]:
    """Map from a cylinder link's index to the index of the tip at its far end."""
    row_to_link = {link.row: i for i, link in enumerate(model.links)}
    out = {}
    for i, link in enumerate(model.links):
        parent = row_to_link.get(int(model.parent[link.row]), -1)
        if link.kind == "tip" and parent >= 0 and model.links[parent].kind == "link":
            out[parent] = i
    return out


def build_scene(model: KinematicModel, kin: Kinematics, index: int = 0) -> Scene:
    """The primitives of state ``index`` of ``kin``, in world coordinates (mm)."""
    layout = _layout(model)
    T = kin.T_world_shape[index][layout.rows]  # (P, 4, 4): each primitive's shape frame
    R, t = T[:, :3, :3], T[:, :3, 3]
    local = layout.params
    params = local.copy()
    params[:, 0:3] = np.einsum("pij,pj->pi", R, local[:, 0:3]) + t
    capsule = layout.kinds == CAPSULE
    params[capsule, 3:6] = np.einsum("pij,pj->pi", R[capsule], local[capsule, 3:6]) \
        + t[capsule]
    box = layout.kinds == BOX
    axes = local[box, 3:12].reshape(-1, 3, 3)  # (B, axis, xyz)
    params[box, 3:12] = np.einsum("bkj,bij->bki", axes, R[box]).reshape(-1, 9)
    return Scene(layout.kinds, layout.labels, layout.far_labels, params)


@dataclass(frozen=True)
class _Layout:
    """A model's primitives in their links' shape frames: a :class:`Scene` whose
    ``params`` are local, and ``rows`` (P,) the frame row each one moves with."""

    kinds: np.ndarray
    labels: np.ndarray
    far_labels: np.ndarray
    params: np.ndarray
    rows: np.ndarray


@lru_cache(maxsize=32)
def _layout(model: KinematicModel) -> _Layout:
    """The model's primitives, built once: a cylinder link's capsule runs along shape +x
    from the origin, a tip's ball sits at the origin, the palm's rounded slab is centred
    at ``link.centre`` with the shape frame's axes."""
    tips = tip_of_link(model)
    rows: list[tuple[int, int, int, int, np.ndarray]] = []
    for i, link in enumerate(model.links):
        if link.kind == "link":
            rows.append((CAPSULE, i, tips.get(i, i), link.row,
                         _pack(np.zeros(3), [link.length, 0.0, 0.0], [link.radius])))
        elif link.kind == "tip":
            rows.append((BALL, i, i, link.row, _pack(np.zeros(3), [link.radius])))
        elif link.kind == "palm":
            rows += [(kind, i, i, link.row, p) for kind, p in
                     _rounded_slab(np.asarray(link.centre, dtype=float), np.eye(3),
                                   0.5 * np.asarray(link.size, dtype=float))]
    return _Layout(np.array([r[0] for r in rows], dtype=np.int8),
                   np.array([r[1] for r in rows], dtype=np.int16),
                   np.array([r[2] for r in rows], dtype=np.int16),
                   np.stack([r[4] for r in rows]) if rows else np.zeros((0, N_PARAMS)),
                   np.array([r[3] for r in rows], dtype=np.intp))


def _pack(*parts) -> np.ndarray:
    flat = np.concatenate([np.ravel(np.asarray(p, dtype=float)) for p in parts])
    return np.concatenate([flat, np.zeros(N_PARAMS - flat.size)])


def _rounded_slab(centre: np.ndarray, axes: np.ndarray,
                  half: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """A box (axes as columns, half extents ``half``) with every edge rounded by half its
    smallest size: a thin box plus capsules along the edges of the inner rectangle."""
    thin = int(np.argmin(half))
    rounding = float(half[thin])
    i, j = (k for k in range(3) if k != thin)
    inner = half - rounding
    inner[thin] = 0.0
    prims = []
    if inner[i] > 0.0 and inner[j] > 0.0:
        slab = inner.copy()
        slab[thin] = rounding
        prims.append((BOX, _pack(centre, axes.T, slab)))
    ei, ej = axes[:, i] * inner[i], axes[:, j] * inner[j]
    corners = [centre + ei + ej, centre - ei + ej, centre - ei - ej, centre + ei - ej]
    edges = [(corners[k], corners[(k + 1) % 4]) for k in range(4)
             if np.linalg.norm(corners[(k + 1) % 4] - corners[k]) > 1e-9]
    if len(edges) == 2:  # a flat segment: both long edges are the same
        edges = edges[:1]
    for a, b in edges:
        prims.append((CAPSULE, _pack(a, b, [rounding])))
    if not edges:
        prims.append((BALL, _pack(centre, [rounding])))
    return prims
