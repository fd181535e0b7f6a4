"""Figures of docs/templates.md: each step of the layered template tracker on one frame
(templates, windows and visibility order, segmentation, residual image), written as PNG
files into docs/images/:

* ``templates_*.png``: frame :data:`FRAME` of the ``two-finger-occlusion`` scenario;
* ``templates_real_*.png`` (with ``../shared/data`` present): frame :data:`REAL_FRAME` of
  the real video (grey wall, 1280x720, the default camera of ``track``). Its state comes
  from the keypoint tracker (MediaPipe and the model fit), which ``track --init auto``
  runs first; the template tracker starts from the keypoint tracker's estimate of the
  frame before (templates acquired there, one step on that frame, as ``track --tracker
  templates`` starts; the model's size, ``start_size`` off, as on footage) and the
  pictures are its step on the next frame.

Run: ``python benchmarks/templates_figures.py [--data ../shared/data]``
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from footage_runs import keypoint_states
from real_video import VIDEO

from digiteyes.camera import Rig
from digiteyes.camera.default import default_camera
from digiteyes.features.slices import prepare_image
from digiteyes.io import VideoReader
from digiteyes.kinematics import load_model
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import TrackResult
from digiteyes.trackers.layered_templates import LayeredTemplateOptions, LayeredTemplateTracker
from digiteyes.viz.overlay import to_rgb
from digiteyes.viz.templates import PALETTE, draw_templates, residual_image

OUT = Path(__file__).resolve().parent.parent / "docs" / "images"
FRAME = 30
REAL_FRAME = 108
"""The real video's frame drawn: the middle finger curls down onto the thumb in front of
the palm and the other fingers (the pinch of frames 100-120)."""
REAL_MARGIN_PX = 40
"""Margin of the real pictures' crop around the template windows (px)."""
RESIDUAL_GREY = 100.0
"""Grey levels from mid-grey at which the residual picture draws the 99th percentile of
the residuals' magnitude (so that a real frame's small residuals show)."""


def grey(image: np.ndarray, scale: float) -> np.ndarray:
    """Signed image to uint8 around mid-grey."""
    return np.clip(128 + image * scale, 0, 255).astype(np.uint8)


def template_tiles(result: TrackResult) -> np.ndarray:
    """The templates of camera 0, each part's (a, b) grid as an image, side by side."""
    t = result.details.templates[0]
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
    return np.concatenate([np.pad(c, ((0, height - c.shape[0]), (0, 0)), constant_values=255)
                           for c in tiles], axis=1)


def write_figures(tracker: LayeredTemplateTracker, result: TrackResult, image: np.ndarray,
                  prefix: str, crop: tuple[slice, slice] | None = None) -> None:
    """The six pictures of one step (``result`` of ``tracker`` on ``image``, camera 0)
    as ``docs/images/{prefix}_{frame,log,windows,segmentation,residual,templates}.png``,
    the image-sized ones cut to ``crop`` (rows, columns) when given."""
    d = result.details
    ev, order = d.evaluations[0], d.orders[0]
    names = [p.name for p in tracker.parts]
    rows, cols = crop or (slice(None), slice(None))
    height, width = image.shape[:2]
    residual = residual_image(ev, width, height)
    seg = d.segmentations[0]
    colour = np.zeros((*seg.shape, 3), np.uint8)
    colour[seg >= 0] = PALETTE[seg[seg >= 0] % len(PALETTE)]
    pictures = {
        "frame": to_rgb(image)[..., ::-1],
        "log": grey(tracker.options.templates.log.apply(prepare_image(image)), 1.5),
        "windows": draw_templates(image, ev.windows, order, None, names, 0.0)[..., ::-1],
        "segmentation": colour[..., ::-1],
        "residual": grey(residual, RESIDUAL_GREY / max(np.percentile(np.abs(residual[
            residual != 0]), 99), 1e-9) if np.any(residual) else 1.0),
    }
    OUT.mkdir(parents=True, exist_ok=True)
    for name, picture in pictures.items():
        cv2.imwrite(str(OUT / f"{prefix}_{name}.png"), np.ascontiguousarray(picture[rows, cols]))
    cv2.imwrite(str(OUT / f"{prefix}_templates.png"), template_tiles(result))
    print(f"{prefix}: order (front first):", [names[k] for k in order.order])
    print(f"{prefix}: relations:",
          [(names[r.front], names[r.back], r.rule) for r in order.relations])


def synthetic_figures() -> None:
    """The pictures of frame :data:`FRAME` of ``two-finger-occlusion``."""
    scenario = build_scenario("two-finger-occlusion")
    model, rig = scenario.model, scenario.rig
    tracker = LayeredTemplateTracker(model, rig)
    tracker.reset(scenario.initial_state)
    for i in range(FRAME + 1):
        image = render_views(model, scenario.states[i], rig, RenderOptions(), rng=i)[0].image
        result = tracker.step([image])
    write_figures(tracker, result, image, "templates")


def real_figures(data: Path) -> bool:
    """The pictures of frame :data:`REAL_FRAME` of the real video (module docstring);
    False when the video is absent."""
    video = data / VIDEO
    if not video.is_file():
        return False
    log = keypoint_states(video, REAL_FRAME + 1)
    model = load_model("hand")
    with VideoReader(str(video)) as reader:
        frames = [frame for i, frame in zip(range(REAL_FRAME + 1), reader, strict=False)
                  if i >= REAL_FRAME - 1]
    camera = default_camera(frames[0].shape[1], frames[0].shape[0])
    tracker = LayeredTemplateTracker(model, Rig((camera,)),
                                     replace(LayeredTemplateOptions(), start_size=False))
    start = int(np.flatnonzero(log.frames == REAL_FRAME - 1)[0])
    tracker.reset(log.states[start])
    tracker.step([frames[0]])  # the templates acquired at the frame before
    result = tracker.step([frames[1]])
    box = result.details.evaluations[0].windows.bounds()
    low = np.maximum(np.floor(box[:, :2].min(axis=0)) - REAL_MARGIN_PX, 0).astype(int)
    high = np.ceil(box[:, 2:].max(axis=0)).astype(int) + REAL_MARGIN_PX
    write_figures(tracker, result, frames[1], "templates_real",
                  (slice(low[1], high[1]), slice(low[0], high[0])))
    gap = np.linalg.norm(result.state[4:7] - log.states[start + 1][4:7])
    print(f"templates_real: palm {gap:.1f} mm from the keypoint tracker's estimate, lost: "
          f"{result.lost} {result.loss_reason}")
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path,
                        default=Path(__file__).resolve().parents[2] / "shared" / "data")
    args = parser.parse_args()
    synthetic_figures()
    if not real_figures(args.data):
        print(f"no real video under {args.data}: the real-frame pictures are not drawn")


if __name__ == "__main__":
    main()
