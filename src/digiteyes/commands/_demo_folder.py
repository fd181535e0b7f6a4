"""The output folder of ``digiteyes demo``: replaced only as far as the demo wrote it.

The demo owns three sub-folders of its output folder (:data:`PARTS`). It writes into a
new or empty folder, or into one holding its own manifest (:mod:`digiteyes.io.safe_paths`):
then it deletes the files an earlier demo listed there and refuses if its sub-folders still
hold anything else. After a run, interrupted or not, it lists what it wrote.
"""

from __future__ import annotations

from pathlib import Path

from digiteyes.errors import DatasetError
from digiteyes.io.safe_paths import read_manifest, remove_listed, write_manifest

COMMAND = "digiteyes demo"
PARTS = ["sequence", "track", "evaluation"]


def prepare(out: Path) -> None:
    """Make ``out`` ready for a demo run, deleting only files an earlier demo wrote."""
    if out.exists() and not out.is_dir():
        raise DatasetError(f"{out}: exists and is not a folder")
    if not out.exists():
        return
    if read_manifest(out, COMMAND) is None and any(out.iterdir()):
        raise DatasetError(f"{out}: holds files the demo did not write (no demo manifest); "
                           "choose a new or empty --output folder")
    remove_listed(out, COMMAND)
    for part in PARTS:
        path = out / part
        if path.is_symlink() or (path.exists() and not path.is_dir()) or (
                path.is_dir() and any(path.iterdir())):
            raise DatasetError(f"{path}: holds files the demo did not write (no demo "
                               f"manifest lists them); choose another --output folder")


def record(out: Path) -> None:
    """List every file the demo wrote in ``out``'s manifest."""
    if out.is_dir():
        write_manifest(out, COMMAND, PARTS)
