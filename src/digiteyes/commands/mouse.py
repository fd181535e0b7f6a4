"""``digiteyes mouse``: the 3D mouse of thesis Sec. 4.3.4 in a local web page."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from digiteyes.apps.mouse_server import DEFAULT_REACH_MM, DEFAULT_SPHERE, MouseServer, SceneConfig
from digiteyes.apps.mouse_stream import MouseFrame, open_mouse_stream, smoothed
from digiteyes.filters import OneEuroOptions
from digiteyes.io import StateLogWriter
from digiteyes.mouse_job import open_footage_mouse

HELP = """Serve the 3D mouse (thesis Fig. 4.9) on http://127.0.0.1:PORT/.

SOURCE is a dataset folder, a video file or a live camera index (e.g. 0). A video or
camera without --init starts by itself: the full hand is found, tracked (the keypoint
tracker with MediaPipe installed) and its own start pose is the table (--rig optional:
a default camera otherwise); with --init it is the thesis's set-up and needs --model and
--rig. Without SOURCE the `mouse` scenario is rendered and tracked on the fly. --replay
RUN plays back the states.csv (and overlay.mp4) that `digiteyes track` wrote in RUN. The
stream starts when the first page connects and the server stops when it ends, or on
Ctrl-C.
"""


@click.command(help=HELP)
@click.argument("source", required=False)
@click.option("--replay", type=click.Path(file_okay=False, exists=True),
              help="Replay a `digiteyes track` output folder instead of tracking.")
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Port on 127.0.0.1 (0: any free port).")
@click.option("--frames", type=click.IntRange(min=1), default=None,
              help="Stop after this many frames.")
@click.option("--fps", type=click.FloatRange(min=0.1), default=None,
              help="Frame rate for files, the scenario and replays (default: the source's).")
@click.option("--model", "model_name", help="Model name or .dh file (default: mouse-hand, "
              "the dataset's, or for footage without --init the full hand).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False), help="Rig file.")
@click.option("--init", "init_path", type=click.Path(dir_okay=False),
              help="Initial state JSON.")
@click.option("--iterations", type=click.IntRange(min=1), default=5, show_default=True,
              help="Gauss-Newton iterations per frame.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the rendered scenario.")
@click.option("--sphere", nargs=3, type=float, default=DEFAULT_SPHERE, show_default=True,
              metavar="X Y R", help="The sphere to pick up: ground x, y and radius, mm.")
@click.option("--reach", type=click.FloatRange(min=0.0), default=DEFAULT_REACH_MM,
              show_default=True, help="Pole tip to sphere centre distance (mm) within which "
              "the thumb button picks the sphere up.")
@click.option("--log", "log_path", type=click.Path(dir_okay=False),
              help="Also write the streamed states to this state log (CSV).")
@click.option("--no-overlay", is_flag=True, help="Send no overlay images.")
@click.option("--smooth", is_flag=True,
              help="One Euro filter the states online (defaults, docs/output.md): a steadier "
                   "pole, a little later.")
def mouse(source: str | None, replay: str | None, port: int, frames: int | None,
          fps: float | None, model_name: str | None, rig_path: str | None,
          init_path: str | None, iterations: int, seed: int,
          sphere: tuple[float, float, float], reach: float, log_path: str | None,
          no_overlay: bool, smooth: bool) -> None:
    if source is not None and replay is None and init_path is None \
            and not Path(source).is_dir():
        stream = open_footage_mouse(source, model_name=model_name, rig_path=rig_path,
                                    frames=frames, fps=fps, overlay=not no_overlay)
        if smooth:
            stream = replace(stream, frames=smoothed(stream.frames, stream.model, stream.fps,
                                                     OneEuroOptions()))
    else:
        stream = open_mouse_stream(source, replay=replay, model_name=model_name,
                                   rig_path=rig_path, init_path=init_path, frames=frames,
                                   fps=fps, iterations=iterations, seed=seed,
                                   overlay=not no_overlay,
                                   smooth=OneEuroOptions() if smooth else None)
    config = SceneConfig(tuple(sphere), reach, stream.description, stream.fps)
    log = StateLogWriter(log_path, stream.model) if log_path else None

    def record(frame: MouseFrame) -> None:
        log.append(frame.index, frame.state, time_s=frame.t_state - frame.t_frame,
                   lost=frame.lost, residual_rms_px=float("nan"), iterations=0)

    server = MouseServer(stream, port, config, on_frame=record if log else None)
    click.echo(f"digiteyes mouse: {stream.description}")
    try:
        server.run(lambda url: click.echo(f"open {url} in a browser (Ctrl-C stops)"))
    finally:
        if log is not None:
            log.close()
    click.echo(f"served {server.frames_sent} frame(s)")
