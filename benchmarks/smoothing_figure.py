"""The smoothing picture of docs/output.md: raw and One Euro-filtered estimates against truth.

Renders and tracks the still and moving ``whole-hand`` sequences of
``digiteyes bench smoothing`` (shorter: 40 and 100 frames) drawn as the independent flesh
hand (docs/appearance.md, where the tracker's noise is largest), filters them with the default
:class:`~digiteyes.filters.OneEuroOptions`, and plots the index fingertip's height and the
index MCP flexion over time. Usage:
``python benchmarks/smoothing_figure.py docs/images/smoothing.png``.
"""

from __future__ import annotations

import sys

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from digiteyes.benchmarks.smoothing import keypoint_tracks, tracked_pair
from digiteyes.benchmarks.tracker import SEED
from digiteyes.filters import one_euro_filter
from digiteyes.kinematics.joint_angles import joint_angles_deg
from digiteyes.kinematics.keypoints import keypoint_names


def main(out: str) -> None:
    pair = tracked_pair(SEED, 40, 100, progress=True, appearance="flesh")
    model, fps = pair["model"], pair["fps"]
    tip = keypoint_names(model).index("index.tip")
    fig = Figure(figsize=(11, 4.2))
    FigureCanvasAgg(fig)
    for col, name in enumerate(("still", "moving")):
        raw = pair[name]
        smooth = one_euro_filter(model, raw, fps)
        t = np.arange(len(raw)) / fps
        truth_kp = pair[f"{name}_truth"]
        names, raw_deg = joint_angles_deg(model, raw)
        _, smooth_deg = joint_angles_deg(model, smooth)
        true_states = pair["moving_truth_states"]
        if name == "still":
            true_states = np.repeat(true_states[:1], len(raw), axis=0)
        _, true_deg = joint_angles_deg(model, true_states)
        j = names.index("index_mcp_flexion")
        series = (
            ("index fingertip height (mm)", truth_kp[:, tip, 2],
             keypoint_tracks(model, raw)[:, tip, 2], keypoint_tracks(model, smooth)[:, tip, 2]),
            ("index MCP flexion (deg)", true_deg[:, j], raw_deg[:, j], smooth_deg[:, j]))
        for row, (label, truth, r, s) in enumerate(series):
            ax = fig.add_subplot(2, 2, 1 + col + 2 * row)
            ax.plot(t, truth, "k--", linewidth=1.0, label="truth")
            ax.plot(t, r, color="tab:red", linewidth=0.9, label="tracker")
            ax.plot(t, s, color="tab:blue", linewidth=1.4, label="One Euro (defaults)")
            ax.set_ylabel(label, fontsize=8)
            ax.tick_params(labelsize=7)
            if row == 0:
                ax.set_title(f"{name} hand", fontsize=9)
            else:
                ax.set_xlabel("time (s)", fontsize=8)
            if row == 0 and col == 0:
                ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.1, top=0.93, hspace=0.25, wspace=0.2)
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "smoothing.png")
