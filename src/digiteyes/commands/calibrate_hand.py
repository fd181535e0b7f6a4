"""``digiteyes calibrate-hand``: the user's hand size, written as a personal model file."""

from __future__ import annotations

from pathlib import Path

import click

from digiteyes.camera.mirror import HANDS
from digiteyes.detect.pose import DETECTORS


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
@click.option("--detector", type=click.Choice(DETECTORS),
              default="auto", show_default=True)
@click.option("--model", "model_name", default="hand", show_default=True,
              help="Model to scale (name or file).")
@click.option("--scale-only", is_flag=True,
              help="With a rig: keep the model's proportions (one global scale) instead of "
                   "measuring the 15 finger segments.")
@click.option("--hand", type=click.Choice(("auto", *HANDS)), default="auto",
              show_default=True,
              help="The hand in the images (with a second hand in view, the one measured); "
                   "a left hand is measured as the right hand of the mirror image; auto: "
                   "the side the detector reports in the first image set.")
def calibrate_hand(images: tuple[Path, ...], output: Path, rig: Path | None,
                   hand_length_mm: float | None, detector: str, model_name: str,
                   scale_only: bool, hand: str) -> None:
    """Estimate the hand's scale from frames of an open hand seen by a calibrated stereo
    rig (and there its finger segments one by one), or from a measured hand length, and
    write the personal model file."""
    import cv2

    from digiteyes.camera import load_rig
    from digiteyes.camera.mirror import mirror_images, rig_for_hand
    from digiteyes.detect.hand_size import measure_hand, scale_from_length, write_personal_model
    from digiteyes.detect.link_lengths import SEGMENT_NAMES, model_lengths
    from digiteyes.detect.pose import estimate_pose, make_detector
    from digiteyes.detect.side import TRACKED_SIDE
    from digiteyes.errors import DigitEyesError
    from digiteyes.kinematics import load_model

    model = load_model(model_name)
    lengths = None
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

        def read(path: Path):
            bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if bgr is None:
                raise DigitEyesError(f"{path}: not an image OpenCV can read")
            return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

        det = make_detector(detector, model, max_hands=2)
        sets = [[read(p) for p in images[start:start + len(the_rig)]]
                for start in range(0, len(images), len(the_rig))]
        if hand == "auto":  # the side of the first set's hand, right when it cannot tell
            seen = estimate_pose(sets[0], the_rig, det, model).sides()
            hand = "left" if seen == {"left"} else "right"
        cameras = rig_for_hand(the_rig, hand)
        if cameras.mirrored:
            sets = [mirror_images(images) for images in sets]
        measured = measure_hand(sets, cameras, det, model, segments=not scale_only,
                                side=TRACKED_SIDE)
        scale, lengths = measured.scale, measured.lengths
        how = (f"{measured.frames} stereo frame(s) of a {hand} hand, spread "
               f"{100 * measured.spread:.1f} %")
        if not scale_only and lengths is None:
            click.echo(f"the {det.name} detector places its keypoints with a model, so it "
                       "cannot measure finger segments: one global scale is kept (install "
                       'the MediaPipe extra, pip install "digiteyes[mediapipe]", to measure '
                       "them)")
        elif lengths is not None:
            nominal = scale * model_lengths(model)
            click.echo(f"{'segment':<18} {'scaled model':>12} {'measured':>9} {'frames':>6}")
            for name, ours, theirs, n in zip(SEGMENT_NAMES, nominal, lengths,
                                             measured.segment_frames, strict=True):
                click.echo(f"{name:<18} {ours:>9.1f} mm {theirs:>6.1f} mm {n:>6d}")
    write_personal_model(model, scale, output, name=output.stem, lengths=lengths)
    click.echo(f"hand scale {scale:.3f} ({how}); wrote {output}")
