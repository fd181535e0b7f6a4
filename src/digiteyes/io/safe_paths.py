"""The safe-file rules every command follows (docs/safety.md).

* Names read from input files (camera names, frame and video file names) are single path
  components: no separators, no ``..``, no absolute paths (:func:`check_name`), and paths
  built from them stay inside their folder (:func:`inside`).
* A command deletes only what it can prove it wrote: the files listed in the manifest
  ``.digiteyes-manifest.json`` it left in its output folder (:func:`write_manifest`,
  :func:`remove_listed`).
* Files appear under their final name only when whole: they are written to a temporary
  name in the same folder and renamed (:func:`atomic_write_bytes`, :func:`atomic_path`).
* Outputs named after inputs get a name of their own even where two inputs share a stem
  (``a/x.jpg`` and ``b/x.jpg``), so that one does not overwrite the other
  (:func:`distinct_names`).
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

from digiteyes.errors import DatasetError, DigitEyesError
from digiteyes.jsonfile import load_json_text

MANIFEST = ".digiteyes-manifest.json"
"""File in an output folder listing what a command wrote there (paths relative to it)."""
MAX_NAME = 200
"""Longest name accepted from an input file (characters)."""


def check_name(name: object, what: str, where: str,
               error: type[DigitEyesError] = DatasetError) -> str:
    """Return ``name`` if it is a plain file or folder name, else raise ``error``.

    A plain name is a non-empty string of at most :data:`MAX_NAME` characters without
    ``/``, ``\\``, NUL or ``:`` and other than ``.`` and ``..``: it can only name an entry
    of the folder it is joined to.
    """
    if not isinstance(name, str) or not name or len(name) > MAX_NAME or name in (".", "..") \
            or any(c in name for c in "/\\:\0") or name != name.strip():
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."
        raise error(f"{where}: {what} {shown} is not a plain name (no path separators, "
                    f"no '..', at most {MAX_NAME} characters)")
    return name


def inside(folder: Path, relative: object, what: str, where: str,
           error: type[DigitEyesError] = DatasetError) -> Path:
    """``folder / relative`` if that path stays inside ``folder`` (after resolving ``..``
    and symbolic links), else raise ``error`` naming ``where`` and ``what``."""
    if not isinstance(relative, str) or not relative or "\0" in relative \
            or len(relative) > 4 * MAX_NAME or os.path.isabs(relative) \
            or any(len(part) > MAX_NAME for part in Path(relative).parts):
        raise error(f"{where}: {what} must be a relative path inside {folder}, each name at "
                    f"most {MAX_NAME} characters")
    path = folder / relative
    try:
        base = folder.resolve()
        resolved = path.resolve()
    except (OSError, RuntimeError, ValueError):
        raise error(f"{where}: {what} {relative!r} cannot be resolved") from None
    if resolved != base and base not in resolved.parents:
        raise error(f"{where}: {what} {relative!r} points outside {folder}")
    return path


def distinct_names(paths: Sequence[str | Path]) -> list[str]:
    """A distinct name per input: a file's stem or a folder's name, suffixed ``-2``,
    ``-3``, ... where an earlier input took it, skipping the suffixed names that other
    inputs bear as their own (``x``, ``x``, ``x-2`` give ``x``, ``x-3``, ``x-2``)."""
    stems = [(path.name if path.is_dir() else path.stem) or "input"
             for path in map(Path, paths)]
    own, taken, names = set(stems), set(), []
    for stem in stems:
        name, count = stem, 1
        while name in taken or (count > 1 and name in own):
            count += 1
            name = f"{stem}-{count}"
        taken.add(name)
        names.append(name)
    return names


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}.part{path.suffix}")


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write to; on success rename it to
    ``path``, on any failure remove it (the final name never holds a partial file)."""
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; OSError becomes :class:`DatasetError`."""
    path = Path(path)
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as handle:
            handle.write(data)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write ({exc.strerror or exc})") from None


def atomic_write_json(path: str | Path, payload: object) -> None:
    """Write ``payload`` as indented JSON to ``path`` atomically."""
    atomic_write_bytes(path, (json.dumps(payload, indent=2) + "\n").encode("utf-8"))


# ------------------------------------------------------------------ manifests
def read_manifest(folder: Path, command: str) -> list[str] | None:
    """Files (relative paths) that ``command`` recorded in ``folder``'s manifest, or None
    when the folder holds no manifest of that command."""
    path = folder / MANIFEST
    if not path.is_file():
        return None
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    try:
        payload = load_json_text(text, str(path), DatasetError, "manifest")
    except DatasetError:
        return None
    if not isinstance(payload, dict) or payload.get("command") != command \
            or not isinstance(payload.get("files"), list):
        return None
    return [f for f in payload["files"] if isinstance(f, str)]


def write_manifest(folder: Path, command: str, parts: list[str]) -> None:
    """Record every file now under ``folder / part`` for each of ``parts`` (the folders and
    files ``command`` created) in ``folder``'s manifest."""
    files: list[str] = []
    for part in parts:
        root = folder / part
        if root.is_file():
            files.append(part)
        elif root.is_dir():
            files += sorted(p.relative_to(folder).as_posix() for p in root.rglob("*")
                            if p.is_file() and not p.is_symlink())
    atomic_write_json(folder / MANIFEST, {"command": command, "parts": parts, "files": files})


def remove_listed(folder: Path, command: str) -> None:
    """Delete the files ``folder``'s manifest says ``command`` wrote, then the folders they
    leave empty and the manifest itself. Entries outside ``folder`` are skipped."""
    listed = read_manifest(folder, command)
    if listed is None:
        return
    where = str(folder / MANIFEST)
    dirs: set[Path] = set()
    for name in listed:
        try:
            path = inside(folder, name, "file", where)
        except DatasetError:
            continue
        if path.is_symlink() or path.is_file():
            try:
                path.unlink()
            except OSError as exc:
                raise DatasetError(f"{path}: cannot remove ({exc.strerror or exc})") from None
            dirs.update(p for p in path.parents if folder in p.parents)
    for directory in sorted(dirs, key=lambda p: len(p.parts), reverse=True):
        with contextlib.suppress(OSError):
            directory.rmdir()
    (folder / MANIFEST).unlink(missing_ok=True)


def write_png(path: str | Path, image: object) -> Path:
    """Write an RGB (H, W, 3) or grey (H, W) ``uint8`` image as a PNG at ``path``,
    atomically. ``path`` must end in ``.png`` and must not be a device or a folder."""
    import cv2
    import numpy as np

    path = Path(path)
    if path.suffix.lower() != ".png":
        raise DatasetError(f"{path}: the image is written as PNG; give a name ending in .png")
    if path.exists() and not path.is_file():
        raise DatasetError(f"{path}: exists and is not a regular file")
    array = np.asarray(image)
    if array.ndim == 3:
        array = cv2.cvtColor(array, cv2.COLOR_RGB2BGR)
    ok, buffer = cv2.imencode(".png", array)
    if not ok:
        raise DatasetError(f"{path}: PNG encoding failed")
    atomic_write_bytes(path, buffer.tobytes())
    return path
