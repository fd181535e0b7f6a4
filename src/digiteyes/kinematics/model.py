"""The kinematic model: a fixed tree of DH frames with a state layout (thesis Sec. 2.2, 4.2).

:class:`KinematicModel` is built once from a model file and never changes while tracking
(pinocchio's ``Model``); per-state results live in
:class:`~digiteyes.kinematics.forward.Kinematics`.

Frames are the rows of the table. Row ``r`` has its own coordinate frame ("frame r"); its
DH transform (thesis eq. 2.2) maps frame r to each frame in its ``next`` list, and its
shape frame is frame r followed by ``Rot_z(theta_r)`` (thesis eq. 2.4). The root row may
be a base node with a 7-state spatial transform ``T_world_root`` (quaternion + translation).

Configuration vs tangent: ``n_q`` numbers store a state (28 for the hand: four quaternion
numbers), ``n_v`` numbers are a step (27: a 3-vector rotation). See
:func:`~digiteyes.kinematics.state.integrate`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from digiteyes.errors import ModelFileError
from digiteyes.kinematics.model_file import FrameSpec, ModelSpec, StateSpec, read_model_file
from digiteyes.models import model_path

DESCRIBE_INDENT = 12
"""Deepest level :meth:`KinematicModel.describe` indents; deeper rows print their depth."""


@dataclass(frozen=True)
class Link:
    """A part of the model with geometry: a cylinder link, a fingertip sphere, the palm
    slab, or a tracked edge of a body.

    ``row`` is the frame row whose shape frame carries the geometry. Cylinders (kind
    ``"link"``) and edges (kind ``"edge"``) run from the shape-frame origin along +x for
    ``length`` mm with ``radius`` mm; tips are spheres of ``radius`` centred on the
    shape-frame origin; the palm is a box (``size``, ``centre`` in the shape frame, mm).
    Edges are measured like links but belong to another body's surface.
    """

    name: str
    kind: str
    row: int
    length: float
    radius: float
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)


class KinematicModel:
    """A tree of frames with DH transforms, built from a :class:`ModelSpec`.

    Attributes (all fixed): ``name``, ``n_frames``, ``parent`` (row of each frame's parent,
    -1 at the root), ``theta``, ``d``, ``a``, ``alpha`` (constant DH parts per row),
    ``theta_state`` / ``d_state`` (state index per row, -1 if none), ``base_state`` (first of
    the 7 pose states or None), ``state_names``, ``state_kinds``, ``lower``, ``upper``
    (limits per state, radians or mm), ``links`` and ``levels`` (rows grouped by depth).
    """

    def __init__(self, spec: ModelSpec) -> None:
        self.name = spec.name
        self.description = spec.description
        self.path = spec.path
        self.spec = spec
        self._check_states(spec)
        self._build_tree(spec)
        self._build_links(spec)
        self._build_tangent_layout()

    # ------------------------------------------------------------------ construction
    def _check_states(self, spec: ModelSpec) -> None:
        states = sorted(spec.states, key=lambda s: s.index)
        for expected, state in enumerate(states):
            if state.index != expected:
                raise ModelFileError(
                    spec.path, state.line,
                    f"states must be numbered q0..q{len(states) - 1} without gaps or repeats; "
                    f"expected q{expected}, got q{state.index}",
                )
        names = [s.name for s in states]
        seen: dict[str, int] = {}
        for state in sorted(states, key=lambda s: s.line):
            if state.name in seen:
                raise ModelFileError(
                    spec.path, state.line,
                    f"state name {state.name!r} repeats (first on line {seen[state.name]})",
                )
            seen[state.name] = state.line
        self.n_q = len(states)
        self.state_names: tuple[str, ...] = tuple(names)
        self.state_kinds: tuple[str, ...] = tuple(s.kind for s in states)
        self.lower = np.array([s.lower for s in states])
        self.upper = np.array([s.upper for s in states])
        self._state_specs: tuple[StateSpec, ...] = tuple(states)

    def _use_state(self, used: dict[int, int], index: int, kind: str, row: FrameSpec) -> None:
        path = self.spec.path
        if index >= self.n_q:
            raise ModelFileError(path, row.line, f"q{index} is not declared in [states]")
        if index in used:
            raise ModelFileError(
                path, row.line, f"q{index} is already used by the row on line {used[index]}"
            )
        if self.state_kinds[index] != kind:
            raise ModelFileError(
                path, row.line,
                f"q{index} is declared as {self.state_kinds[index]!r} but used as {kind!r}",
            )
        used[index] = row.line

    def _build_tree(self, spec: ModelSpec) -> None:
        rows = sorted(spec.frames, key=lambda f: f.index)
        path = spec.path
        for expected, row in enumerate(rows):
            if row.index != expected:
                raise ModelFileError(
                    path, row.line,
                    f"frames must be numbered 0..{len(rows) - 1} without gaps or repeats; "
                    f"expected {expected}, got {row.index}",
                )
        n = len(rows)
        parent = np.full(n, -1)
        for row in rows:
            for child in row.next:
                if child >= n:
                    raise ModelFileError(path, row.line, f"next frame {child} does not exist")
                if child == row.index or parent[child] != -1:
                    raise ModelFileError(
                        path, row.line, f"frame {child} is reached twice; the frames must form "
                        "a tree",
                    )
                parent[child] = row.index
        roots = [r for r in range(n) if parent[r] == -1]
        if len(roots) != 1:
            raise ModelFileError(
                path, rows[roots[1]].line if roots else rows[parent[0]].line,
                f"the frames must form one tree with one root; found roots {roots}",
            )
        root = roots[0]
        levels: list[list[int]] = []
        depth = np.full(n, -1)
        queue = deque([root])
        depth[root] = 0
        while queue:
            r = queue.popleft()
            if len(levels) <= depth[r]:
                levels.append([])
            levels[depth[r]].append(r)
            for child in rows[r].next:
                depth[child] = depth[r] + 1
                queue.append(child)
        if (depth < 0).any():
            lost = int(np.flatnonzero(depth < 0)[0])
            raise ModelFileError(path, rows[lost].line, f"frame {lost} is in a cycle")

        used: dict[int, int] = {}
        self.base_state: int | None = None
        theta_state = np.full(n, -1)
        d_state = np.full(n, -1)
        for row in rows:
            if row.pose_state is not None:
                if row.index != root:
                    raise ModelFileError(path, row.line, "only the root row may have pose:qK")
                k = row.pose_state
                for offset, kind in enumerate(("quat",) * 4 + ("trans",) * 3):
                    self._use_state(used, k + offset, kind, row)
                self.base_state = k
            if row.theta_state is not None:
                self._use_state(used, row.theta_state, "angle", row)
                theta_state[row.index] = row.theta_state
            if row.d_state is not None:
                self._use_state(used, row.d_state, "length", row)
                d_state[row.index] = row.d_state
        unused = sorted(set(range(self.n_q)) - set(used))
        if unused:
            spec_line = self._state_specs[unused[0]].line
            raise ModelFileError(path, spec_line, f"q{unused[0]} is declared but no row uses it")

        self.n_frames = n
        self.root = root
        self.parent = parent
        self.depth = depth
        self.levels: tuple[np.ndarray, ...] = tuple(np.array(lv) for lv in levels)
        self.order = np.concatenate(self.levels)
        self.theta = np.array([r.theta for r in rows])
        self.d = np.array([r.d for r in rows])
        self.a = np.array([r.a for r in rows])
        self.alpha = np.array([r.alpha for r in rows])
        self.cos_alpha = np.cos(self.alpha)
        self.sin_alpha = np.sin(self.alpha)
        self.theta_state = theta_state
        self.d_state = d_state
        self.rows: tuple[FrameSpec, ...] = tuple(rows)
        # ancestors[r, s]: state s moves the shape frame of row r (row r's own joint included).
        joint_row = np.full(self.n_q, -1)
        joint_row[theta_state[theta_state >= 0]] = np.flatnonzero(theta_state >= 0)
        joint_row[d_state[d_state >= 0]] = np.flatnonzero(d_state >= 0)
        self.joint_row = joint_row
        moved = np.zeros((n, self.n_q), dtype=bool)
        for level in self.levels:
            for r in level:
                if parent[r] >= 0:
                    moved[r] = moved[parent[r]]
                    p = parent[r]
                    if theta_state[p] >= 0:
                        moved[r, theta_state[p]] = True
                    if d_state[p] >= 0:
                        moved[r, d_state[p]] = True
                elif self.base_state is not None:
                    moved[r, self.base_state:self.base_state + 7] = True
        # A shape frame also turns with its own row's theta (thesis eq. 2.4).
        shape_moved = moved.copy()
        own = theta_state >= 0
        shape_moved[np.flatnonzero(own), theta_state[own]] = True
        self.shape_moved_by = shape_moved

    def _build_links(self, spec: ModelSpec) -> None:
        links: list[Link] = []
        for row in self.rows:
            if row.shape is None:
                continue
            name = row.geometry or f"frame{row.index}"
            if row.shape.kind in ("cyl", "edge"):
                if row.a <= 0.0:
                    raise ModelFileError(
                        spec.path, row.line, f"a {row.shape.kind}() link needs a positive length a"
                    )
                kind = "link" if row.shape.kind == "cyl" else "edge"
                links.append(Link(name, kind, row.index, row.a, row.shape.params[0]))
            elif row.shape.kind == "tip":
                links.append(Link(name, "tip", row.index, 0.0, row.shape.params[0]))
            else:
                p = row.shape.params
                links.append(Link(name, "palm", row.index, 0.0, 0.5 * p[2], p[:3], p[3:6]))
        seen: dict[str, int] = {}
        for link in sorted(links, key=lambda link: self.rows[link.row].line):
            line = self.rows[link.row].line
            if link.name in seen:
                raise ModelFileError(
                    spec.path, line,
                    f"geometry name {link.name!r} repeats (first on line {seen[link.name]})",
                )
            seen[link.name] = line
        self.links: tuple[Link, ...] = tuple(links)

    def _build_tangent_layout(self) -> None:
        """Index maps between configuration (n_q) and tangent (n_v) coordinates."""
        q_to_v = np.arange(self.n_q)
        if self.base_state is None:
            self.n_v = self.n_q
        else:
            k = self.base_state
            self.n_v = self.n_q - 1
            q_to_v[k + 4:] -= 1
            q_to_v[k:k + 4] = -1  # the quaternion maps to the 3 rotation components k..k+2
        self.q_to_v = q_to_v
        names = []
        for i, name in enumerate(self.state_names):
            if self.base_state is not None and i == self.base_state:
                prefix = name.split(".")[0]
                names += [f"{prefix}.rx", f"{prefix}.ry", f"{prefix}.rz"]
            elif q_to_v[i] >= 0:
                names.append(name)
        self.tangent_names: tuple[str, ...] = tuple(names)

    # ------------------------------------------------------------------ queries
    def state_index(self, name: str) -> int:
        """Index of a state by name (``"index.pip"``) or by ``"q9"``."""
        if name in self.state_names:
            return self.state_names.index(name)
        if name.startswith("q") and name[1:].isdigit() and int(name[1:]) < self.n_q:
            return int(name[1:])
        raise KeyError(
            f"model {self.name!r} has no state {name!r}; states are "
            f"{', '.join(self.state_names)}"
        )

    def link(self, name: str) -> Link:
        """The link (or tip, or palm) with this geometry name."""
        for link in self.links:
            if link.name == name:
                return link
        raise KeyError(f"model {self.name!r} has no link {name!r}")

    def axis_and_tip_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Both ends of every cylinder link's and edge's axis and every tip centre, as
        shape-frame rows (P,) and offsets (P, 3) mm: the points the DigitEyes residuals
        live on."""
        rows: list[int] = []
        offsets: list[tuple[float, float, float]] = []
        for link in self.links:
            if link.kind in ("link", "edge"):
                rows += [link.row, link.row]
                offsets += [(0.0, 0.0, 0.0), (link.length, 0.0, 0.0)]
            elif link.kind == "tip":
                rows.append(link.row)
                offsets.append((0.0, 0.0, 0.0))
        return np.array(rows, dtype=int), np.array(offsets, dtype=float).reshape(-1, 3)

    def neutral(self) -> np.ndarray:
        """The zero state: identity quaternion, zero translation, all joints at zero,
        clipped into the joint limits."""
        q = np.zeros(self.n_q)
        if self.base_state is not None:
            q[self.base_state] = 1.0
        return np.clip(q, self.lower, self.upper)

    def describe(self) -> str:
        """A human-readable summary: the frame tree and the state layout."""
        lines = [f"model {self.name}: {self.description}".rstrip(": "),
                 f"  {self.n_frames} frames, "
                 f"{sum(link.kind in ('link', 'palm') for link in self.links)} rigid bodies, "
                 f"{sum(link.kind == 'tip' for link in self.links)} tips, "
                 f"{self.n_q} states (tangent size {self.n_v})", "", "frame tree:"]

        stack = [(self.root, 0)]
        while stack:
            r, depth = stack.pop()
            # Indentation stops growing at DESCRIBE_INDENT levels (deeper rows say their
            # depth), so deep chains print in linear, not quadratic, size.
            indent = "  " * (1 + min(depth, DESCRIBE_INDENT))
            if depth > DESCRIBE_INDENT:
                indent += f"[depth {depth}] "
            row = self.rows[r]
            joint = ""
            if row.pose_state is not None:
                joint = f"pose q{row.pose_state}..q{row.pose_state + 6}"
            elif row.theta_state is not None:
                joint = f"revolute q{row.theta_state} ({self.state_names[row.theta_state]})"
            elif row.d_state is not None:
                joint = f"prismatic q{row.d_state} ({self.state_names[row.d_state]})"
            shape = ""
            if row.shape is not None:
                shape = f"{row.shape.kind}({', '.join(f'{p:g}' for p in row.shape.params)})"
            label = row.geometry or ""
            lines.append(f"{indent}{r:>3} {label:<18} {joint:<32} {shape}".rstrip())
            stack.extend((child, depth + 1) for child in reversed(row.next))
        lines += ["", "state layout:"]
        for i, (name, kind) in enumerate(zip(self.state_names, self.state_kinds, strict=True)):
            lim = ""
            if np.isfinite(self.lower[i]) or np.isfinite(self.upper[i]):
                if kind == "angle":
                    lim = f"[{np.degrees(self.lower[i]):g}, {np.degrees(self.upper[i]):g}] deg"
                else:
                    lim = f"[{self.lower[i]:g}, {self.upper[i]:g}] mm"
            lines.append(f"  q{i:<3} {name:<18} {kind:<6} {lim}".rstrip())
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"KinematicModel({self.name!r}, n_frames={self.n_frames}, n_q={self.n_q})"


def model_from_file(path: str | Path) -> KinematicModel:
    """Build a :class:`KinematicModel` from a model file on disk."""
    return KinematicModel(read_model_file(path))


@lru_cache(maxsize=32)
def _load_cached(path: str, mtime: float) -> KinematicModel:
    return model_from_file(path)


def load_model(name_or_path: str | Path) -> KinematicModel:
    """Load a :class:`KinematicModel` by shipped name (``"hand"``, docs/models.md) or model
    file path: the one route to a model (loaded once per file and modification time)."""
    path = model_path(name_or_path)
    try:
        mtime = path.stat().st_mtime
        resolved = str(path.resolve())
    except OSError as exc:
        raise ModelFileError(str(path), None, f"no such model file ({exc.strerror})") from None
    return _load_cached(resolved, mtime)
