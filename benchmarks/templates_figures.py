"""Figures of docs/templates.md: each step of the layered template tracker on one frame
of the ``two-finger-occlusion`` scenario (templates, windows and visibility order,
segmentation, residual image). Writes PNG files into docs/images/.

Run: ``PYTHONPATH=src python benchmarks/templates_figures.py``
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers.layered_templates import LayeredTemplateTracker
from digiteyes.viz.templates import PALETTE, draw_templates, residual_image

OUT = Path(__file__).resolve().parent.parent / "docs" / "images"
FRAME = 30


def grey(image: np.ndarray, scale: float) -> np.ndarray:
    """Signed image to uint8 around mid-grey."""
    return np.clip(128 + image * scale, 0, 255).astype(np.uint8)


def main() -> None:
    scenario = build_scenario("two-finger-occlusion")
    model, rig = scenario.model, scenario.rig
    tracker = LayeredTemplateTracker(model, rig)
    tracker.reset(scenario.initial_state)
    for i in range(FRAME + 1):
        image = render_views(model, scenario.states[i], rig, RenderOptions(), rng=i)[0].image
        result = tracker.step([image])
    d = result.details
    ev, order = d.evaluations[0], d.orders[0]
    names = [p.name for p in tracker.parts]
    OUT.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(OUT / "templates_frame.png"), image)
    filtered = tracker.options.templates.log.apply(image)
    cv2.imwrite(str(OUT / "templates_log.png"), grey(filtered, 1.5))
    overlay = draw_templates(image, ev.windows, order, None, names, 0.0)
    cv2.imwrite(str(OUT / "templates_windows.png"), cv2.cvtColor(overlay, cv2.COLOR_RGB2BGR))
    seg = d.segmentations[0]
    colour = np.zeros((*seg.shape, 3), np.uint8)
    colour[seg >= 0] = PALETTE[seg[seg >= 0] % len(PALETTE)]
    cv2.imwrite(str(OUT / "templates_segmentation.png"), cv2.cvtColor(colour, cv2.COLOR_RGB2BGR))
    res = residual_image(ev, rig[0].width, rig[0].height)
    cv2.imwrite(str(OUT / "templates_residual.png"), grey(res, 3.0))
    # the templates themselves, each part's (a, b) grid as an image, side by side
    t = d.templates[0]
    tiles = []
    for part, sl in zip(t.parts, t.slices, strict=True):
        ab = t.ab[sl]
        a_vals, b_vals = np.unique(np.round(ab[:, 0], 6)), np.unique(np.round(ab[:, 1], 6))
        tile = np.full((len(b_vals), len(a_vals)), 128, np.uint8)
        ia = np.searchsorted(a_vals, np.round(ab[:, 0], 6))
        ib = np.searchsorted(b_vals, np.round(ab[:, 1], 6))
        tile[ib, ia] = np.where(t.weights[sl] > 0, grey(t.values[sl], 1.5), 0)
        tile = cv2.resize(tile, None, fx=4, fy=4, interpolation=cv2.INTER_NEAREST)
        canvas = np.full((max(tile.shape[0], 40) + 14, tile.shape[1] + 6), 255, np.uint8)
        canvas[14:14 + tile.shape[0], 3:3 + tile.shape[1]] = tile
        cv2.putText(canvas, part.name.split(".")[-1][:6], (2, 11), cv2.FONT_HERSHEY_SIMPLEX,
                    0.3, 0, 1)
        tiles.append(canvas)
    height = max(c.shape[0] for c in tiles)
    row = np.concatenate([np.pad(c, ((0, height - c.shape[0]), (0, 0)), constant_values=255)
                          for c in tiles], axis=1)
    cv2.imwrite(str(OUT / "templates_templates.png"), row)
    print("order (front first):", [names[k] for k in order.order])
    print("relations:", [(names[r.front], names[r.back], r.rule) for r in order.relations])


if __name__ == "__main__":
    main()
