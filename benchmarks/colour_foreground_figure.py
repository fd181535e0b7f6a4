"""Figure of docs/accuracy.md ("Over a textured backdrop"): what the silhouette rule's colour
model sees. Left: the flesh desk render over clutter with the index finger fully curled while
the state holds it straight; the colour model (learned on the straight frame) tints the hand's
pixels green, the model's silhouette at the state is outlined (magenta) and its index
finger (yellow), which the rule flags. Right, with ``../shared/data`` present: a frame of
the real video with the model learned on its first frame, at the keypoint tracker's state.

Run: ``python benchmarks/colour_foreground_figure.py [--data ../shared/data]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from footage_runs import keypoint_states

from digiteyes.camera import Rig
from digiteyes.camera.default import default_camera
from digiteyes.features.colour_foreground import fit_colour_foreground
from digiteyes.features.foreground import MARGIN_PX, model_labels
from digiteyes.io import VideoReader
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.anatomy import with_digits
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "colour-foreground.png"
VIDEO = Path("real_video") / "human_hand_video.mp4"
REAL_FRAME = 108
HEIGHT = 360


def panel(rgb: np.ndarray, mask: np.ndarray, labels: np.ndarray,
          finger: np.ndarray | None = None) -> np.ndarray:
    """``rgb`` with the mask tinted green, the model's outline magenta and ``finger``'s
    outline yellow, as BGR for OpenCV, scaled to :data:`HEIGHT` rows."""
    out = rgb.copy()
    out[mask] = (0.5 * out[mask] + (0, 70, 0)).astype(np.uint8)
    for region, colour in ((labels >= 0, (255, 0, 255)), (finger, (255, 255, 0))):
        if region is not None:
            out[cv2.Canny(region.astype(np.uint8) * 255, 50, 150) > 0] = colour
    scale = HEIGHT / out.shape[0]
    return cv2.resize(out, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)[..., ::-1]


def render_panel() -> np.ndarray:
    scenario = build_scenario("desk-1cam", seed=0, n_frames=2)
    model, rig = scenario.model, Rig(scenario.rig.cameras[:1])
    q = np.array(scenario.states[0])
    curled = with_digits(model, q, ["index"], extended=False)
    options = RenderOptions(appearance="flesh", noise_sigma=2.0, color=True,
                            background="clutter", background_seed=3)
    straight, bent = (render_views(model, s, rig, options, rng=i)[0].image
                      for i, s in enumerate((q, curled)))
    labels = model_labels(model, forward_kinematics(model, q), rig.cameras[0])
    colour = fit_colour_foreground(straight, labels, MARGIN_PX)
    index = np.isin(labels, [k for k, link in enumerate(model.links)
                             if link.name.startswith("index")])
    return panel(bent, colour.mask(bent), labels, index)


def real_panel(data: Path) -> np.ndarray | None:
    video = data / VIDEO
    if not video.is_file():
        return None
    log = keypoint_states(video, REAL_FRAME + 1)
    model = load_model("hand")
    frames = []
    with VideoReader(str(video)) as reader:
        for i, frame in enumerate(reader):
            if i in (0, REAL_FRAME):
                frames.append(frame)
            if i >= REAL_FRAME:
                break
    camera = default_camera(frames[0].shape[1], frames[0].shape[0])
    first = model_labels(model, forward_kinematics(model, log.states[0]), camera)
    colour = fit_colour_foreground(frames[0], first, MARGIN_PX)
    labels = model_labels(model, forward_kinematics(model, log.states[REAL_FRAME]), camera)
    return panel(frames[1], colour.mask(frames[1]), labels)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path,
                        default=Path(__file__).resolve().parents[2] / "shared" / "data")
    args = parser.parse_args()
    panels = [render_panel()]
    real = real_panel(args.data)
    if real is not None:
        panels.append(real)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(OUT), np.hstack(panels))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
