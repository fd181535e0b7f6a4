"""Folders of still images as footage: one folder per camera, frames in file-name order.

Many recordings come as numbered images (``frame_0001.jpg``, ...) rather than a video.
``digiteyes track FOLDER [FOLDER2 ...]`` reads them like videos: the image files of each
folder (:data:`IMAGE_SUFFIXES`) in natural order (``frame_2`` before ``frame_10``), RGB,
one folder per camera of the rig, stopping at the shortest folder. A folder holding a
``sequence.json`` is a digiteyes dataset instead (:mod:`digiteyes.io.dataset`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from pathlib import Path

import cv2
import numpy as np

from digiteyes.errors import DatasetError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
"""File suffixes read as frames (any case)."""


def _natural_key(path: Path) -> list[object]:
    """``frame_2`` before ``frame_10``: digit runs compare as numbers."""
    return [int(part) if part.isdigit() else part.lower()
            for part in re.split(r"(\d+)", path.name)]


def image_files(folder: str | Path) -> list[Path]:
    """The image files of ``folder`` in natural order (empty when it holds none)."""
    folder = Path(folder)
    return sorted((p for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES), key=_natural_key)


def is_image_folder(path: str | Path) -> bool:
    """Whether ``path`` is a folder of images and not a digiteyes dataset."""
    path = Path(path)
    return (path.is_dir() and not (path / "sequence.json").is_file()
            and bool(image_files(path)))


def read_rgb(path: Path) -> np.ndarray:
    """One image file as ``uint8`` (H, W, 3) RGB (grey images repeated in the channels).
    Raises :class:`DatasetError` naming the file when OpenCV cannot read it."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise DatasetError(f"{path}: not an image OpenCV can read")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def open_image_folder_frames(folders: Sequence[str | Path]
                             ) -> tuple[Iterator[list[np.ndarray]], list[int]]:
    """Synchronised frames of several image folders, one per camera (rig order), and the
    number of images in each. Raises :class:`DatasetError` for a folder without images."""
    listings = []
    for folder in folders:
        files = image_files(folder) if Path(folder).is_dir() else []
        if not files:
            raise DatasetError(f"{folder}: no images ({', '.join(IMAGE_SUFFIXES)}) and no "
                               "sequence.json: neither footage nor a dataset")
        listings.append(files)

    def frames() -> Iterator[list[np.ndarray]]:
        for paths in zip(*listings, strict=False):
            yield [read_rgb(p) for p in paths]

    return frames(), [len(files) for files in listings]
