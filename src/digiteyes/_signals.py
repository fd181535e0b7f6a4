"""SIGTERM handled like Ctrl-C (docs/safety.md).

A process told to stop by ``kill`` or a job scheduler gets SIGTERM; by default Python dies
at once, leaving a half-written video and no summary. Inside :func:`sigterm_as_interrupt`
SIGTERM raises :class:`KeyboardInterrupt` instead, so ``track``, ``render`` and ``demo``
finish their files as they do on Ctrl-C.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM raises KeyboardInterrupt (main thread only; elsewhere a
    no-op). The previous handler is restored on exit."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
