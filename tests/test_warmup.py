"""First-run compiling: which kernels have no compiled version on disk yet, and the
background compile that ``digiteyes demo`` starts."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys

import pytest

from digiteyes.warmup import DEMO_KERNELS, KERNEL_MODULES, _kernels, cold_kernels

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


def test_cold_kernels_can_be_limited_to_some_names(tmp_path, monkeypatch):
    (tmp_path / "kernel_probe2.py").write_text(KERNEL.replace("inlined", "other")
                                               .replace(', inline="always"', ""),
                                               encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    importlib.import_module("kernel_probe2")
    try:
        assert cold_kernels(["kernel_probe2"]) == ["kernel_probe2.twice", "kernel_probe2.other"]
        assert cold_kernels(["kernel_probe2"], only=["kernel_probe2.other"]) == [
            "kernel_probe2.other"]
    finally:
        sys.modules.pop("kernel_probe2", None)


def test_the_demo_kernels_are_kernels_of_the_listed_modules():
    names = {f"{k.__module__}.{k.py_func.__qualname__}" for k in _kernels(KERNEL_MODULES)}
    assert set(DEMO_KERNELS) <= names
    assert len(set(DEMO_KERNELS)) == len(DEMO_KERNELS)


DEMO_AFTER_COMPILE = """
import json, sys
from numba.core import event
from digiteyes.cli import main
from digiteyes.warmup import DEMO_KERNELS, KERNEL_MODULES, _kernels, cold_kernels

compiled = []
class Listener(event.Listener):
    def on_start(self, e):
        compiled.append(e.data["dispatcher"].py_func.__module__)
    def on_end(self, e):
        pass
event.register("numba:compile", Listener())
warm = [f"{k.__module__}.{k.py_func.__qualname__}" for k in _kernels(KERNEL_MODULES)]
cold = set(cold_kernels())
code = main(["demo", "-o", sys.argv[1], "--frames", "3", "--quiet"])
print(json.dumps({"code": code, "warm": sorted(set(warm) - cold),
                  "compiled": sorted({m for m in compiled if m.startswith("digiteyes")})}))
"""


@pytest.mark.slow
def test_the_background_compile_leaves_nothing_for_the_demo_to_compile(tmp_path):
    """``python -m digiteyes.warmup`` on an empty cache compiles exactly the demo's
    kernels, with the demo's types: a demo after it compiles nothing (it only loads)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    subprocess.run([sys.executable, "-m", "digiteyes.warmup", "whole-hand"], env=env,
                   check=True, timeout=900)
    demo = subprocess.run([sys.executable, "-c", DEMO_AFTER_COMPILE, str(tmp_path / "demo")],
                          env=env, check=True, capture_output=True, text=True, timeout=900)
    result = json.loads(demo.stdout.strip().splitlines()[-1])
    assert result["code"] == 0
    assert result["warm"] == sorted(DEMO_KERNELS)
    assert result["compiled"] == []
