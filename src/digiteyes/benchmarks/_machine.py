"""What every benchmark suite shares: the machine it ran on (CPU, cores, Python and
library versions, BLAS threads), the threads its kernels may use (:func:`kernel_threads`),
how it times a call (:func:`seconds_per_call`) and how it reports (:func:`emit`: the table,
then the JSON file).

Shared by every module of :mod:`digiteyes.benchmarks`, so that all their tables and JSON
files describe the machine the same way.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import platform
import timeit
from collections.abc import Iterator, Sequence
from pathlib import Path

import cv2
import numba
import numpy as np

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Environment variables that fix the BLAS thread count when numpy is first imported."""


@contextlib.contextmanager
def kernel_threads(opencv: int, numba_kernels: int) -> Iterator[None]:
    """Run OpenCV and numba's parallel kernels (the ray cast, the link measurement) on the
    given numbers of threads (``numba_kernels`` at most ``NUMBA_NUM_THREADS``), restoring
    both after."""
    before = cv2.getNumThreads(), numba.get_num_threads()
    cv2.setNumThreads(opencv)
    numba.set_num_threads(min(numba_kernels, numba.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        cv2.setNumThreads(before[0])
        numba.set_num_threads(before[1])


def cpu_model() -> str:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else what :mod:`platform` says."""
    fallback = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            for line in handle:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return fallback


def package_version(module: str) -> str | None:
    """``module.__version__``, or None when the module cannot be imported."""
    try:
        return str(importlib.import_module(module).__version__)
    except ImportError:
        return None


def blas_info() -> dict[str, object]:
    """Which BLAS numpy uses and how many threads it may run.

    Keys: ``library`` (numpy's build information), ``env`` (the thread variables set in
    the environment), ``threads`` (per library, from ``threadpoolctl`` when it is
    importable, else None: the count is then unknown and, unless an environment variable
    fixed it before numpy loaded, OpenBLAS uses every core).
    """
    library = None
    try:
        config = np.show_config(mode="dicts")
        library = config["Build Dependencies"]["blas"].get("name")
    except (TypeError, KeyError, AttributeError):
        pass
    env = {name: os.environ[name] for name in BLAS_THREAD_VARIABLES if name in os.environ}
    threads = None
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        pass
    else:
        threads = {pool["internal_api"]: pool["num_threads"] for pool in threadpool_info()}
    return {"library": library, "env": env, "threads": threads}


def machine_info(extra: Sequence[str] = ()) -> dict[str, object]:
    """Describe this machine for a benchmark report.

    Parameters
    ----------
    extra : further modules whose versions to report (e.g. ``("pinocchio",)``); None
        for those that are not importable.

    Returns
    -------
    dict
        ``cpu`` (model name), ``cores`` (logical CPUs), ``cores_usable`` (CPUs this process
        may run on), ``platform``, ``python``, ``numpy``, ``numba``, ``opencv``, ``blas``
        (see :func:`blas_info`), ``load_average_start`` (the 1-minute load average when
        the suite started; :func:`emit` adds ``load_average_end``: how busy the machine
        was, the suite's own work included) and one entry per module of ``extra``.
    """
    try:
        usable: int | None = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    info: dict[str, object] = {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "cores_usable": usable,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": package_version("numba"),
        "opencv": package_version("cv2"),
        "blas": blas_info(),
        "load_average_start": _load_average(),
    }
    for module in extra:
        info[module] = package_version(module)
    return info


def _load_average() -> float | None:
    """The 1-minute load average (None where the system has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def machine_lines(info: dict[str, object]) -> list[str]:
    """Two or three lines describing ``info`` (from :func:`machine_info`) for a table."""
    blas = info["blas"]
    if blas["threads"] is not None:
        threads = ", ".join(f"{k} {v} thread(s)" for k, v in blas["threads"].items())
    elif blas["env"]:
        threads = ", ".join(f"{k}={v}" for k, v in blas["env"].items())
    else:
        threads = "thread count not limited (threadpoolctl not installed, no *_NUM_THREADS)"
    return [
        f"machine: {info['cpu']}, {info['cores']} cores ({info['cores_usable']} usable), "
        f"{info['platform']}",
        f"         Python {info['python']}, numpy {info['numpy']}, numba {info['numba']}, "
        f"OpenCV {info['opencv']}",
        f"         BLAS {blas['library'] or 'unknown'}: {threads}",
        f"         load average (1 min) at the start: {info.get('load_average_start')}",
    ]


def emit(result: dict, table: str, json_path: str | None) -> dict:
    """Print a suite's table and, if ``json_path`` is given, write its result as JSON
    (strict: NaN and infinities are refused); returns ``result``. The machine's load
    average at the end goes into ``result["machine"]`` and the table."""
    if isinstance(result.get("machine"), dict):
        result["machine"]["load_average_end"] = _load_average()
        table += f"\nload average (1 min) at the end: {result['machine']['load_average_end']}"
    print(table)
    if json_path is not None:
        Path(json_path).write_text(json.dumps(result, indent=2, allow_nan=False) + "\n",
                                   encoding="utf-8")
    return result


def seconds_per_call(fn, repeat: int, min_time: float) -> list[float]:
    """Seconds per call of ``fn`` in each of ``repeat`` timed runs.

    ``fn`` is called once first (numba compilation, caches); each run then makes as many
    calls as needed to last ``min_time`` seconds (at least one).
    """
    fn()
    timer = timeit.Timer(fn)
    number = 1
    while (elapsed := timer.timeit(number)) < min_time:
        number = max(number * 2, int(number * 1.2 * min_time / max(elapsed, 1e-9)))
    return [t / number for t in timer.repeat(repeat=repeat, number=number)]
