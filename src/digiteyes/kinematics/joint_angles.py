"""Joint angles in degrees with anatomical names (a per-frame table of a state sequence).

The model files name their states by finger and joint (``index.mcp``, ``thumb.cmc_flex``)
with the signs of their DH frames (models/hand.dh header, docs/models.md). Users of joint
angles expect anatomical names and signs: flexion positive towards the palm, abduction
positive away from the hand's midline. :data:`ANATOMICAL_NAMES` maps the states of the
shipped ``hand`` model to such names and signs; states of other models keep their own name
(dots become underscores) and sign.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from digiteyes.errors import DatasetError
from digiteyes.kinematics.model import KinematicModel

ANATOMICAL_NAMES: dict[str, tuple[str, float]] = {
    # finger MCP abduction: the model turns every finger towards the little finger for a
    # positive angle; anatomically the index abducts towards the thumb, the middle finger
    # has radial (+, towards the thumb) and ulnar deviation, ring and little abduct
    # towards the little-finger side.
    "index.abd": ("index_mcp_abduction", -1.0),
    "index.mcp": ("index_mcp_flexion", 1.0),
    "index.pip": ("index_pip_flexion", 1.0),
    "index.dip": ("index_dip_flexion", 1.0),
    "middle.abd": ("middle_mcp_radial_deviation", -1.0),
    "middle.mcp": ("middle_mcp_flexion", 1.0),
    "middle.pip": ("middle_pip_flexion", 1.0),
    "middle.dip": ("middle_dip_flexion", 1.0),
    "ring.abd": ("ring_mcp_abduction", 1.0),
    "ring.mcp": ("ring_mcp_flexion", 1.0),
    "ring.pip": ("ring_pip_flexion", 1.0),
    "ring.dip": ("ring_dip_flexion", 1.0),
    "little.abd": ("little_mcp_abduction", 1.0),
    "little.mcp": ("little_mcp_flexion", 1.0),
    "little.pip": ("little_pip_flexion", 1.0),
    "little.dip": ("little_dip_flexion", 1.0),
    # thumb: q23 and q25 lift the thumb palmar-wards (palmar abduction); q24, q26, q27
    # turn it away from the fingers for positive angles (extension), so flexion is minus.
    "thumb.cmc_abd": ("thumb_cmc_abduction", 1.0),
    "thumb.cmc_flex": ("thumb_cmc_flexion", -1.0),
    "thumb.mp_abd": ("thumb_mcp_abduction", 1.0),
    "thumb.mp": ("thumb_mcp_flexion", -1.0),
    "thumb.ip": ("thumb_ip_flexion", -1.0),
}
"""Hand-model state name -> (anatomical name, sign): degrees = sign * degrees(state)."""


def joint_angle_columns(model: KinematicModel) -> tuple[tuple[int, ...], tuple[str, ...],
                                                         np.ndarray]:
    """State indices, anatomical names and signs of the model's joint angles (revolute
    states other than the base pose), in state order."""
    indices, names, signs = [], [], []
    for i, (name, kind) in enumerate(zip(model.state_names, model.state_kinds, strict=True)):
        if kind != "angle":
            continue
        anatomical, sign = ANATOMICAL_NAMES.get(name, (name.replace(".", "_"), 1.0))
        indices.append(i)
        names.append(anatomical)
        signs.append(sign)
    return tuple(indices), tuple(names), np.array(signs)


def joint_angles_deg(model: KinematicModel, states: np.ndarray) -> tuple[tuple[str, ...],
                                                                         np.ndarray]:
    """Anatomical names and joint angles in degrees, (T, J) for states (T, n_q) (or (J,)
    for one state)."""
    q = np.asarray(states, dtype=float)
    indices, names, signs = joint_angle_columns(model)
    return names, np.degrees(q[..., list(indices)]) * signs


def write_joint_angles_csv(path: str | Path, model: KinematicModel, frames: np.ndarray,
                           states: np.ndarray) -> Path:
    """Write ``frame,<anatomical names>`` in degrees, one row per state; return the path."""
    path = Path(path)
    names, degrees = joint_angles_deg(model, states)
    try:
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(["frame", *names])
            for frame, row in zip(frames, degrees, strict=True):
                writer.writerow([int(frame), *(f"{v:.6f}" for v in row)])
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write joint angles ({exc.strerror or exc})"
                           ) from None
    return path
