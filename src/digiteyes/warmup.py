"""Compiled kernels on the first run: say when they compile, and keep the compiling out of
the tracking figures.

The inner loops are numba kernels compiled on first use and cached on disk
(``cache=True``: ``__pycache__`` next to each module, or ``NUMBA_CACHE_DIR``). The first
run after an install compiles them (about a minute on a slow machine); later runs load
them in well under a second. :func:`cold_kernels` tells beforehand whether a run will
compile, so the commands can say so; :func:`warm_up` steps a tracker once on the first
frame and resets it, so that the timed loop of :func:`digiteyes.pipeline.run_tracker`
measures tracking, not compiling. :func:`compile_in_background` compiles the tracking
kernels in a second process while the first one renders (``digiteyes demo``): the two
cores then split the compiling, the renderer's kernels in the first process and the
tracker's in the second, and neither compiles what the other does.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numba.core.registry import CPUDispatcher

from digiteyes.trackers import warm_up

KERNEL_MODULES = (
    "digiteyes.kinematics._kernels", "digiteyes.camera.camera", "digiteyes.render._kernels",
    "digiteyes.features._kernels", "digiteyes.features._residual_kernels",
    "digiteyes.features.edges", "digiteyes.features.lines", "digiteyes.features.slices",
    "digiteyes.features.silhouette", "digiteyes.solvers._kernels",
    "digiteyes.detect._fit_kernels",
)
"""Modules that define numba kernels (tracking, rendering and the keypoint fit of an
automatic start)."""
DEMO_KERNELS = (
    "digiteyes.kinematics._kernels.fk_kernel", "digiteyes.kinematics._kernels.jacobian_kernel",
    "digiteyes.kinematics._kernels.integrate_kernel", "digiteyes.camera.camera.project_kernel",
    "digiteyes.render._kernels._extend", "digiteyes.render._kernels._extend_ball",
    "digiteyes.render._kernels._block", "digiteyes.render._kernels._row_span",
    "digiteyes.render._kernels.cast_kernel", "digiteyes.features._kernels.links_kernel",
    "digiteyes.features._kernels.tips_kernel",
    "digiteyes.features._residual_kernels.feature_residuals_kernel",
    "digiteyes.features._residual_kernels._across",
    "digiteyes.features._residual_kernels.contour_points_kernel",
    "digiteyes.features._residual_kernels.residual_rows_kernel",
    "digiteyes.features.lines._tls", "digiteyes.features.lines._median",
    "digiteyes.features.lines._robust_scale", "digiteyes.features.lines._lmeds",
    "digiteyes.features.lines.fit_one", "digiteyes.features.slices.tangent_pair",
    "digiteyes.features.silhouette._count", "digiteyes.solvers._kernels.scaled_cholesky_solve",
    "digiteyes.solvers._kernels.damped_system",
)
"""The kernels that rendering a scenario and tracking it with the default tracker compile
(``digiteyes demo``; tests/test_warmup.py checks the list against a first run)."""
COMPILE_MESSAGE = "compiling kernels (first run only)..."


def _kernels(modules: Iterable[str]) -> list[CPUDispatcher]:
    """The cached, separately compiled kernels of ``modules`` (kernels inlined into their
    callers are compiled with them and left out)."""
    found = []
    for name in modules:
        module = importlib.import_module(name)
        for value in vars(module).values():
            if (isinstance(value, CPUDispatcher) and value.__module__ == name
                    and value.targetoptions.get("inline", "never") == "never"
                    and getattr(value, "_cache", None) is not None):
                found.append(value)
    return found


def cold_kernels(modules: Iterable[str] = KERNEL_MODULES,
                 only: Iterable[str] | None = None) -> list[str]:
    """Names (``module.qualname``) of the kernels of ``modules`` with no compiled version
    in numba's cache yet (empty when a run will only load them); with ``only``, just
    those of the names in it."""
    wanted = None if only is None else set(only)
    cold = []
    for kernel in _kernels(modules):
        name = f"{kernel.__module__}.{kernel.py_func.__qualname__}"
        if wanted is not None and name not in wanted:
            continue
        folder = Path(kernel._cache.cache_path)
        stem = f"{Path(kernel.py_func.__code__.co_filename).stem}.{kernel.py_func.__qualname__}-"
        if not any(folder.glob(f"{stem}*.nbi")):
            cold.append(name)
    return cold


def compile_in_background(scenario: str = "whole-hand") -> subprocess.Popen | None:
    """Start a process that compiles every kernel a render and track of ``scenario`` with
    the default tracker uses (:data:`DEMO_KERNELS`), tracking kernels first; None when
    they are all in numba's cache already. Meant to run while this process renders the
    sequence: :meth:`~subprocess.Popen.wait` for it before tracking (the kernels are then
    loaded, not compiled again)."""
    if not cold_kernels(only=DEMO_KERNELS):
        return None
    return subprocess.Popen([sys.executable, "-m", "digiteyes.warmup", scenario],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def compile_tracking(scenario_name: str = "whole-hand") -> None:
    """Compile the kernels of tracking ``scenario_name`` with the default tracker.

    First the tracker steps once on blank frames with its drawing steps off (shading
    correction and silhouette check, which call the renderer): that compiles the feature,
    residual and Jacobian kernels without touching the renderer's, which the rendering
    process compiles meanwhile. Then frame 0 is rendered (the renderer's kernels are
    loaded from the cache by then, or compiled here on a single core) and the tracker
    steps on it with its default options, compiling what is left (the solver's step and
    the drawing steps).
    """
    from digiteyes.synth import RenderOptions
    from digiteyes.synth.scenarios import build_scenario
    from digiteyes.synth.sequence import render_frames
    from digiteyes.trackers import DEFAULT_TRACKER, create_tracker

    scenario = build_scenario(scenario_name, seed=0, n_frames=1)
    blank = [np.zeros((camera.height, camera.width), np.uint8) for camera in scenario.rig]
    warm_up(create_tracker(DEFAULT_TRACKER, scenario.model, scenario.rig,
                           shading_correction=False, silhouette_check=False),
            blank, scenario.initial_state)
    images, _ = next(render_frames(scenario, RenderOptions()))
    warm_up(create_tracker(DEFAULT_TRACKER, scenario.model, scenario.rig), images,
            scenario.initial_state)


if __name__ == "__main__":
    compile_tracking(sys.argv[1] if len(sys.argv) > 1 else "whole-hand")
