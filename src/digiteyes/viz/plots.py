"""Trajectory and error plots (matplotlib, Agg canvas; no pyplot, no display needed).

Styles follow the thesis's trajectory plots: palm quaternion and translation over time
(Fig. 4.7) and joint angles of a finger and the thumb (Fig. 4.8), here with the ground
truth drawn dashed beside the estimate. Every function returns a
:class:`matplotlib.figure.Figure`; :func:`save_figure` writes it as PNG.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

ESTIMATE_STYLE = {"linestyle": "-", "linewidth": 1.4}
TRUTH_STYLE = {"linestyle": "--", "linewidth": 1.0, "alpha": 0.8}


def new_figure(width_in: float = 8.0, height_in: float = 4.5) -> Figure:
    """A figure with an Agg canvas (safe in threads and without a display).

    Margins are fixed (no layout engine: constrained layout doubles the drawing time).
    """
    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 100) -> Path:
    """Write ``fig`` as PNG and return the path."""
    from digiteyes.io.safe_paths import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return path


def _min_span(ax, curves: Sequence[np.ndarray | None], span: float) -> None:
    """Show at least ``span`` on the y axis, so near-constant curves are not drawn at the
    scale of rounding noise."""
    values = np.concatenate([np.ravel(c) for c in curves if c is not None])
    values = values[np.isfinite(values)]
    if len(values) and np.ptp(values) < span:
        mid = 0.5 * (values.min() + values.max())
        ax.set_ylim(mid - 0.5 * span, mid + 0.5 * span)


def _mark_lost(ax, t: np.ndarray, lost: np.ndarray | None) -> None:
    if lost is not None and np.any(lost):
        ax.axvline(t[int(np.argmax(lost))], color="tab:red", linewidth=0.8, alpha=0.7,
                   label="first lost frame")


def plot_error_series(t: np.ndarray, series: Mapping[str, np.ndarray], *, ylabel: str,
                      title: str = "", xlabel: str = "frame", threshold: float | None = None,
                      lost: np.ndarray | None = None) -> Figure:
    """Error curves over time, one per entry of ``series`` (e.g. per fingertip, mm).

    ``threshold`` draws a horizontal line (the track-loss threshold); ``lost`` (T,) bool
    marks the first frame the tracker flagged lost.
    """
    fig = new_figure(8.0, 3.6)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.14, top=0.9)
    ax = fig.add_subplot()
    t = np.asarray(t, dtype=float)
    for name, values in series.items():
        ax.plot(t, np.asarray(values, dtype=float), label=name, linewidth=1.2)
    if threshold is not None:
        ax.axhline(threshold, color="k", linestyle=":", linewidth=0.9,
                   label=f"loss threshold {threshold:g}")
    _mark_lost(ax, t, lost)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    if title:
        ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", ncol=3)
    return fig


def plot_palm_trajectory(t: np.ndarray, est_quat: np.ndarray, true_quat: np.ndarray | None,
                         est_trans: np.ndarray, true_trans: np.ndarray | None, *,
                         xlabel: str = "frame", title: str = "") -> Figure:
    """Palm rotation (quaternion Qw..Qz) and translation (Tx..Tz, mm) over time (Fig. 4.7).

    Quaternions (T, 4) (w, x, y, z); the estimate's sign is flipped where needed to match
    the truth (q and -q are one rotation), so the curves are comparable.
    """
    t = np.asarray(t, dtype=float)
    est_quat = np.array(est_quat, dtype=float)
    if true_quat is not None:
        flip = np.sum(est_quat * true_quat, axis=1) < 0
        est_quat[flip] *= -1
    fig = new_figure(9.0, 7.0)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.08, top=0.93, wspace=0.25)
    axes = fig.subplots(4, 2, sharex=True, squeeze=False)
    columns = ((0, ("Qw", "Qx", "Qy", "Qz"), est_quat, true_quat, "tab:blue", 0.1),
               (1, ("Tx (mm)", "Ty (mm)", "Tz (mm)"), est_trans, true_trans, "tab:orange", 2.0))
    for col, labels, estimate, truth, color, span in columns:
        for j, label in enumerate(labels):
            ax = axes[j, col]
            ax.plot(t, estimate[:, j], color=color, label="estimate", **ESTIMATE_STYLE)
            if truth is not None:
                ax.plot(t, truth[:, j], color="k", label="truth", **TRUTH_STYLE)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            _min_span(ax, [estimate[:, j], None if truth is None else truth[:, j]], span)
    axes[3, 1].axis("off")
    axes[0, 0].legend(fontsize="small")
    axes[0, 1].legend(fontsize="small")
    axes[3, 0].set_xlabel(xlabel)
    axes[2, 1].set_xlabel(xlabel)
    axes[2, 1].xaxis.set_tick_params(labelbottom=True)
    fig.suptitle(title or "Palm rotation and translation")
    return fig


def plot_joint_angles(t: np.ndarray, groups: Mapping[str, Sequence[str]],
                      estimated_deg: Mapping[str, np.ndarray],
                      true_deg: Mapping[str, np.ndarray] | None = None, *,
                      xlabel: str = "frame", title: str = "") -> Figure:
    """Joint angles (degrees) over time, one panel per finger (Fig. 4.8).

    ``groups`` maps a panel title (``"index"``) to state names; ``estimated_deg`` and
    ``true_deg`` map state names to (T,) angle series in degrees.
    """
    t = np.asarray(t, dtype=float)
    rows = max(1, len(groups))
    height = 0.6 + 2.8 * rows
    fig = new_figure(9.0, height)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.45 / height, top=1 - 0.4 / height)
    axes = fig.subplots(max(1, len(groups)), 1, sharex=True, squeeze=False)[:, 0]
    colors = [f"C{i}" for i in range(10)]
    for ax, (finger, names) in zip(axes, groups.items(), strict=False):
        for j, name in enumerate(names):
            color = colors[j % len(colors)]
            ax.plot(t, estimated_deg[name], color=color, label=name, **ESTIMATE_STYLE)
            if true_deg is not None:
                ax.plot(t, true_deg[name], color=color, **TRUTH_STYLE)
        _min_span(ax, [*(estimated_deg[n] for n in names),
                       *((true_deg[n] for n in names) if true_deg is not None else ())], 2.0)
        ax.set_ylabel(f"{finger} (deg)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", ncol=len(names), loc="upper left")
    axes[-1].set_xlabel(xlabel)
    fig.suptitle(title or "Joint angles: estimate (solid), truth (dashed)")
    return fig


def plot_error_bars(groups: Mapping[str, Mapping[str, float | None]], *,
                    keys: Sequence[str] = ("rms", "mean_abs"), ylabel: str = "error (deg)",
                    title: str = "") -> Figure:
    """Grouped bars: for each group (a finger), one bar per statistic in ``keys``."""
    fig = new_figure(7.0, 3.6)
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.12, top=0.9)
    ax = fig.add_subplot()
    names = list(groups)
    x = np.arange(len(names))
    width = 0.8 / max(1, len(keys))
    for j, key in enumerate(keys):
        values = [groups[n].get(key) for n in names]
        values = [np.nan if v is None else float(v) for v in values]
        ax.bar(x + (j - (len(keys) - 1) / 2) * width, values, width, label=key.replace("_", " "))
    ax.set_xticks(x, names)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize="small")
    return fig
