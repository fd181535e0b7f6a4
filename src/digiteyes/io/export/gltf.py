"""glTF 2.0 export: an animated, skinned skeleton in one binary ``.glb`` file.

One node per joint of :func:`~digiteyes.io.export.skeleton.build_skeleton` (translation =
the constant offset, rotation = the local rotation, children = the child joints), one
animation with a rotation channel per joint and a translation channel for the root, a
skin binding every joint, and a mesh of thin boxes along the bones (each box weighted
fully to the joint it hangs from) posed at the first frame (the bind pose). glTF's units
are metres: millimetres are divided by 1000. glTF's world has +y up: the model's world
(z up on the tabletop) is turned by :data:`R_GLTF_WORLD` (-90 degrees about x), so the hand
stands as in the sequence. Quaternions are glTF's (x, y, z, w).
Written by hand after the specification (Khronos glTF 2.0, sections 3.6-3.11: buffers,
accessors, skins, animations, GLB container); read back with pygltflib in the tests.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from digiteyes.errors import DatasetError
from digiteyes.io.export.skeleton import Skeleton, build_skeleton, skeleton_motion
from digiteyes.kinematics import KinematicModel

METRES_PER_MM = 1e-3
R_GLTF_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rotation from the model's world (z up) to glTF's (y up): (x, y, z) -> (x, z, -y)."""
BONE_HALF_WIDTH_MM = 3.0
"""Half the side of the square boxes drawn along the bones, mm."""

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class _Buffer:
    """The binary chunk: appends arrays 4-byte aligned, one buffer view and accessor each."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, kind: str, component: int, target: int | None = None,
            bounds: bool = False) -> int:
        raw = np.ascontiguousarray(array).tobytes()
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target is not None:
            view["target"] = target
        self.data += raw + b"\0" * (-len(raw) % 4)
        self.views.append(view)
        accessor = {"bufferView": len(self.views) - 1, "componentType": component,
                    "count": len(array), "type": kind}
        if bounds:
            flat = np.asarray(array, dtype=float).reshape(len(array), -1)
            accessor["min"] = flat.min(axis=0).tolist()
            accessor["max"] = flat.max(axis=0).tolist()
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _bone_boxes(skeleton: Skeleton, bind_positions: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (V, 3) mm, joint indices (V,) and triangles (F, 3) of a box per bone."""
    corners = np.array([[0, -1, -1], [0, 1, -1], [0, 1, 1], [0, -1, 1],
                        [1, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    vertices, joints, triangles = [], [], []
    for j in range(1, len(skeleton)):
        p = int(skeleton.parent[j])
        start, end = bind_positions[p], bind_positions[j]
        axis = end - start
        length = float(np.linalg.norm(axis))
        if length < 1e-9:
            continue
        x = axis / length
        helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        y = np.cross(helper, x)
        y /= np.linalg.norm(y)
        z = np.cross(x, y)
        box = (start + corners[:, :1] * axis + BONE_HALF_WIDTH_MM
               * (corners[:, 1:2] * y + corners[:, 2:3] * z))
        triangles.append(faces + 8 * len(vertices))
        vertices.append(box)
        joints.append(np.full(8, p))
    return np.concatenate(vertices), np.concatenate(joints), np.concatenate(triangles)


def write_gltf(path: str | Path, model: KinematicModel, states: np.ndarray, fps: float,
               mirrored: bool = False) -> Path:
    """Write states (T, n_q) sampled at ``fps`` as an animated skinned skeleton (``.glb``;
    a left hand's, reflected back from the mirror image, with ``mirrored``); return its
    path."""
    skeleton = build_skeleton(model, mirrored)
    root, local, positions = skeleton_motion(model, skeleton, states)
    root = root @ R_GLTF_WORLD.T
    positions = positions @ R_GLTF_WORLD.T
    local[:, 0] = R_GLTF_WORLD @ local[:, 0]
    n_frames, n_joints = local.shape[:2]
    quats = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_quat().reshape(n_frames, n_joints, 4)
    # consecutive quaternions on the same hemisphere, so that interpolation takes the short way
    for t in range(1, n_frames):
        flip = (quats[t] * quats[t - 1]).sum(axis=1) < 0
        quats[t, flip] *= -1.0
    buffer = _Buffer()
    nodes = []
    for j in range(n_joints):
        translation = root[0] if j == 0 else skeleton.offsets_mm[j]
        node = {"name": skeleton.names[j],
                "translation": (np.asarray(translation) * METRES_PER_MM).tolist(),
                "rotation": quats[0, j].tolist()}
        children = skeleton.children(j)
        if children:
            node["children"] = children
        nodes.append(node)

    times = buffer.add((np.arange(n_frames) / fps).astype(np.float32), "SCALAR", FLOAT,
                       bounds=True)
    samplers, channels = [], []
    for j in range(n_joints):
        output = buffer.add(quats[:, j].astype(np.float32), "VEC4", FLOAT)
        samplers.append({"input": times, "output": output, "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
    output = buffer.add((root * METRES_PER_MM).astype(np.float32), "VEC3", FLOAT)
    samplers.append({"input": times, "output": output, "interpolation": "LINEAR"})
    channels.append({"sampler": len(samplers) - 1, "target": {"node": 0, "path": "translation"}})

    kin_bind = np.tile(np.eye(4), (n_joints, 1, 1))
    R_bind = np.empty((n_joints, 3, 3))
    for j in range(n_joints):
        p = int(skeleton.parent[j])
        R_bind[j] = local[0, j] if p < 0 else R_bind[p] @ local[0, j]
    kin_bind[:, :3, :3] = R_bind
    kin_bind[:, :3, 3] = positions[0] * METRES_PER_MM
    inverse_bind = np.linalg.inv(kin_bind).transpose(0, 2, 1)  # glTF matrices: column-major
    vertices, joint_of_vertex, triangles = _bone_boxes(skeleton, positions[0])
    mesh_attributes = {
        "POSITION": buffer.add((vertices * METRES_PER_MM).astype(np.float32), "VEC3", FLOAT,
                               ARRAY_BUFFER, bounds=True),
        "JOINTS_0": buffer.add(np.stack([joint_of_vertex] + [np.zeros_like(joint_of_vertex)] * 3,
                                        axis=1).astype(np.uint16), "VEC4", UNSIGNED_SHORT,
                               ARRAY_BUFFER),
        "WEIGHTS_0": buffer.add(np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32),
                                        (len(vertices), 1)), "VEC4", FLOAT, ARRAY_BUFFER),
    }
    indices = buffer.add(triangles.reshape(-1).astype(np.uint32), "SCALAR", UNSIGNED_INT,
                         ELEMENT_ARRAY_BUFFER)
    skin_matrices = buffer.add(inverse_bind.reshape(n_joints, 16).astype(np.float32), "MAT4",
                               FLOAT)
    nodes.append({"name": f"{model.name}_bones", "mesh": 0, "skin": 0})
    document = {
        "asset": {"version": "2.0", "generator": "digiteyes"},
        "scene": 0,
        "scenes": [{"name": model.name, "nodes": [0, n_joints]}],
        "nodes": nodes,
        "meshes": [{"name": f"{model.name}_bones",
                    "primitives": [{"attributes": mesh_attributes, "indices": indices}]}],
        "skins": [{"name": model.name, "joints": list(range(n_joints)), "skeleton": 0,
                   "inverseBindMatrices": skin_matrices}],
        "animations": [{"name": "track", "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": len(buffer.data)}],
        "bufferViews": buffer.views,
        "accessors": buffer.accessors,
    }
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    body = bytes(buffer.data)
    total = 12 + 8 + len(text) + 8 + len(body)
    blob = (struct.pack("<III", 0x46546C67, 2, total)
            + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(body), 0x004E4942) + body)
    path = Path(path)
    try:
        path.write_bytes(blob)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write glTF ({exc.strerror or exc})") from None
    return path
