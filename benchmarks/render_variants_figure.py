"""Figure of docs/accuracy.md ("Renders the trackers were not developed on"): the first
frame of the accuracy table's desk view (camera 0, flesh hand, exact size) under each
render variant of ``digiteyes bench render-variants``, with the silhouette rule's
foreground at the true first state outlined (green), or "rule off" where the grey fit
refuses the frame.

Run: ``python benchmarks/render_variants_figure.py``
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from digiteyes.benchmarks.accuracy import scenario_for
from digiteyes.benchmarks.render_variants import VARIANTS
from digiteyes.benchmarks.tracker import render_sequence
from digiteyes.features.foreground import fit_foreground, model_labels
from digiteyes.kinematics import forward_kinematics

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "render-variants.png"
CROP = (slice(60, 420), slice(120, 520))
"""Rows and columns of the 640x480 frame around the hand."""


def panel(variant: str, render: dict) -> np.ndarray:
    """One variant's frame (BGR), the foreground outlined, labelled."""
    scenario = scenario_for("desk", "exact", 1)
    sequence = render_sequence(scenario, appearance="flesh", render=render)
    image, camera = sequence.images[0][0], sequence.rig.cameras[0]
    labels = model_labels(scenario.model, forward_kinematics(scenario.model,
                                                             scenario.initial_state), camera)
    fg = fit_foreground(image, labels)
    out = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if fg is not None:
        contours, _ = cv2.findContours(fg.mask(image).astype(np.uint8), cv2.RETR_EXTERNAL,
                                       cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(out, contours, -1, (0, 220, 0), 1)
    out = np.ascontiguousarray(out[CROP])
    note = "" if fg is not None else ", rule off"
    note = note or (f", blur {fg.blur_px:g} px" if fg.blur_px else "")
    cv2.putText(out, variant + note, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255),
                1, cv2.LINE_AA)
    return out


def main() -> None:
    panels = [panel(name, render) for name, render in VARIANTS.items()]
    rows = [np.hstack(panels[i:i + 3]) for i in range(0, len(panels), 3)]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(OUT), np.vstack(rows))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
