"""Compiled kernels on the first run: say when they compile, and keep the compiling out of
the tracking figures.

The inner loops are numba kernels compiled on first use and cached on disk
(``cache=True``: ``__pycache__`` next to each module, or ``NUMBA_CACHE_DIR``). The first
run after an install compiles them (about a minute on a slow machine); later runs load
them in well under a second. :func:`cold_kernels` tells beforehand whether a run will
compile, so the commands can say so; :func:`warm_up` steps a tracker once on the first
frame and resets it, so that the timed loop of :func:`digiteyes.pipeline.run_tracker`
measures tracking, not compiling. :func:`compile_in_background` compiles the tracking
kernels in a second process while the first one does something else (``digiteyes demo``
renders its sequence meanwhile): on two or more cores the compiling then costs little
wall time.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from numba.core.registry import CPUDispatcher

from digiteyes.trackers import warm_up

KERNEL_MODULES = (
    "digiteyes.kinematics._kernels", "digiteyes.camera.camera", "digiteyes.render._kernels",
    "digiteyes.features._kernels", "digiteyes.features._residual_kernels",
    "digiteyes.features.edges", "digiteyes.features.lines", "digiteyes.features.slices",
    "digiteyes.solvers._kernels",
)
"""Modules that define numba kernels (tracking and rendering)."""
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


def cold_kernels(modules: Iterable[str] = KERNEL_MODULES) -> list[str]:
    """Names of the kernels with no compiled version in numba's cache yet (empty when a
    run will only load them)."""
    cold = []
    for kernel in _kernels(modules):
        folder = Path(kernel._cache.cache_path)
        stem = f"{Path(kernel.py_func.__code__.co_filename).stem}.{kernel.py_func.__qualname__}-"
        if not any(folder.glob(f"{stem}*.nbi")):
            cold.append(f"{kernel.__module__}.{kernel.py_func.__qualname__}")
    return cold


def compile_in_background(scenario: str = "whole-hand") -> subprocess.Popen | None:
    """Start a process that renders one frame of ``scenario`` and steps the feature
    tracker on it, filling numba's cache with every kernel a track of that scenario uses;
    None when nothing is left to compile. :meth:`~subprocess.Popen.wait` for it before
    tracking (the kernels are then loaded, not compiled again)."""
    if not cold_kernels():
        return None
    return subprocess.Popen([sys.executable, "-m", "digiteyes.warmup", scenario],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _compile(scenario_name: str) -> None:
    """Render frame 0 of ``scenario_name`` (as ``digiteyes render`` does) and track it."""
    from digiteyes.synth import RenderOptions
    from digiteyes.synth.scenarios import build_scenario
    from digiteyes.synth.sequence import render_frames
    from digiteyes.trackers import DEFAULT_TRACKER, create_tracker

    scenario = build_scenario(scenario_name, seed=0, n_frames=1)
    images, _ = next(render_frames(scenario, RenderOptions()))
    warm_up(create_tracker(DEFAULT_TRACKER, scenario.model, scenario.rig), images,
            scenario.initial_state)


if __name__ == "__main__":
    _compile(sys.argv[1] if len(sys.argv) > 1 else "whole-hand")
