"""Drive the 3D-mouse page in a real headless browser (Chromium through Selenium).

Used by the browser test and ``digiteyes bench mouse``: start ``digiteyes mouse`` in a
child process (:func:`start_mouse_server`), open its page in headless Chromium
(:func:`headless_chromium`), wait until the stream ended and read what the page holds
(``window.digiteyesMouse``: per frame the pole it drew, the buttons, the sphere and the
latency from frame to page, ms).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from digiteyes.errors import DigitEyesError

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
URL_PATTERN = re.compile(r"open (http://127\.0\.0\.1:\d+/)")


class BrowserError(DigitEyesError):
    """Chromium, chromedriver or Selenium is missing, or the page did not finish."""


def headless_chromium(width: int = 1300, height: int = 640):
    """A Selenium driver for headless Chromium (Debian's ``chromium`` and
    ``chromedriver``); raises :class:`BrowserError` naming what is missing."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError as exc:
        raise BrowserError("the browser check needs selenium: pip install selenium") from exc
    for path in (CHROMIUM, CHROMEDRIVER):
        if not Path(path).is_file():
            raise BrowserError(f"{path} is missing: apt-get install chromium chromium-driver")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu",
                     "--disable-dev-shm-usage", f"--window-size={width},{height}"):
        options.add_argument(argument)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def start_mouse_server(args: Sequence[str], timeout_s: float = 120.0,
                       env: dict[str, str] | None = None) -> tuple[subprocess.Popen, str]:
    """Run ``digiteyes mouse --port 0 ARGS`` in a child process; return it and the URL it
    printed. Raises :class:`BrowserError` (with the child's output) when no URL comes."""
    command = [sys.executable, "-m", "digiteyes.cli", "mouse", "--port", "0", *args]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True, env={**os.environ, **(env or {})})
    lines: list[str] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = child.stdout.readline()
        if not line:
            break
        lines.append(line)
        if match := URL_PATTERN.search(line):
            return child, match.group(1)
    child.kill()
    child.wait()
    child.stdout.close()
    raise BrowserError("digiteyes mouse printed no URL:\n" + "".join(lines))


def stop_server(child: subprocess.Popen, timeout_s: float = 10.0) -> int:
    """SIGTERM the server child and wait for it; returns its exit code."""
    if child.poll() is None:
        child.send_signal(signal.SIGTERM)
    try:
        return child.wait(timeout=timeout_s)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        if child.stdout is not None:
            child.stdout.close()


def page_state(driver) -> dict:
    """What the page holds (``window.digiteyesMouse``)."""
    return driver.execute_script("return window.digiteyesMouse")


def watch_until_ended(driver, url: str, timeout_s: float = 60.0) -> dict:
    """Open ``url``, wait until the stream's end message arrived, return the page state."""
    driver.get(url)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        state = page_state(driver)
        if state and state["ended"]:
            return state
        time.sleep(0.1)
    state = page_state(driver)
    frames = len(state["frames"]) if state else 0
    raise BrowserError(f"{url}: the stream did not end within {timeout_s:.0f} s "
                       f"({frames} frame(s) seen)")
