"""Figure of docs/features.md ("Edge detection"): the first frame of the accuracy table's
webcam view (flesh hand, exact size) rendered over the mid-grey wall of ``digiteyes bench
render-variants``, measured at the true first state with the usual edge signs (a hand
brighter than its backdrop, thesis Sec. 4.3.1) and with the signs the feature tracker
learns on that frame (:func:`digiteyes.features.edge_signs.learn_side_signs`). The sides
that keep the other sign are outlined in yellow on the right.

Run: ``python benchmarks/edge_signs_figure.py``
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from digiteyes.benchmarks.accuracy import scenario_for
from digiteyes.benchmarks.render_variants import VARIANTS
from digiteyes.benchmarks.tracker import render_sequence
from digiteyes.features import FeatureOptions, measure_features
from digiteyes.features.edge_signs import learn_side_signs
from digiteyes.features.foreground import model_labels
from digiteyes.features.measure import usual_side_signs
from digiteyes.kinematics import forward_kinematics
from digiteyes.viz.overlay import draw_features

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "edge-signs.png"
VARIANT = "grey wall"
SETUP = "webcam"
SCALE = 2
PAD_PX = 15
"""Margin around the model's silhouette in the crop, px of the frame."""


def main() -> None:
    scenario = scenario_for(SETUP, "exact", 1)
    sequence = render_sequence(scenario, appearance="flesh", render=VARIANTS[VARIANT])
    image, camera = sequence.images[0][0], sequence.rig.cameras[0]
    kin = forward_kinematics(scenario.model, scenario.initial_state)
    learned = learn_side_signs(image, camera, scenario.model, kin)
    usual_signs = usual_side_signs(len(learned))
    panels = []
    for name, signs in (("usual signs", usual_signs), ("learned signs", learned)):
        meas = measure_features(image, camera, scenario.model, kin, FeatureOptions(),
                                side_signs=signs)
        drawn = draw_features(image, meas, scale=SCALE, show_slices=False)
        for link, side in zip(*np.nonzero(signs != usual_signs), strict=True):
            points = meas.edge_points[link, side]
            points = points[np.isfinite(points).all(axis=1)] * SCALE
            for x, y in points:
                cv2.circle(drawn, (int(x), int(y)), 5, (255, 220, 0), 1, cv2.LINE_AA)
        valid = int(meas.link_valid.sum())
        panels.append((drawn, f"{name}: {valid} of {len(meas.link_valid)} links measured"))
    ys, xs = np.nonzero(model_labels(scenario.model, kin, camera) >= 0)
    crop = (slice(max(ys.min() - PAD_PX, 0) * SCALE, (ys.max() + PAD_PX) * SCALE),
            slice(max(xs.min() - PAD_PX, 0) * SCALE, (xs.max() + PAD_PX) * SCALE))
    tiles = []
    for drawn, label in panels:
        tile = np.ascontiguousarray(drawn[crop])
        cv2.putText(tile, label, (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.9, (255, 255, 255), 2,
                    cv2.LINE_AA)
        tiles.append(tile)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(OUT), cv2.cvtColor(np.hstack(tiles), cv2.COLOR_RGB2BGR))
    print(f"wrote {OUT}; {int((learned != usual_signs).sum())} sides learned the other sign")


if __name__ == "__main__":
    main()
