"""Visibility orders predicted from the state (Rehg thesis Sec. 3.2, 3.4).

For one camera and one state:

1. **Binary occlusion relations** (Sec. 3.2.1): for every pair of parts whose windows
   overlap in the image, which one is in front. Three rules:

   * *revolute joint* (Sec. 3.2.2): two parts joined by a joint overlap around it; the
     child is in front when the joint bends it towards the camera, i.e. when the child's
     axis turns towards the camera relative to the parent's,
     ``(d_child - d_parent) . c > 0`` with ``c`` the unit vector from the joint to the
     camera. A tip is in front of its distal link when the finger points towards the
     camera (``d_distal . c > 0``).
   * *hand templates* (Sec. 3.2.3), any other pair: the closest points of the two
     projected outlines are lifted back to the parts (axis points of links and tips, the
     face plane of the palm), and the one nearer the camera there is in front. This
     covers the finger-finger, thumb-finger and palm-chain tests of the thesis without
     relying on the planarity of the fingers.

2. **Occlusion graph and order** (Sec. 3.4.2): an edge ``j -> k`` for "j occludes k";
   a topological sort gives the visibility order (front first). A cycle (three or more
   parts occluding each other in turn, which the binary-occlusion assumption rules out)
   is reported and broken at its weakest edge (the smallest depth margin).

3. **Occlusion events** (Sec. 3.4.3): relations that appear, disappear or flip between
   two frames; the tracker reports them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from digiteyes.camera import Camera
from digiteyes.occlusion.windows import CAPSULE, ImageWindows
from digiteyes.templates.geometry import TemplatePart, towards_camera


@dataclass(frozen=True)
class OcclusionRelation:
    """Part ``front`` occludes part ``back`` (indices into the part list); ``margin`` is
    the depth difference behind the decision, mm (larger is surer); ``rule`` is
    ``"joint"``, ``"tip"`` or ``"depth"``."""

    front: int
    back: int
    margin: float
    rule: str


@dataclass
class VisibilityOrder:
    """The predicted visibility of the parts in one camera.

    Attributes
    ----------
    order : (K,) part indices, front first.
    relations : the binary relations kept in the graph.
    cycles : each broken cycle as a list of part indices.
    occluders : for each part, the parts that occlude it (overlapping and earlier).
    """

    order: np.ndarray
    relations: list[OcclusionRelation]
    cycles: list[list[int]] = field(default_factory=list)
    occluders: list[list[int]] = field(default_factory=list)

    def csr(self) -> tuple[np.ndarray, np.ndarray]:
        """The occluder lists as (start (K + 1,), index) int64 arrays for compiled code."""
        start = np.zeros(len(self.occluders) + 1, dtype=np.int64)
        start[1:] = np.cumsum([len(o) for o in self.occluders])
        index = np.array([j for o in self.occluders for j in o], dtype=np.int64)
        return start, index

    def pairs(self) -> dict[tuple[int, int], int]:
        """``{(min, max): front}`` of every relation (for comparing frames)."""
        return {(min(r.front, r.back), max(r.front, r.back)): r.front for r in self.relations}


def _segment_closest(p0, p1, q0, q1) -> tuple[float, float, float]:
    """Closest points of two 2D segments: (distance, s on p, t on q), s, t in [0, 1]."""
    best = (np.inf, 0.0, 0.0)
    d1, d2 = p1 - p0, q1 - q0
    candidates = []
    for t in (0.0, 1.0):
        q = q0 + t * d2
        s = np.clip((q - p0) @ d1 / max(d1 @ d1, 1e-12), 0.0, 1.0)
        candidates.append((s, t))
    for s in (0.0, 1.0):
        p = p0 + s * d1
        t = np.clip((p - q0) @ d2 / max(d2 @ d2, 1e-12), 0.0, 1.0)
        candidates.append((s, t))
    denom = d1[0] * d2[1] - d1[1] * d2[0]
    if abs(denom) > 1e-12:
        e = q0 - p0
        s = (e[0] * d2[1] - e[1] * d2[0]) / denom
        t = (e[0] * d1[1] - e[1] * d1[0]) / denom
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            candidates.append((s, t))
    for s, t in candidates:
        dist = float(np.linalg.norm(p0 + s * d1 - q0 - t * d2))
        if dist < best[0]:
            best = (dist, float(s), float(t))
    return best


def _inside_polygon(points: np.ndarray, w: np.ndarray) -> float:
    """Signed distance of ``w`` inside a convex polygon (positive inside), px."""
    area = sum(points[i, 0] * points[(i + 1) % 4, 1] - points[(i + 1) % 4, 0] * points[i, 1]
               for i in range(4))
    s = 1.0 if area >= 0 else -1.0
    best = np.inf
    for i in range(4):
        e = points[(i + 1) % 4] - points[i]
        best = min(best, s * (e[0] * (w[1] - points[i, 1]) - e[1] * (w[0] - points[i, 0]))
                   / max(np.linalg.norm(e), 1e-12))
    return float(best)


def _plane_depth(windows: ImageWindows, k: int, camera: Camera, w: np.ndarray) -> float:
    """Camera depth of the palm face of part k seen at pixel ``w`` (mm)."""
    corners = windows.world[k]
    origin, normal = corners[0], np.cross(corners[1] - corners[0], corners[3] - corners[0])
    rays_o, rays_d = camera.viewing_rays(np.asarray(w, dtype=float)[None])
    denom = float(rays_d[0] @ normal)
    if abs(denom) < 1e-9:
        return float(windows.depth[k].mean())
    t = float((origin - rays_o[0]) @ normal) / denom
    return float(camera.depth(rays_o[0] + t * rays_d[0]))


def _overlap_depths(windows: ImageWindows, parts, j: int, k: int, camera: Camera,
                    margin: float) -> tuple[bool, float, float]:
    """Whether the windows of j and k overlap, and the two parts' depths where they come
    closest (front surface of links and tips: axis depth minus radius); outlines closer
    than ``margin`` px count as overlapping."""
    P, r = windows.points, windows.radius
    kinds = windows.kind
    if kinds[j] == CAPSULE and kinds[k] == CAPSULE:
        dist, s, t = _segment_closest(P[j, 0], P[j, 1], P[k, 0], P[k, 1])
        if dist >= r[j] + r[k] + margin:
            return False, 0.0, 0.0
        zj = (1 - s) * windows.depth[j, 0] + s * windows.depth[j, 1] - parts[j].radius
        zk = (1 - t) * windows.depth[k, 0] + t * windows.depth[k, 1] - parts[k].radius
        return True, zj, zk
    if kinds[j] != CAPSULE and kinds[k] != CAPSULE:
        return False, 0.0, 0.0
    cap, poly = (j, k) if kinds[j] == CAPSULE else (k, j)
    best = None
    for s in np.linspace(0.0, 1.0, 9):
        w = (1 - s) * P[cap, 0] + s * P[cap, 1]
        inside = _inside_polygon(P[poly], w) + r[cap] + margin
        if inside > 0 and (best is None or inside > best[0]):
            best = (inside, s, w)
    if best is None:
        return False, 0.0, 0.0
    _, s, w = best
    z_cap = (1 - s) * windows.depth[cap, 0] + s * windows.depth[cap, 1] - parts[cap].radius
    z_poly = _plane_depth(windows, poly, camera, w)
    return (True, z_cap, z_poly) if cap == j else (True, z_poly, z_cap)


def occlusion_relations(parts: tuple[TemplatePart, ...], windows: ImageWindows,
                        camera: Camera, margin: float = 0.0) -> list[OcclusionRelation]:
    """The binary occlusion relations of all pairs whose windows overlap or come within
    ``margin`` px of each other (module docstring)."""
    bounds = windows.bounds()
    bounds[:, :2] -= margin
    relations = []
    K = len(parts)
    for j in range(K):
        for k in range(j + 1, K):
            if (bounds[j, 0] > bounds[k, 2] or bounds[k, 0] > bounds[j, 2]
                    or bounds[j, 1] > bounds[k, 3] or bounds[k, 1] > bounds[j, 3]):
                continue
            relation = _joint_relation(parts, windows, camera, j, k)
            if relation is None:
                overlap, zj, zk = _overlap_depths(windows, parts, j, k, camera, margin)
                if not overlap:
                    continue
                front, back = (j, k) if zj <= zk else (k, j)
                relation = OcclusionRelation(front, back, abs(zj - zk), "depth")
            relations.append(relation)
    return relations


def _joint_relation(parts, windows: ImageWindows, camera: Camera, j: int,
                    k: int) -> OcclusionRelation | None:
    """The revolute-joint rule (Sec. 3.2.2) for a part and its parent, else None."""
    if parts[k].parent == j:
        parent, child = j, k
    elif parts[j].parent == k:
        parent, child = k, j
    else:
        return None
    if parts[parent].kind != "link":
        return None
    world = windows.world
    d_parent = world[parent, 1] - world[parent, 0]
    d_parent /= max(np.linalg.norm(d_parent), 1e-12)
    joint = world[parent, 1]
    c = towards_camera(camera, joint)
    if parts[child].kind == "tip":
        score, rule = float(d_parent @ c), "tip"
    elif parts[child].kind == "link":
        d_child = world[child, 1] - world[child, 0]
        d_child /= max(np.linalg.norm(d_child), 1e-12)
        score, rule = float((d_child - d_parent) @ c), "joint"
    else:
        return None
    margin = abs(score) * parts[child].radius
    return (OcclusionRelation(child, parent, margin, rule) if score > 0
            else OcclusionRelation(parent, child, margin, rule))


def visibility_order(n_parts: int, relations: list[OcclusionRelation]) -> VisibilityOrder:
    """Topological order of the occlusion graph (front first), cycles broken at their
    weakest edge (Sec. 3.4.2). Parts in no relation keep their index order."""
    kept = list(relations)
    cycles: list[list[int]] = []
    while True:
        order, cycle = _topological(n_parts, kept)
        if cycle is None:
            break
        cycles.append(cycle)
        in_cycle = [r for r in kept if r.front in cycle and r.back in cycle
                    and cycle[(cycle.index(r.front) + 1) % len(cycle)] == r.back]
        kept.remove(min(in_cycle, key=lambda r: r.margin))
    rank = np.empty(n_parts, dtype=int)
    rank[order] = np.arange(n_parts)
    occluders: list[list[int]] = [[] for _ in range(n_parts)]
    for r in relations:
        front, back = (r.front, r.back) if rank[r.front] < rank[r.back] else (r.back, r.front)
        occluders[back].append(front)
    return VisibilityOrder(np.asarray(order, dtype=np.int64), kept, cycles,
                           [sorted(o) for o in occluders])


def _topological(n: int, relations: list[OcclusionRelation]
                 ) -> tuple[list[int], list[int] | None]:
    """Kahn's algorithm; on a cycle, returns the partial order and one cycle."""
    succ: list[list[int]] = [[] for _ in range(n)]
    indegree = np.zeros(n, dtype=int)
    for r in relations:
        succ[r.front].append(r.back)
        indegree[r.back] += 1
    ready = sorted(int(i) for i in np.flatnonzero(indegree == 0))
    order = []
    while ready:
        i = ready.pop(0)
        order.append(i)
        for k in succ[i]:
            indegree[k] -= 1
            if indegree[k] == 0:
                ready.append(k)
                ready.sort()
    if len(order) == n:
        return order, None
    # walk backwards along remaining edges until a part repeats
    left = {i for i in range(n) if indegree[i] > 0}
    pred = {r.back: r.front for r in relations if r.back in left and r.front in left}
    node, seen = next(iter(left)), []
    while node not in seen:
        seen.append(node)
        node = pred[node]
    cycle = seen[seen.index(node):][::-1]
    return order, cycle


def occlusion_events(previous: VisibilityOrder | None,
                     current: VisibilityOrder) -> list[tuple[str, int, int]]:
    """Changes of the binary relations between two frames (Sec. 3.4.3): ``("appear",
    front, back)``, ``("disappear", a, b)`` and ``("flip", new_front, new_back)``."""
    if previous is None:
        return []
    old, new = previous.pairs(), current.pairs()
    events = []
    for pair, front in new.items():
        back = pair[0] + pair[1] - front
        if pair not in old:
            events.append(("appear", front, back))
        elif old[pair] != front:
            events.append(("flip", front, back))
    events += [("disappear", *pair) for pair in old if pair not in new]
    return events


def predict_visibility(parts: tuple[TemplatePart, ...], windows: ImageWindows,
                       camera: Camera, margin: float = 0.0) -> VisibilityOrder:
    """Relations, graph and order for one camera at the state of ``windows`` (pairs
    within ``margin`` px count as overlapping)."""
    return visibility_order(len(parts), occlusion_relations(parts, windows, camera, margin))
