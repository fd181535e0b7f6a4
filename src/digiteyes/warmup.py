"""Compiled kernels on the first run: say when they compile, and keep the compiling out of
the tracking figures.

The inner loops are numba kernels compiled on first use and cached on disk
(``cache=True``: ``__pycache__`` next to each module, or ``NUMBA_CACHE_DIR``). The first
run after an install compiles them (about a minute on a slow machine); later runs load
them in well under a second. :func:`cold_kernels` tells beforehand whether a run will
compile, so the commands can say so; :func:`warm_up` steps a tracker once on the first
frame and resets it, so that the timed loop of :func:`digiteyes.pipeline.run_tracker`
measures tracking, not compiling.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from numba.core.registry import CPUDispatcher

from digiteyes.trackers import Tracker

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


def warm_up(tracker: Tracker, images: Sequence[np.ndarray], initial_state: np.ndarray
            ) -> float:
    """Step ``tracker`` once on ``images`` from ``initial_state`` and discard the result
    (compiles or loads every kernel the tracker uses); the caller resets the tracker
    before tracking. Returns the seconds it took."""
    start = time.perf_counter()
    tracker.reset(np.asarray(initial_state, dtype=float))
    tracker.step(list(images))
    return time.perf_counter() - start
