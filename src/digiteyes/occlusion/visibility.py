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
from digiteyes.occlusion._kernels import pair_overlap_kernel
from digiteyes.occlusion.parts import TemplatePart, towards_camera
from digiteyes.occlusion.windows import CAPSULE, ImageWindows

RULE_FRONT, RULE_BACK = 1, 2
"""Flags of :attr:`VisibilityOrder.pixel_depth`: the occluder is the joint rule's front
link (it hides the pixel at a tie) or its back link (it does not)."""


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
    pixel_depth : ``(part, occluder) -> 1 or 2`` for the occluders decided pixel by
        pixel: the two links of a revolute joint when the order is predicted with
        ``pixel_depth_at_joints``, each listed as an occluder of the other. At a pixel of
        the part the occluder hides it where its surface lies nearer the camera along
        the pixel's ray by more than a tolerance; within the tolerance (the joint, where
        the two surfaces meet) the joint rule decides: :data:`RULE_FRONT` marks the
        rule's front link, :data:`RULE_BACK` its back one.
    """

    order: np.ndarray
    relations: list[OcclusionRelation]
    cycles: list[list[int]] = field(default_factory=list)
    occluders: list[list[int]] = field(default_factory=list)
    pixel_depth: dict[tuple[int, int], int] = field(default_factory=dict)

    def csr(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The occluder lists as (start (K + 1,), index) int64 arrays for compiled code,
        and (index's length,) uint8 flags of :attr:`pixel_depth` (0 for occluders that
        hide every pixel of their overlap)."""
        start = np.zeros(len(self.occluders) + 1, dtype=np.int64)
        start[1:] = np.cumsum([len(o) for o in self.occluders])
        index = np.array([j for o in self.occluders for j in o], dtype=np.int64)
        tested = np.array([self.pixel_depth.get((k, j), 0)
                           for k, o in enumerate(self.occluders) for j in o], dtype=np.uint8)
        return start, index, tested

    def in_front(self, k: int) -> list[int]:
        """The occluders of part ``k`` that come before it in the order (the front of each
        relation; without the joints' back links that :attr:`pixel_depth` adds)."""
        return [j for j in self.occluders[k] if self.pixel_depth.get((k, j)) != RULE_BACK]

    def pairs(self) -> dict[tuple[int, int], int]:
        """``{(min, max): front}`` of every relation (for comparing frames)."""
        return {(min(r.front, r.back), max(r.front, r.back)): r.front for r in self.relations}


def _plane_depths(windows: ImageWindows, polys: list[int], camera: Camera,
                  pixels: np.ndarray) -> np.ndarray:
    """Camera depths (mm) of the palm faces ``polys`` seen at ``pixels`` (n, 2)."""
    if not polys:
        return np.zeros(0)
    corners = windows.world[polys]
    origin = corners[:, 0]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 3] - corners[:, 0])
    rays_o, rays_d = camera.viewing_rays(pixels)
    denom = np.einsum("ij,ij->i", rays_d, normal)
    safe = np.where(np.abs(denom) < 1e-9, 1.0, denom)
    t = np.einsum("ij,ij->i", origin - rays_o, normal) / safe
    z = camera.depth(rays_o + t[:, None] * rays_d)
    return np.where(np.abs(denom) < 1e-9, windows.depth[polys].mean(axis=1), z)


def occlusion_relations(parts: tuple[TemplatePart, ...], windows: ImageWindows,
                        camera: Camera, margin: float = 0.0) -> list[OcclusionRelation]:
    """The binary occlusion relations of all pairs whose windows overlap or come within
    ``margin`` px of each other (module docstring)."""
    bounds = windows.bounds()
    bounds[:, :2] -= margin
    K = len(parts)
    j, k = np.triu_indices(K, 1)
    near = ~((bounds[j, 0] > bounds[k, 2]) | (bounds[k, 0] > bounds[j, 2])
             | (bounds[j, 1] > bounds[k, 3]) | (bounds[k, 1] > bounds[j, 3]))
    pairs = np.ascontiguousarray(np.stack([j[near], k[near]], axis=1), dtype=np.int64)
    overlap = np.zeros(len(pairs), dtype=np.bool_)
    s_at = np.zeros(len(pairs))
    t_at = np.zeros(len(pairs))
    pair_overlap_kernel(windows.kind, windows.points, windows.radius, float(margin), pairs,
                        overlap, s_at, t_at)
    relations: list[OcclusionRelation | None] = []
    palm_pairs, polys, pixels, z_caps = [], [], [], []
    depth = windows.depth
    for n, (a, b) in enumerate(pairs):
        a, b = int(a), int(b)
        relation = _joint_relation(parts, windows, camera, a, b)
        if relation is None and overlap[n]:
            s, t = s_at[n], t_at[n]
            if windows.kind[a] == CAPSULE and windows.kind[b] == CAPSULE:
                za = (1 - s) * depth[a, 0] + s * depth[a, 1] - parts[a].radius
                zb = (1 - t) * depth[b, 0] + t * depth[b, 1] - parts[b].radius
                front, back = (a, b) if za <= zb else (b, a)
                relation = OcclusionRelation(front, back, abs(za - zb), "depth")
            else:
                cap, poly = (a, b) if windows.kind[a] == CAPSULE else (b, a)
                palm_pairs.append((len(relations), cap, poly))
                polys.append(poly)
                pixels.append((1 - s) * windows.points[cap, 0] + s * windows.points[cap, 1])
                z_caps.append((1 - s) * depth[cap, 0] + s * depth[cap, 1] - parts[cap].radius)
                relations.append(None)
                continue
        if relation is not None:
            relations.append(relation)
    z_polys = _plane_depths(windows, polys, camera, np.array(pixels).reshape(-1, 2))
    for (index, cap, poly), z_cap, z_poly in zip(palm_pairs, z_caps, z_polys, strict=True):
        front, back = (cap, poly) if z_cap <= z_poly else (poly, cap)
        relations[index] = OcclusionRelation(front, back, float(abs(z_cap - z_poly)), "depth")
    return [r for r in relations if r is not None]


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


def visibility_order(n_parts: int, relations: list[OcclusionRelation],
                     pixel_depth_at_joints: bool = False) -> VisibilityOrder:
    """Topological order of the occlusion graph (front first), cycles broken at their
    weakest edge (Sec. 3.4.2). Parts in no relation keep their index order. With
    ``pixel_depth_at_joints`` the two links of each revolute-joint relation (rule
    ``"joint"``) occlude each other pixel by pixel (:attr:`VisibilityOrder.pixel_depth`)
    instead of the front one hiding the back one wherever their windows overlap."""
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
    pixel_depth: dict[tuple[int, int], int] = {}
    for r in relations:
        front, back = (r.front, r.back) if rank[r.front] < rank[r.back] else (r.back, r.front)
        occluders[back].append(front)
        if pixel_depth_at_joints and r.rule == "joint":
            occluders[front].append(back)
            pixel_depth[back, front] = RULE_FRONT
            pixel_depth[front, back] = RULE_BACK
    return VisibilityOrder(np.asarray(order, dtype=np.int64), kept, cycles,
                           [sorted(o) for o in occluders], pixel_depth)


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
                       camera: Camera, margin: float = 0.0,
                       pixel_depth_at_joints: bool = False) -> VisibilityOrder:
    """Relations, graph and order for one camera at the state of ``windows`` (pairs
    within ``margin`` px count as overlapping; ``pixel_depth_at_joints`` as for
    :func:`visibility_order`)."""
    return visibility_order(len(parts), occlusion_relations(parts, windows, camera, margin),
                            pixel_depth_at_joints)
