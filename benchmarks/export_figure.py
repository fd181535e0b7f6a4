"""The picture of docs/output.md: a BVH export read back by the ``bvh`` package and drawn.

Exports six frames of the ``whole-hand`` truth as BVH, parses the file with the
independent ``bvh`` package, rebuilds every joint's world position by composing the
OFFSETs and X-Y-Z rotation channels (as an importer does), and draws the skeletons with
matplotlib. Usage: ``python benchmarks/export_figure.py docs/images/export-bvh.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from bvh import Bvh
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from digiteyes.io.export import export_track
from digiteyes.synth.scenarios import build_scenario


def bvh_joint_positions(mocap: Bvh, t: int) -> dict[str, tuple[np.ndarray, str | None]]:
    """World position (mm) and parent name of every joint at frame ``t``."""
    world: dict[str, tuple[np.ndarray, np.ndarray, str | None]] = {}
    for name in mocap.get_joints_names():
        channels = mocap.joint_channels(name)
        values = np.array(mocap.frame_joint_channels(t, name, channels), dtype=float)
        R = np.eye(3)
        for channel, value in zip(channels, values, strict=True):
            if channel.endswith("rotation"):
                R = R @ Rotation.from_euler(channel[0].lower(), value, degrees=True).as_matrix()
        offset = np.array(mocap.joint_offset(name), dtype=float)
        parent = mocap.joint_parent(name)
        if parent is None:
            world[name] = (R, values[:3] + offset, None)
        else:
            R_p, p_p, _ = world[parent.name]
            world[name] = (R_p @ R, p_p + R_p @ offset, parent.name)
    return {name: (p, parent) for name, (_, p, parent) in world.items()}


def main(out: str) -> None:
    scenario = build_scenario("whole-hand")
    frames = np.arange(0, 200, 40)
    with tempfile.TemporaryDirectory() as tmp:
        path = export_track(scenario.model, frames, scenario.states[frames],
                            np.zeros(len(frames)), 0.25, tmp, "bvh")
        mocap = Bvh(path.read_text())
    fig = Figure(figsize=(12, 3.0))
    FigureCanvasAgg(fig)
    for k, frame in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), k + 1, projection="3d")
        joints = bvh_joint_positions(mocap, k)
        for point, parent in joints.values():
            if parent is not None:
                segment = np.stack([joints[parent][0], point])
                ax.plot(*segment.T, color="tab:blue", linewidth=1.5)
        points = np.array([p for p, _ in joints.values()])
        ax.scatter(*points.T, s=4, color="tab:red")
        centre = points.mean(axis=0)
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            setter(c - 70, c + 70)
        ax.view_init(elev=35, azim=-60)
        ax.set_title(f"frame {frame}", fontsize=9)
        ax.set_xticklabels([])
        ax.set_yticklabels([])
        ax.set_zticklabels([])
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=0.88, wspace=0.0)
    fig.suptitle("whole-hand truth exported as BVH, read back with the bvh package", fontsize=10)
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "export-bvh.png")
    print(Path(sys.argv[1] if len(sys.argv) > 1 else "export-bvh.png").resolve())
