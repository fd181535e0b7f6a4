"""One self-contained HTML page for a track or evaluation folder: ``report.html``.

The page embeds every PNG of the folder (plots, the 3D views in ``views/``) as data URIs,
links the overlay video by a relative path in a ``<video>`` element, and lists the numbers
of ``summary.json`` (the run) and ``metrics.json`` (the accuracy, when the folder was
evaluated) in tables. It loads nothing from the internet and needs no server: open the file
in a browser. An evaluation folder (``RESULT_DIR/evaluation``) also shows the run's
overlay, summary and 3D views from its parent folder.
"""

from __future__ import annotations

import base64
import html
import json
import os
from pathlib import Path
from typing import Any

from digiteyes.errors import DatasetError

PAGE_NAME = "report.html"
STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; padding: 0 1em; max-width: 1100px;
       color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
td.number { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; }
img, video { max-width: 100%; }
.views { display: flex; flex-wrap: wrap; gap: 0.5em; }
.views figure { flex: 0 1 320px; margin: 0; }
"""


def _find(folder: Path, name: str) -> Path | None:
    for candidate in (folder / name, folder.parent / name):
        if candidate.is_file():
            return candidate
    return None


def _read_json(path: Path | None) -> dict[str, Any] | None:
    if path is None:
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: cannot read ({exc})") from None


def _image(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(alt)}">'


def _number(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return html.escape(str(value))
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    return html.escape(str(value))


def _table(rows: list[tuple[str, Any]], key: str) -> str:
    cells = "".join(
        f'<tr><th>{html.escape(label)}</th><td class="number" data-key="{html.escape(name)}">'
        f"{_number(value)}</td></tr>"
        for label, name, value in ((label, f"{key}.{label}", value) for label, value in rows))
    return f'<table id="{key}">{cells}</table>'


def summary_rows(summary: dict[str, Any]) -> list[tuple[str, Any]]:
    """The scalar entries of a run's ``summary.json`` (keys as labels)."""
    return [(k, v) for k, v in summary.items()
            if isinstance(v, int | float | str | bool) or v is None]


def write_report_page(folder: str | Path, title: str | None = None) -> Path:
    """Write ``report.html`` into ``folder`` (a track or evaluation output folder) from what
    the folder holds; return its path. Raises :class:`DatasetError` for a missing folder or
    an unreadable JSON file."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError(f"{folder}: no such output folder")
    summary_path = _find(folder, "summary.json")
    summary = _read_json(summary_path)
    metrics = _read_json(folder / "metrics.json" if (folder / "metrics.json").is_file()
                         else None)
    video = _find(folder, "overlay.mp4")
    title = title or f"digiteyes report: {folder.name}"
    parts = [f"<h1>{html.escape(title)}</h1>"]
    if metrics is not None:
        from digiteyes.evaluate.report import headline_rows

        parts += ["<h2>Accuracy against ground truth</h2>",
                  _table(headline_rows(metrics), "accuracy")]
    if summary is not None:
        parts += ["<h2>Run summary</h2>", _table(summary_rows(summary), "summary")]
        stages = summary.get("ms_per_iteration_by_stage") or {}
        if stages:
            parts += ["<h3>ms per Gauss-Newton iteration by stage</h3>",
                      _table(list(stages.items()), "stages")]
    if video is not None:
        src = html.escape(os.path.relpath(video, folder))
        parts += ["<h2>Overlay video</h2>",
                  f'<video id="overlay" controls muted preload="auto" src="{src}"></video>']
    plots = sorted(folder.glob("*.png"))
    if plots:
        parts.append("<h2>Plots</h2>")
        parts += [f"<figure>{_image(p, p.stem)}<figcaption>{html.escape(p.stem)}"
                  "</figcaption></figure>" for p in plots]
    views_dir = next((d for d in (folder / "views", folder.parent / "views") if d.is_dir()), None)
    views = sorted(views_dir.glob("*.png")) if views_dir is not None else []
    if views:
        parts.append('<h2>3D views of the estimate</h2><div class="views">')
        parts += [f"<figure>{_image(p, p.stem)}<figcaption>{html.escape(p.stem)}"
                  "</figcaption></figure>" for p in views]
        parts.append("</div>")
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>\n"
            + "\n".join(parts) + "\n</body></html>\n")
    path = folder / PAGE_NAME
    try:
        path.write_text(page, encoding="utf-8")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path
