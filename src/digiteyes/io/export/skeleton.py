"""The animation skeleton of a model: one joint per kinematic frame, constant offsets.

BVH and glTF both want a tree of joints whose offsets from their parents are constant
and whose local rotations change per frame. The DH frames of a model (thesis eq. 2.2)
give that once each joint takes the orientation of its row's *shape* frame (thesis
eq. 2.4, the row frame turned by the row's own theta): the child of row ``r`` then sits
at the constant offset ``(a_r, 0, d_r)`` in joint ``r`` (``Trans_z(d) Trans_x(a)``), and
joint ``c``'s local rotation ``R_shape_r^T R_shape_c = Rot_x(alpha_r) Rot_z(theta_c)``
carries the joint angle. The root joint's global pose is ``T_world_shape`` of the root
row. The joint positions are the row-frame origins (joint centres, fingertips).

Rows that only carry the tracked palm edges (``edge`` links) are left out; a model with
a prismatic state (``d`` from the state) has no constant offset and is refused.

A left hand is tracked as the right hand of the mirror image (:mod:`digiteyes.camera.
mirror`); its skeleton is that of the mirror image reflected back, ``S = diag(-1, 1,
1)``: offsets ``S o``, world rotations ``S R S`` (so local rotations ``S L S``, still
proper rotations) and positions ``S p``, the real hand's joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera.mirror import REFLECTION
from digiteyes.errors import StateError
from digiteyes.kinematics import KinematicModel, forward_kinematics


@dataclass(frozen=True)
class Skeleton:
    """Joints of a model in parent-before-child order.

    rows (J,) model rows, names (J,) unique joint names, parent (J,) index into the
    joints (-1 for the root), offsets_mm (J, 3) position of each joint in its parent
    joint's frame (root: zeros); mirrored: the skeleton of a left hand, the model's
    reflected (module docstring).
    """

    rows: tuple[int, ...]
    names: tuple[str, ...]
    parent: np.ndarray
    offsets_mm: np.ndarray
    mirrored: bool = False

    def __len__(self) -> int:
        return len(self.rows)

    def children(self, j: int) -> list[int]:
        """Indices of the joints whose parent is joint ``j``."""
        return [int(c) for c in np.flatnonzero(self.parent == j)]


def _joint_name(model: KinematicModel, r: int) -> str:
    """A joint's name: its row's geometry, else the state its row turns, else the first
    named geometry below it with the row number (``index_frame1``)."""
    row = model.rows[r]
    if row.geometry:
        return row.geometry.replace(".", "_")
    if model.theta_state[r] >= 0:
        return model.state_names[model.theta_state[r]].replace(".", "_")
    below = r
    while model.rows[below].next and not model.rows[below].geometry:
        below = model.rows[below].next[0]
    prefix = (model.rows[below].geometry or "frame").split(".")[0]
    return f"{prefix}_frame{r}"


def build_skeleton(model: KinematicModel, mirrored: bool = False) -> Skeleton:
    """The skeleton of ``model`` (see the module docstring), reflected for a left hand
    with ``mirrored``. Raises :class:`StateError` for a model with prismatic states."""
    if (model.d_state >= 0).any():
        raise StateError(f"model {model.name!r} has prismatic states; the export needs "
                         "constant bone offsets")
    keep = np.zeros(model.n_frames, dtype=bool)
    for link in model.links:
        if link.kind == "edge":
            continue
        r = link.row
        while r >= 0 and not keep[r]:
            keep[r] = True
            r = model.parent[r]
    keep[model.root] = True
    rows = [int(r) for r in model.order if keep[r]]
    position = {r: j for j, r in enumerate(rows)}
    names, parent, offsets = [], [], []
    for r in rows:
        names.append(_joint_name(model, r))
        p = int(model.parent[r])
        parent.append(-1 if p < 0 else position[p])
        offsets.append((0.0, 0.0, 0.0) if p < 0 else (model.a[p], 0.0, model.d[p]))
    offsets = np.array(offsets) * (REFLECTION if mirrored else 1.0)
    return Skeleton(tuple(rows), tuple(names), np.array(parent), offsets, mirrored)


def skeleton_motion(model: KinematicModel, skeleton: Skeleton, states: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame motion of the skeleton for states (T, n_q).

    Returns the root translation (T, 3) mm in the world, the local rotations (T, J, 3, 3)
    of every joint (the root's is its world rotation) and the world joint positions
    (T, J, 3) mm (the row-frame origins, for checks and plots).
    """
    kin = forward_kinematics(model, np.atleast_2d(np.asarray(states, dtype=float)))
    T_world = kin.T_world_shape[:, list(skeleton.rows)]
    R_world = T_world[..., :3, :3]
    positions = T_world[..., :3, 3]
    if skeleton.mirrored:
        R_world = R_world * REFLECTION[:, None] * REFLECTION[None, :]  # S R S
        positions = positions * REFLECTION
    local = R_world.copy()
    child = np.flatnonzero(skeleton.parent >= 0)
    local[:, child] = np.einsum("tjki,tjkl->tjil", R_world[:, skeleton.parent[child]],
                                R_world[:, child])
    return positions[:, 0].copy(), local, positions
