"""A track in the configuration space (Huang Fig. 2 style): the first two PCA dimensions
with the basis configurations, the manifolds between them and the estimated (and true)
finger configuration per frame."""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from digiteyes.smc.configuration import ConfigurationSpace
from digiteyes.smc.manifolds import manifold_pairs
from digiteyes.viz.plots import ESTIMATE_STYLE, TRUTH_STYLE, new_figure


def plot_configuration_track(space: ConfigurationSpace, track: np.ndarray | None = None,
                             truth: np.ndarray | None = None,
                             particles: np.ndarray | None = None,
                             dims: tuple[int, int] = (0, 1)) -> Figure:
    """Figure of the configuration space in PCA dimensions ``dims``.

    ``track`` and ``truth`` are (T, D) PCA coordinates per frame (``space.to_coordinates``
    of the joint angles); ``particles`` (N, D) are drawn as faint dots (one frame's set).
    """
    fig = new_figure(6.5, 6.0)
    ax = fig.add_axes((0.1, 0.08, 0.86, 0.86))
    a, b = dims
    basis = space.basis[:, [a, b]]
    pairs = manifold_pairs(len(basis))
    ax.add_collection(LineCollection(basis[pairs], colors="0.8", linewidths=0.5,
                                     zorder=1, label="manifolds L_ij"))
    if particles is not None:
        ax.scatter(particles[:, a], particles[:, b], s=3, color="tab:green", alpha=0.3,
                   zorder=2, label="particles")
    if truth is not None:
        ax.plot(truth[:, a], truth[:, b], color="k", zorder=3, label="truth", **TRUTH_STYLE)
    if track is not None:
        ax.plot(track[:, a], track[:, b], color="tab:red", zorder=4, label="estimate",
                **ESTIMATE_STYLE)
    ax.scatter(basis[:, 0], basis[:, 1], s=22, color="tab:blue", zorder=5,
               label="basis configurations")
    for name, (x, y) in zip(space.basis_names, basis, strict=True):
        ax.annotate(name, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel(f"PCA dimension {a + 1} (rad)")
    ax.set_ylabel(f"PCA dimension {b + 1} (rad)")
    ax.set_title("Finger configuration space (Huang et al. Fig. 2 style)", fontsize=10)
    ax.legend(loc="best", fontsize=7)
    ax.autoscale_view()
    return fig
