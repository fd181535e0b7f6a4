"""The "flesh" hand: a surface of its own, driven by the model's joint frames.

The tracking model draws a hand as capsules, balls and a rounded slab (:mod:`scene`);
images drawn from that same geometry let a tracker succeed for the wrong reason (the
"inverse crime"). The flesh hand shares only the kinematic state with it: forward
kinematics gives the joint frames, and this module hangs a different surface on them.

* **Phalanges** are round cones (the convex hull of two balls) from joint to joint whose
  radius shrinks towards the tip (anatomical widths below, not the model file's radii);
  the distal one ends in a smaller, rounded pad at the tip centre.
* **Joints** are smooth unions of neighbouring phalanges (blend width 3 mm), fingers meet
  the palm with a wide blend (8-10 mm).
* **The palm** is a thick round box (about 22 mm, against the model's 15 mm slab) with
  fleshy metacarpal ridges to each knuckle, a knuckle ridge, a thenar eminence reaching
  the thumb's MP joint, a web between thumb and index finger and a wrist stub.

Labels: a primitive carries the link whose frames drive it (palm parts carry the palm);
the renderer labels each surface point with the primitive nearest to it. The cap of a
distal phalanx beyond the tip centre carries the tip's label, as in :mod:`scene`.

Sizes scale with the model's palm (its length over Appendix A's 86 mm), so a model scaled
by :func:`digiteyes.synth.perturb.scale_model` gets a flesh hand scaled alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics
from digiteyes.render._flesh_kernels import N_PARAMS, ROUND_BOX, ROUND_CONE, field_at
from digiteyes.render.scene import tip_of_link

APPENDIX_A_PALM_LENGTH_MM = 86.0
"""Length of Appendix A's palm box along the fingers: the size reference of the radii."""

PHALANX_RADII_MM = {
    "index": ((9.6, 8.9), (8.7, 8.0), (7.9, 6.6)),
    "middle": ((9.8, 9.1), (8.9, 8.2), (8.1, 6.8)),
    "ring": ((9.2, 8.5), (8.3, 7.7), (7.6, 6.4)),
    "little": ((8.2, 7.5), (7.3, 6.8), (6.8, 5.8)),
    "thumb": ((11.5, 10.5), (10.5, 9.4), (9.6, 7.6)),
}
"""Radii (mm) at the proximal and distal end of each phalanx (proximal, middle, distal;
for the thumb metacarpal, proximal, distal) of a hand of Appendix A's size: half the
widths of an adult hand's fingers at the joints, which narrow towards the tip."""

JOINT_BLEND_MM = 3.0
PALM_BLEND_MM = 9.0
TAPER = (0.92, 0.82)
"""Radii of a link the table does not name, as fractions of the model file's radius."""


@dataclass(frozen=True)
class FleshScene:
    """The flesh primitives in one frame (world or camera), mm.

    ``kinds`` (P,) int8 (round cone 0, round box 1); ``params`` (P, 17) as in
    :mod:`digiteyes.render._flesh_kernels`; ``blend`` (P,) smooth-union width k (mm) with
    everything before it; ``labels``, ``far_labels`` (P,) int16 link indices;
    ``frames`` (P, 12) texture frames (origin, three unit axes as rows), which move with
    the skin; ``nails`` (P, 4) dorsal unit vector of a distal phalanx and a flag.
    """

    kinds: np.ndarray
    params: np.ndarray
    blend: np.ndarray
    labels: np.ndarray
    far_labels: np.ndarray
    frames: np.ndarray
    nails: np.ndarray

    def transformed(self, T: np.ndarray) -> FleshScene:
        """The scene in another frame: ``T`` (4, 4) maps this scene's frame to the new one."""
        R, t = T[:3, :3], T[:3, 3]
        params = self.params.copy()
        params[:, 0:3] = self.params[:, 0:3] @ R.T + t
        cone = self.kinds == ROUND_CONE
        params[cone, 3:6] = self.params[cone, 3:6] @ R.T + t
        box = self.kinds == ROUND_BOX
        params[box, 3:12] = (self.params[box, 3:12].reshape(-1, 3, 3) @ R.T).reshape(-1, 9)
        frames = self.frames.copy()
        frames[:, 0:3] = self.frames[:, 0:3] @ R.T + t
        frames[:, 3:12] = (self.frames[:, 3:12].reshape(-1, 3, 3) @ R.T).reshape(-1, 9)
        nails = self.nails.copy()
        nails[:, 0:3] = self.nails[:, 0:3] @ R.T
        return FleshScene(self.kinds, params, self.blend, self.labels, self.far_labels,
                          frames, nails)

    def field(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The blended signed distance (M,) at points (M, 3), negative inside, and the
        index (M,) of the nearest primitive."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
        return field_at(pts, self.kinds, self.params, self.blend)

    def bounding_spheres(self) -> np.ndarray:
        """(P, 4) centre and radius of a sphere holding each primitive grown by its blend
        width: outside it the primitive cannot change the blended surface."""
        P = self.params
        out = np.empty((len(self.kinds), 4))
        cone = self.kinds == ROUND_CONE
        out[cone, :3] = 0.5 * (P[cone, 0:3] + P[cone, 3:6])
        out[cone, 3] = 0.5 * np.linalg.norm(P[cone, 3:6] - P[cone, 0:3], axis=1) \
            + np.maximum(P[cone, 6], P[cone, 7])
        box = ~cone
        out[box, :3] = P[box, 0:3]
        out[box, 3] = np.linalg.norm(P[box, 12:15], axis=1) + P[box, 15]
        out[:, 3] += self.blend + 1e-3
        return out

    def bounding_cores(self) -> np.ndarray:
        """(P, 7) a segment and a radius (a capsule) holding each primitive grown by its
        blend width, inside its bounding sphere: a tighter test for long phalanges."""
        P = self.params
        out = np.empty((len(self.kinds), 7))
        cone = self.kinds == ROUND_CONE
        out[cone, 0:6] = P[cone, 0:6]
        out[cone, 6] = np.maximum(P[cone, 6], P[cone, 7])
        box = ~cone
        out[box, 0:3] = out[box, 3:6] = P[box, 0:3]
        out[box, 6] = np.linalg.norm(P[box, 12:15], axis=1) + P[box, 15]
        out[:, 6] += self.blend + 1e-3
        return out


def build_flesh(model: KinematicModel, kin: Kinematics, index: int = 0) -> FleshScene:
    """The flesh primitives of state ``index`` of ``kin``, world mm."""
    layout = _layout(model)
    T = kin.T_world_shape[index]
    a = _apply(T[layout.row_a], layout.local_a)
    b = _apply(T[layout.row_b], layout.local_b)
    R_tex = T[layout.row_tex, :3, :3]  # (P, 3, 3): columns are the frame's axes
    params = np.zeros((len(layout.kinds), N_PARAMS))
    cone = layout.kinds == ROUND_CONE
    params[cone, 0:3], params[cone, 3:6] = a[cone], b[cone]
    params[cone, 6:8] = layout.sizes[cone, 0:2]
    box = ~cone
    params[box, 0:3] = a[box]
    params[box, 3:12] = np.swapaxes(R_tex[box], 1, 2).reshape(-1, 9)
    params[box, 12:16] = layout.sizes[box]
    frames = np.concatenate([T[layout.row_tex, :3, 3],
                             np.swapaxes(R_tex, 1, 2).reshape(-1, 9)], axis=1)
    nails = np.zeros((len(layout.kinds), 4))
    nails[:, 0:3] = np.einsum("pij,pj->pi", R_tex, layout.dorsal)
    nails[:, 3] = layout.has_nail
    return FleshScene(layout.kinds, params, layout.blend, layout.labels, layout.far_labels,
                      frames, nails)


def _apply(T: np.ndarray, local: np.ndarray) -> np.ndarray:
    return np.einsum("pij,pj->pi", T[:, :3, :3], local) + T[:, :3, 3]


@dataclass(frozen=True)
class _Layout:
    """Each primitive as points fixed in frames: a (row_a, local_a), b (row_b, local_b);
    ``sizes`` (ra, rb) or (inner half extents, rounding); texture frame row ``row_tex``,
    whose axes are the round box's axes; ``dorsal`` in that frame."""

    kinds: np.ndarray
    row_a: np.ndarray
    local_a: np.ndarray
    row_b: np.ndarray
    local_b: np.ndarray
    sizes: np.ndarray
    blend: np.ndarray
    labels: np.ndarray
    far_labels: np.ndarray
    row_tex: np.ndarray
    dorsal: np.ndarray
    has_nail: np.ndarray


@lru_cache(maxsize=32)
def _layout(model: KinematicModel) -> _Layout:
    """The flesh primitives of ``model`` in its frames, built once per model."""
    links = list(model.links)
    palm = next((i for i, link in enumerate(links) if link.kind == "palm"), None)
    kin0 = forward_kinematics(model, model.neutral())
    T0 = kin0.T_world_shape[0]
    tips = tip_of_link(model)
    rows: list[dict] = []
    size = 1.0
    if palm is not None:
        size = float(links[palm].size[1]) / APPENDIX_A_PALM_LENGTH_MM
        rows += _palm_parts(model, palm, T0, size)
    for i, link in enumerate(links):
        if link.kind != "link":
            continue
        finger, _, segment = link.name.partition(".")
        radii = _radii(finger, segment, link.radius, size)
        distal = i in tips
        R = T0[link.row, :3, :3]
        dorsal = np.zeros(3)
        if distal and palm is not None:
            dorsal = -(R.T @ T0[links[palm].row, :3, 2])
        rows.append(dict(kind=ROUND_CONE, row_a=link.row, a=np.zeros(3), row_b=link.row,
                         b=np.array([link.length, 0.0, 0.0]), sizes=radii,
                         blend=JOINT_BLEND_MM if segment not in ("proximal", "metacarpal")
                         else PALM_BLEND_MM, label=i, far=tips.get(i, i), tex=link.row,
                         dorsal=dorsal, nail=float(distal)))
    return _Layout(
        kinds=np.array([r["kind"] for r in rows], dtype=np.int8),
        row_a=np.array([r["row_a"] for r in rows], dtype=np.intp),
        local_a=np.array([r["a"] for r in rows], dtype=float).reshape(-1, 3),
        row_b=np.array([r["row_b"] for r in rows], dtype=np.intp),
        local_b=np.array([r["b"] for r in rows], dtype=float).reshape(-1, 3),
        sizes=np.array([np.resize(np.asarray(r["sizes"], dtype=float), 4) for r in rows]),
        blend=np.array([r["blend"] for r in rows], dtype=float),
        labels=np.array([r["label"] for r in rows], dtype=np.int16),
        far_labels=np.array([r["far"] for r in rows], dtype=np.int16),
        row_tex=np.array([r["tex"] for r in rows], dtype=np.intp),
        dorsal=np.array([r["dorsal"] for r in rows], dtype=float).reshape(-1, 3),
        has_nail=np.array([r["nail"] for r in rows], dtype=float))


def _radii(finger: str, segment: str, model_radius: float, size: float) -> tuple:
    order = ("metacarpal", "proximal", "distal") if finger == "thumb" else \
        ("proximal", "middle", "distal")
    if finger in PHALANX_RADII_MM and segment in order:
        ra, rb = PHALANX_RADII_MM[finger][order.index(segment)]
        return (ra * size, rb * size)
    return (TAPER[0] * model_radius, TAPER[1] * model_radius)


def _palm_parts(model: KinematicModel, palm: int, T0: np.ndarray, size: float) -> list[dict]:
    """Round box body, wrist stub, metacarpal and knuckle ridges, thenar eminence and the
    thumb web, all fixed in the palm frame except the ends at the thumb's joints."""
    link = model.links[palm]
    row = link.row
    centre = np.asarray(link.centre, dtype=float)
    T_inv = np.linalg.inv(T0[row])

    def in_palm(point: np.ndarray) -> np.ndarray:
        return T_inv[:3, :3] @ point + T_inv[:3, 3]

    def base(name: str) -> np.ndarray | None:
        try:
            return in_palm(T0[model.link(name).row, :3, 3])
        except (KeyError, ValueError):
            return None

    s = size
    parts = [dict(kind=ROUND_BOX, row_a=row, a=centre + s * np.array([0.0, -2.0, 1.5]),
                  row_b=row, b=np.zeros(3), sizes=(26.0 * s, 30.0 * s, 1.0 * s, 10.0 * s),
                  blend=0.0),
             dict(kind=ROUND_BOX, row_a=row, a=centre + s * np.array([-1.5, -55.0, 1.5]),
                  row_b=row, b=np.zeros(3), sizes=(10.0 * s, 16.0 * s, 0.0, 16.0 * s),
                  blend=14.0 * s)]
    knuckles = [(f, base(f"{f}.proximal")) for f in ("index", "middle", "ring", "little")]
    knuckles = [(f, p) for f, p in knuckles if p is not None]
    for _finger, p in knuckles:
        start = np.array([0.6 * p[0], -35.0 * s, p[2] + 1.5 * s])
        parts.append(dict(kind=ROUND_CONE, row_a=row, a=start, row_b=row,
                          b=p - np.array([0.0, 4.0 * s, 0.0]), sizes=(11.0 * s, 10.0 * s),
                          blend=10.0 * s))
    if len(knuckles) >= 2:
        first, last = knuckles[0][1], knuckles[-1][1]
        parts.append(dict(kind=ROUND_CONE, row_a=row, a=first - np.array([0, 5.0 * s, 0]),
                          row_b=row, b=last - np.array([0, 5.0 * s, 0]),
                          sizes=(10.5 * s, 9.0 * s), blend=6.0 * s))
    thumb_mp = _try_row(model, "thumb.proximal")
    if thumb_mp is not None:
        parts.append(dict(kind=ROUND_CONE, row_a=row,
                          a=centre + s * np.array([14.0, -30.0, 7.0]), row_b=thumb_mp,
                          b=np.zeros(3), sizes=(15.0 * s, 9.5 * s), blend=10.0 * s))
        if knuckles:
            parts.append(dict(kind=ROUND_CONE, row_a=row,
                              a=knuckles[0][1] + s * np.array([0.0, -20.0, 4.0]),
                              row_b=thumb_mp, b=np.zeros(3), sizes=(8.0 * s, 6.5 * s),
                              blend=9.0 * s))
    for part in parts:
        part.update(label=palm, far=palm, tex=row, dorsal=np.zeros(3), nail=0.0)
    return parts


def _try_row(model: KinematicModel, name: str) -> int | None:
    try:
        return model.link(name).row
    except (KeyError, ValueError):
        return None
