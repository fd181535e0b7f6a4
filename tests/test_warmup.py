"""First-run compiling: which kernels have no compiled version on disk yet."""

from __future__ import annotations

import importlib
import sys

from digiteyes.warmup import KERNEL_MODULES, cold_kernels

KERNEL = '''
from numba import njit


@njit(cache=True)
def twice(x):
    return 2.0 * x


@njit(cache=True, inline="always")
def inlined(x):
    return x + 1.0
'''


def test_a_kernel_is_cold_until_it_was_compiled_once(tmp_path, monkeypatch):
    (tmp_path / "kernel_probe.py").write_text(KERNEL, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    module = importlib.import_module("kernel_probe")
    try:
        assert cold_kernels(["kernel_probe"]) == ["kernel_probe.twice"]  # inlined: not listed
        assert module.twice(2.0) == 4.0
        assert cold_kernels(["kernel_probe"]) == []
    finally:
        sys.modules.pop("kernel_probe", None)


def test_the_listed_modules_hold_kernels():
    cold = cold_kernels(KERNEL_MODULES)
    assert isinstance(cold, list) and all(name.startswith("digiteyes.") for name in cold)
