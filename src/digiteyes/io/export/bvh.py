"""BVH export: the model's skeleton with per-frame joint rotations (Biovision hierarchy).

The skeleton is :func:`~digiteyes.io.export.skeleton.build_skeleton`'s: one JOINT per
kinematic frame, OFFSETs in millimetres in the parent joint's frame. The ROOT has six
channels (``Xposition Yposition Zposition Xrotation Yrotation Zrotation``: world
translation, mm, and world rotation), every other joint three (``Xrotation Yrotation
Zrotation``). The angles are degrees of the intrinsic X-Y-Z decomposition
``R = Rot_x(x) Rot_y(y) Rot_z(z)`` of the joint's local rotation; for DH joints
(``Rot_x(alpha) Rot_z(theta)``) this order has y = 0 and no gimbal lock. Leaf joints end
in an ``End Site`` at zero offset. World axes are the model's (z up on the tabletop
scenarios); importers that expect y up may need a -90 degree turn about x.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from digiteyes.errors import DatasetError
from digiteyes.io.export.skeleton import Skeleton, build_skeleton, skeleton_motion
from digiteyes.kinematics import KinematicModel

EULER_ORDER = "XYZ"
"""Intrinsic rotation order of the channels (scipy's upper-case convention)."""


def _hierarchy(skeleton: Skeleton) -> list[str]:
    lines = ["HIERARCHY"]

    def joint(j: int, depth: int) -> None:
        pad = "  " * depth
        keyword = "ROOT" if skeleton.parent[j] < 0 else "JOINT"
        lines.append(f"{pad}{keyword} {skeleton.names[j]}")
        lines.append(f"{pad}{{")
        x, y, z = skeleton.offsets_mm[j]
        lines.append(f"{pad}  OFFSET {x:.9g} {y:.9g} {z:.9g}")
        rotation = " ".join(f"{axis}rotation" for axis in EULER_ORDER)
        if skeleton.parent[j] < 0:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rotation}")
        else:
            lines.append(f"{pad}  CHANNELS 3 {rotation}")
        children = skeleton.children(j)
        for c in children:
            joint(c, depth + 1)
        if not children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint(0, 0)
    return lines


def channel_order(skeleton: Skeleton) -> list[int]:
    """Joints in the order their channels appear in a MOTION line (depth-first)."""
    order: list[int] = []
    stack = [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(skeleton.children(j)))
    return order


def write_bvh(path: str | Path, model: KinematicModel, states: np.ndarray, fps: float,
              mirrored: bool = False) -> Path:
    """Write states (T, n_q) sampled at ``fps`` as a BVH file (a left hand's, reflected
    back from the mirror image, with ``mirrored``); return its path."""
    skeleton = build_skeleton(model, mirrored)
    root, local, _ = skeleton_motion(model, skeleton, states)
    order = channel_order(skeleton)
    n_frames = len(root)
    euler = Rotation.from_matrix(local[:, order].reshape(-1, 3, 3)).as_euler(
        EULER_ORDER, degrees=True).reshape(n_frames, len(order) * 3)
    lines = _hierarchy(skeleton)
    lines += ["MOTION", f"Frames: {n_frames}", f"Frame Time: {1.0 / fps:.9g}"]
    for t in range(n_frames):
        values = np.concatenate([root[t], euler[t]])
        lines.append(" ".join(f"{v:.12g}" for v in values))
    path = Path(path)
    try:
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write BVH ({exc.strerror or exc})") from None
    return path
