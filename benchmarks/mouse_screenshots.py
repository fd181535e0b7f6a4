"""Screenshots of the 3D-mouse page for docs/mouse3d.md (headless Chromium).

Serves the ``mouse`` scenario rendered and tracked on the fly (``digiteyes mouse``) and
takes a picture of the page at the given frames (by default while the finger is raised
and while the thumb button holds the sphere). Run from the repository root:

    python benchmarks/mouse_screenshots.py [--out docs/images] [--frames 60 176]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from digiteyes.apps.mouse_browser import (
    BrowserError,
    headless_chromium,
    page_state,
    start_mouse_server,
    stop_server,
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images")
    parser.add_argument("--frames", type=int, nargs="+", default=[60, 176])
    args = parser.parse_args()
    try:
        driver = headless_chromium(1200, 720)
    except BrowserError as exc:
        print(f"skipped: {exc}")
        return 0
    wanted = sorted(args.frames)
    child, url = start_mouse_server(["--frames", str(wanted[-1] + 2), "--fps", "10"])
    try:
        driver.get(url)
        for frame in wanted:
            while True:
                state = page_state(driver)
                if state["frames"] and state["frames"][-1]["index"] >= frame:
                    break
                if state["ended"]:
                    raise BrowserError(f"the stream ended before frame {frame}")
                time.sleep(0.02)
            path = Path(args.out) / f"mouse-page-{frame:03d}.png"
            driver.save_screenshot(str(path))
            print(f"{path}: frame {state['frames'][-1]['index']}, sphere held "
                  f"{state['sphere']['held']}, latency {state['latencyMs']:.0f} ms")
    finally:
        stop_server(child)
        driver.quit()
    return 0


if __name__ == "__main__":
    sys.exit(main())
