"""``digiteyes calibrate-camera``: a rig file from chessboard or ChArUco views of one or two
cameras."""

from __future__ import annotations

from pathlib import Path

import click


def _grid(option: str, value: str, what: str) -> tuple[int, int]:
    from digiteyes.errors import CameraError

    try:
        cols, rows = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise CameraError(f"{option} must read COLSxROWS ({what}), got {value!r}") from None
    return cols, rows


def _frames(source: Path, every: int) -> list:
    """Images of a folder (sorted by name) or every ``every``-th frame of a video (RGB)."""
    import cv2

    from digiteyes.errors import CameraError
    from digiteyes.io.video import VideoReader

    if source.is_dir():
        paths = sorted(p for p in source.iterdir()
                       if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".tif"))
        images = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in paths]
        if not images or any(im is None for im in images):
            raise CameraError(f"{source}: expected a folder of readable images")
        return images
    with VideoReader(source, gray=True) as reader:
        return [frame for i, frame in enumerate(reader) if i % every == 0]


@click.command("calibrate-camera")
@click.argument("sources", nargs=-1, required=True,
                type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Rig file to write (JSON, read by --rig everywhere).")
@click.option("--pattern", default="9x6", show_default=True,
              help="Inner corners of the chessboard, COLSxROWS.")
@click.option("--square-mm", type=click.FloatRange(min=0, min_open=True), required=True,
              help="Side of one square of the board, mm.")
@click.option("--charuco", metavar="COLSxROWS",
              help="A ChArUco board of COLSxROWS squares instead of a chessboard (needs "
                   "--marker-mm); views showing part of it count.")
@click.option("--marker-mm", type=click.FloatRange(min=0, min_open=True),
              help="Side of one ArUco marker of the ChArUco board, mm.")
@click.option("--dictionary", default="DICT_4X4_50", show_default=True,
              help="OpenCV ArUco dictionary of the ChArUco board.")
@click.option("--every", type=click.IntRange(min=1), default=15, show_default=True,
              help="For a video: use every N-th frame.")
def calibrate_camera(sources: tuple[Path, ...], output: Path, pattern: str, square_mm: float,
                     charuco: str | None, marker_mm: float | None, dictionary: str,
                     every: int) -> None:
    """Calibrate one camera (one SOURCE) or a stereo pair (two SOURCES, frames taken at the
    same moments) from chessboard or ChArUco views; a SOURCE is a folder of images or a
    video."""
    from digiteyes.camera import save_rig
    from digiteyes.camera.calibration import CharucoBoard, Chessboard, calibrate
    from digiteyes.errors import CameraError

    if charuco is not None:
        if marker_mm is None:
            raise CameraError("--charuco needs --marker-mm, the side of one ArUco marker")
        board = CharucoBoard(_grid("--charuco", charuco, "squares"), square_mm, marker_mm,
                             dictionary)
    else:
        board = Chessboard(_grid("--pattern", pattern, "inner corners"), square_mm)

    if len(sources) > 2:
        raise CameraError(f"give one source (one camera) or two (a stereo pair), got "
                          f"{len(sources)}")
    frames = [_frames(s, every) for s in sources]
    second = frames[1] if len(frames) == 2 else None
    if second is not None and len(second) != len(frames[0]):
        n = min(len(second), len(frames[0]))
        frames[0], second = frames[0][:n], second[:n]
    names = tuple(s.stem for s in sources) if len(sources) == 2 and \
        sources[0].stem != sources[1].stem else ("cam0", "cam1")
    result = calibrate(frames[0], board, second, names)
    save_rig(result.rig, output)
    for name, rms in result.rms_px.items():
        click.echo(f"{name}: {result.views[name]} view(s), RMS reprojection {rms:.3f} px")
    click.echo(f"wrote {output}")
