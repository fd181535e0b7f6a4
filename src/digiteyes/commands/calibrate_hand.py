"""``digiteyes calibrate-hand``: the user's hand size, written as a personal model file."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("calibrate-hand")
@click.argument("images", nargs=-1, type=click.Path(exists=True, dir_okay=False,
                                                    path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Personal model file to write (e.g. my-hand.dh).")
@click.option("--rig", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Rig of two or more cameras; IMAGES are taken one per camera at a time.")
@click.option("--hand-length-mm", type=float,
              help="Measured wrist-crease to middle-fingertip length (one camera, no images "
                   "needed).")
@click.option("--detector", type=click.Choice(["auto", "mediapipe", "classic"]),
              default="auto", show_default=True)
@click.option("--model", "model_name", default="hand", show_default=True,
              help="Model to scale (name or file).")
def calibrate_hand(images: tuple[Path, ...], output: Path, rig: Path | None,
                   hand_length_mm: float | None, detector: str, model_name: str) -> None:
    """Estimate the hand's scale from frames of an open hand seen by a calibrated stereo
    rig, or from a measured hand length, and write the scaled model file."""
    import cv2

    from digiteyes.camera import load_rig
    from digiteyes.detect.hand_size import (
        scale_from_fits,
        scale_from_length,
        write_personal_model,
    )
    from digiteyes.detect.pose import estimate_pose, make_detector
    from digiteyes.errors import DigitEyesError
    from digiteyes.kinematics import load_model

    model = load_model(model_name)
    if hand_length_mm is not None:
        scale = scale_from_length(model, hand_length_mm)
        how = f"measured length {hand_length_mm:.1f} mm"
    else:
        if rig is None or not images:
            raise DigitEyesError("give --hand-length-mm, or --rig with two or more cameras and "
                                 "their images (one camera cannot see the hand's size)")
        the_rig = load_rig(rig)
        if len(the_rig) < 2 or len(images) % len(the_rig):
            raise DigitEyesError(f"a rig of at least two cameras and images in sets of "
                                 f"{len(the_rig)} are needed, got {len(the_rig)} camera(s) and "
                                 f"{len(images)} image(s)")
        det = make_detector(detector, model)
        fits = []
        for start in range(0, len(images), len(the_rig)):
            frames = []
            for path in images[start:start + len(the_rig)]:
                bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
                if bgr is None:
                    raise DigitEyesError(f"{path}: not an image OpenCV can read")
                frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
            fits.append(estimate_pose(frames, the_rig, det, model).fit)
        scale, spread, count = scale_from_fits(fits)
        how = f"{count} stereo frame(s), spread {100 * spread:.1f} %"
    write_personal_model(model, scale, output, name=output.stem)
    click.echo(f"hand scale {scale:.3f} ({how}); wrote {output}")
