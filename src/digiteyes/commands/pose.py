"""``digiteyes pose IMAGE... -o OUT``: the hand in single images, in millimetres."""

from __future__ import annotations

from pathlib import Path

import click

from digiteyes.camera.mirror import HANDS
from digiteyes.detect.pose import DETECTORS


@click.command()
@click.argument("images", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for <image>.json and <image>.csv (created; images of the same "
                   "name get <image>-2, -3, ...).")
@click.option("--rig", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Rig file (JSON or OpenCV YAML). With N cameras the images are taken N at "
                   "a time, in rig order. Default: one camera with a 60 deg field of view.")
@click.option("--detector", type=click.Choice(DETECTORS),
              default="auto", show_default=True,
              help="auto = MediaPipe when installed (the classic detector where it finds "
                   "no hand), else the classic detector.")
@click.option("--model", "model_name", default="hand", show_default=True,
              help="Model name or model file (e.g. a personal model from calibrate-hand).")
@click.option("--hand-scale", type=click.FloatRange(0.5, 2.0), default=1.0, show_default=True,
              help="Assumed hand size relative to the model (sets depth with one camera).")
@click.option("--hfov", type=click.FloatRange(10, 170), default=60.0, show_default=True,
              help="Horizontal field of view (deg) of the default camera (no --rig).")
@click.option("--hand", type=click.Choice(("auto", *HANDS)), default="auto",
              show_default=True,
              help="The hand in the images; a left hand is fitted as the right hand of the "
                   "mirror image (outputs in the real images); auto: the side the detector "
                   "reports (right when it cannot tell).")
def pose(images: tuple[Path, ...], output: Path, rig: Path | None, detector: str,
         model_name: str, hand_scale: float, hfov: float, hand: str) -> None:
    """Detect the hand in each image and fit the model: 3D keypoints in the camera frame
    (mm), joint angles (deg) and the state, as JSON and CSV per image."""
    import cv2

    from digiteyes.camera import Rig, load_rig
    from digiteyes.camera.default import default_camera
    from digiteyes.camera.mirror import mirror_images, mirrored_rig, rig_for_hand
    from digiteyes.detect.model_fit import FitOptions
    from digiteyes.detect.pose import (
        estimate_pose,
        make_detector,
        pose_to_json,
        real_keypoints,
        write_pose_csv,
        write_pose_json,
    )
    from digiteyes.detect.side import TRACKED_SIDE
    from digiteyes.errors import DigitEyesError
    from digiteyes.io.safe_paths import distinct_names
    from digiteyes.kinematics import load_model

    model = load_model(model_name)
    the_rig = load_rig(rig) if rig is not None else None
    per_set = 1 if the_rig is None else len(the_rig)
    if len(images) % per_set:
        raise DigitEyesError(f"{len(images)} image(s) for a rig of {per_set} cameras: give "
                             f"them {per_set} at a time")
    det = make_detector(detector, model, classic_fallback=True, max_hands=2)
    options = FitOptions(scale=hand_scale)
    found = 0
    names = distinct_names(images[::per_set])  # a/x.jpg and b/x.jpg: x and x-2
    for start, name in zip(range(0, len(images), per_set), names, strict=True):
        paths = images[start:start + per_set]
        frames = []
        for path in paths:
            bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if bgr is None:
                raise DigitEyesError(f"{path}: not an image OpenCV can read")
            frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        real = the_rig or Rig((default_camera(frames[0].shape[1], frames[0].shape[0], hfov),))
        cams = rig_for_hand(real, "right" if hand == "auto" else hand)
        side = None if hand == "auto" else TRACKED_SIDE  # of several hands, the one asked for
        result = estimate_pose(mirror_images(frames) if cams.mirrored else frames, cams, det,
                               model, options, side)
        if hand == "auto" and result.sides() == {"left"}:
            cams = mirrored_rig(real)
            result = estimate_pose(mirror_images(frames), cams, det, model, options,
                                   TRACKED_SIDE)
        output.mkdir(parents=True, exist_ok=True)  # once an image has been read
        write_pose_json(pose_to_json(result, cams, [str(p) for p in paths]),
                        output / f"{name}.json")
        write_pose_csv(result, cams, output / f"{name}.csv")
        found += result.fit is not None
        ms = 1000 * sum(result.seconds.values())
        if result.fit is None:
            state = ("no hand" if result.fit_failure is None else
                     f"a detection no hand pose explains ({result.fit_failure})")
            if result.other_hands:
                state += (f" (only a hand of the other side: --hand "
                          f"{'right' if hand == 'left' else 'left'}, or auto)")
        else:
            middle_mcp = real_keypoints(result.fit.keypoints_camera(cams[0]), cams)[9]
            state = (f"hand at {middle_mcp.round(0).tolist()} mm "
                     f"(middle MCP, camera {cams[0].name})")
        click.echo(f"{paths[0].name}: {state}, {ms:.0f} ms")
    click.echo(f"{found}/{len(images) // per_set} image set(s) with a hand; wrote {output}")
