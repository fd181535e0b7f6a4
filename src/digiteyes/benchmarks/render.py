"""Renderer benchmark: synthetic frames per second of the full hand at 640x480.

Measured with :func:`~digiteyes.render.render_views` on the Appendix A hand in a relaxed
pose (fingers spread and slightly bent, thumb out, palm turned 30 degrees), filling about
a third of the image, one frame = all images of the rig plus their ground truth:

* ``render_fps_gray_640x480``: one grey-level camera, black cloth backdrop (defaults);
* ``render_fps_color_clutter_640x480``: one colour camera, clutter backdrop;
* ``render_fps_gray_rig2_640x480``: a two-camera rig (thesis Sec. 4.3.3 style), grey;
* ``render_fps_color_clutter_ss2_noise_640x480``: colour clutter with 2x2 supersampling,
  a 0.8 px blur and noise of 3 grey levels (the most expensive options together);
* ``render_fps_flesh_*``: the same hand drawn with the independent flesh appearance
  (:mod:`digiteyes.render.flesh`, sphere traced): grey; colour; colour with cast
  shadows; the two-camera rig. ``flesh_over_model`` is the grey flesh rate over the grey
  model rate of the same run.

``silhouette_mismatch_ms_640x480`` times
:func:`digiteyes.features.silhouette.silhouette_mismatch` on the model's label image and
the flesh image's foreground (milliseconds per call, best of the repeats).

OpenCV is held to one thread, and numba code is not parallel, so the figures are for one
core. Each figure is the best of several repeats (the least disturbed by other processes);
the table also shows the median. The first call (numba compilation) is not timed. Run it
with ``digiteyes bench render [--json FILE] [--quick]``.
"""

from __future__ import annotations

import statistics

import numpy as np

from digiteyes.benchmarks._machine import emit, kernel_threads, machine_info, seconds_per_call
from digiteyes.camera import Camera
from digiteyes.features.silhouette import silhouette_mismatch
from digiteyes.kinematics import KinematicModel, load_model
from digiteyes.synth import RenderOptions, render_views

WIDTH, HEIGHT = 640, 480


def relaxed_hand_state(model: KinematicModel) -> np.ndarray:
    """A natural open-hand state of the Appendix A hand, palm turned 30 degrees about y."""
    q = model.neutral()
    angle = np.radians(30.0)
    q[0:4] = (np.cos(angle / 2), 0.0, np.sin(angle / 2), 0.0)
    degrees = {"index.abd": -8, "middle.abd": 0, "ring.abd": 8, "little.abd": 16,
               "thumb.cmc_abd": 45, "thumb.cmc_flex": 15, "thumb.mp": 10, "thumb.ip": 15}
    for finger in ("index", "middle", "ring", "little"):
        degrees |= {f"{finger}.mcp": 15, f"{finger}.pip": 20, f"{finger}.dip": 10}
    for name, value in degrees.items():
        q[model.state_index(name)] = np.radians(value)
    return q


def _cameras() -> list[Camera]:
    target = (0.0, 40.0, 0.0)
    return [Camera.look_at("left", (-150.0, 40.0, 520.0), target, up=(0, 1, 0)),
            Camera.look_at("right", (150.0, 40.0, 520.0), target, up=(0, 1, 0))]


def _frames_per_second(fn, repeat: int, min_time: float) -> tuple[float, float]:
    """(best, median) calls per second of ``fn`` over ``repeat`` runs of >= min_time s."""
    rates = [1.0 / t for t in seconds_per_call(fn, repeat, min_time)]
    return max(rates), statistics.median(rates)


CASES = {
    "render_fps_gray_640x480": ("grey, black cloth, 1 camera", 1, RenderOptions()),
    "render_fps_color_clutter_640x480": (
        "colour, clutter, 1 camera", 1, RenderOptions(color=True, background="clutter")),
    "render_fps_gray_rig2_640x480": ("grey, black cloth, 2-camera rig", 2, RenderOptions()),
    "render_fps_color_clutter_ss2_noise_640x480": (
        "colour, clutter, 2x2 AA, blur, noise, 1 camera", 1,
        RenderOptions(color=True, background="clutter", supersample=2, blur_sigma=0.8,
                      noise_sigma=3.0)),
    "render_fps_flesh_gray_640x480": ("flesh, grey, black cloth, 1 camera", 1,
                                      RenderOptions(appearance="flesh")),
    "render_fps_flesh_color_640x480": ("flesh, colour, black cloth, 1 camera", 1,
                                       RenderOptions(appearance="flesh", color=True)),
    "render_fps_flesh_color_shadows_640x480": (
        "flesh, colour, cast shadows, 1 camera", 1,
        RenderOptions(appearance="flesh", color=True, shadows=True)),
    "render_fps_flesh_gray_rig2_640x480": ("flesh, grey, 2-camera rig", 2,
                                           RenderOptions(appearance="flesh")),
}


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Time the renderer, print a table, optionally write JSON.

    Returns a dict with one frames-per-second figure per entry of :data:`CASES` (best of
    the repeats), ``median`` (the same as medians), ``repeats``, ``model_pixels`` (pixels
    covered by the hand in the one-camera view) and ``machine``.
    """
    repeat, min_time = (3, 0.1) if quick else (7, 0.5)
    model = load_model("hand")
    q = relaxed_hand_state(model)
    cameras = _cameras()
    with kernel_threads(opencv=1, numba_kernels=1):
        rates = {}
        for key, (_, n_cameras, options) in CASES.items():
            rng = np.random.default_rng(0)
            rates[key] = _frames_per_second(
                lambda o=options, n=n_cameras, r=rng: render_views(model, q, cameras[:n], o, r),
                repeat, min_time)
        model_view = render_views(model, q, cameras[:1])[0]
        flesh_view = render_views(model, q, cameras[:1], RenderOptions(appearance="flesh"))[0]
        foreground = flesh_view.labels >= 0
        silhouette_ms = 1e3 * min(seconds_per_call(
            lambda: silhouette_mismatch(foreground, model_view.labels, len(model.links)),
            repeat, min_time))
    covered = int((model_view.labels >= 0).sum())
    result = {
        "benchmark": "render",
        "model": model.name,
        "image": f"{WIDTH}x{HEIGHT}",
        "model_pixels": covered,
        "statistic": "best",
        "repeats": repeat,
        **{key: best for key, (best, _) in rates.items()},
        "median": {key: med for key, (_, med) in rates.items()},
        "flesh_over_model": rates["render_fps_flesh_gray_640x480"][0]
        / rates["render_fps_gray_640x480"][0],
        "flesh_pixels": int(foreground.sum()),
        "silhouette_mismatch_ms_640x480": silhouette_ms,
        "machine": machine_info(),
    }
    return emit(result, format_table(result), json_path)


def format_table(result: dict) -> str:
    """The plain-text report of :func:`run`'s result."""
    m = result["machine"]
    lines = [
        f"render benchmark: model {result['model']}, {result['image']} images, the hand "
        f"covers {result['model_pixels']} pixels per view; one core",
        f"machine: {m['cpu']}, {m['cores']} cores, {m['platform']}",
        f"         Python {m['python']}, numpy {m['numpy']}, numba {m['numba']}, "
        f"OpenCV {m['opencv']}",
        f"figures: best of {result['repeats']} repeats (median in brackets)",
        "",
        f"{'case':<48} {'frames/s':>18}",
    ]
    for key, (label, _, _) in CASES.items():
        lines.append(f"{label:<48} {result[key]:>8.1f} ({result['median'][key]:>6.1f})")
    if "flesh_over_model" in result:
        lines += ["", f"flesh / model (grey, 1 camera): {result['flesh_over_model']:.2f}; "
                  f"flesh covers {result['flesh_pixels']} pixels",
                  f"silhouette_mismatch at 640x480: "
                  f"{result['silhouette_mismatch_ms_640x480']:.3f} ms"]
    return "\n".join(lines)
