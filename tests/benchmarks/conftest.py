"""Fixtures of the benchmark tests: ``benchmark_script`` loads a script of
``benchmarks/`` (not a package) as a module, for the tests of its stages."""

from __future__ import annotations

import importlib.util
import os
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def load_script(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as a module named ``<name>_script`` (the folder goes on
    ``sys.path`` first, for the scripts' own imports such as ``one_thread``).

    The process environment is restored afterwards: ``one_thread`` sets the thread
    variables for a script run, and numba, already running in the test process, refuses
    a changed ``NUMBA_NUM_THREADS`` at its next compilation."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location(f"{name}_script", BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    environ = dict(os.environ)
    try:
        spec.loader.exec_module(module)
    finally:
        os.environ.clear()
        os.environ.update(environ)
    return module


@pytest.fixture
def benchmark_script() -> Callable[[str], ModuleType]:
    """:func:`load_script`, for a test to load the script it checks."""
    return load_script
