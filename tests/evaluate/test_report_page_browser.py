"""The report page in a real headless browser (Debian's chromium through chromedriver):
it loads without console errors, its video plays its metadata, every image decodes, and
the summary table shows the numbers of summary.json."""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

from digiteyes.evaluate.report_page import PAGE_NAME, summary_rows, write_report_page
from digiteyes.io import VideoWriter
from digiteyes.viz.plots import new_figure, save_figure

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"


@pytest.fixture(scope="module")
def browser():
    if not (shutil.which(CHROMIUM) and shutil.which(CHROMEDRIVER)):
        pytest.fail("the browser test needs Debian's chromium and chromedriver in /usr/bin")
    options = Options()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,1600"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def track_folder(tmp_path_factory) -> Path:
    """A track output folder as `digiteyes track` leaves it: summary, plot, video, view."""
    out = tmp_path_factory.mktemp("track")
    summary = {"frames": 8, "lost_frames": 1, "first_lost_frame": 6, "interrupted": False,
               "iterations": 40, "tracker_seconds": 0.123456789, "tracker_fps": 64.8,
               "ms_per_iteration": 3.0864, "ms_per_iteration_by_stage": {"jacobian": 0.5}}
    (out / "summary.json").write_text(json.dumps(summary))
    fig = new_figure(4, 3)
    fig.add_subplot().plot([0, 1, 2], [1, 0, 2])
    save_figure(fig, out / "trajectory-joints.png")
    (out / "views").mkdir()
    view = np.full((120, 160, 3), 200, dtype=np.uint8)
    view[40:80, 60:100] = (30, 90, 200)
    cv2.imwrite(str(out / "views" / "estimate-000007.png"), view)
    with VideoWriter(out / "overlay.mp4", 10.0, codec="h264", preset="veryfast") as video:
        for t in range(8):
            image = np.zeros((48, 64, 3), dtype=np.uint8)
            image[:, 8 * t:8 * t + 8] = 255
            video.write(image)
    return out


def test_page_loads_plays_and_shows_the_summary(browser, track_folder, tmp_path):
    page = write_report_page(track_folder, title="browser test")
    assert page == track_folder / PAGE_NAME
    browser.get(page.as_uri())
    deadline = time.monotonic() + 10.0
    while browser.execute_script("return document.getElementById('overlay').readyState") < 1:
        assert time.monotonic() < deadline, "the overlay video never loaded its metadata"
        time.sleep(0.05)
    width, error = browser.execute_script(
        "const v = document.getElementById('overlay'); return [v.videoWidth, v.error];")
    assert width == 64 and error is None
    widths = browser.execute_script(
        "return Array.from(document.images).map(i => i.complete ? i.naturalWidth : 0)")
    assert len(widths) == 2 and all(w > 0 for w in widths)
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == []
    summary = json.loads((track_folder / "summary.json").read_text())
    cells = {c.get_attribute("data-key"): c.text
             for c in browser.find_elements(By.CSS_SELECTOR, "#summary td")}
    assert len(cells) == len(summary_rows(summary))
    for key, value in summary_rows(summary):
        shown = cells[f"summary.{key}"]
        if isinstance(value, float):
            assert float(shown) == pytest.approx(value, rel=1e-5)
        else:
            assert shown == str(value)
    assert browser.find_element(By.CSS_SELECTOR, "#stages td").text == "0.5"
    browser.save_screenshot(str(tmp_path / "report.png"))
    assert (tmp_path / "report.png").stat().st_size > 0


def test_evaluation_folder_links_the_parent_video(track_folder):
    evaluation = track_folder / "evaluation"
    evaluation.mkdir()
    text = write_report_page(evaluation).read_text()
    assert 'src="../overlay.mp4"' in text
    assert not re.search(r'(src|href)="(https?:)?//', text)  # nothing from the internet
    assert text.count("<img ") == 1  # the parent's 3D view
