"""``digiteyes mouse`` in a real headless browser (Debian's chromium through Selenium): the
page loads its own files only, the pole follows the streamed track, the thumb button picks
the sphere up and puts it down, and the frame-to-page latency is measured."""

from __future__ import annotations

import re
import signal
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from digiteyes.apps.mouse3d import pole_from_state
from digiteyes.apps.mouse_browser import (
    headless_chromium,
    page_state,
    start_mouse_server,
    stop_server,
    watch_until_ended,
)
from digiteyes.apps.mouse_server import DEFAULT_SPHERE, static_file
from digiteyes.io import StateLogWriter, read_state_log
from digiteyes.kinematics import load_model
from digiteyes.synth.scenarios import MOUSE_RAISE

N_REPLAY = 50
PRESS = (10, 35)  # thumb pressed in frames [10, 35)
LATENCY_TARGET_MS = 50.0


@pytest.fixture(scope="module")
def driver():
    browser = headless_chromium()
    yield browser
    browser.quit()


@pytest.fixture(scope="module")
def model():
    return load_model("mouse-hand")


def carry_states(model) -> np.ndarray:
    """Index raised (pole tip about 35 mm up); the thumb presses at frame 10, the palm
    carries the pole 80 mm along x and 40 mm along -y, the thumb lets go at frame 35 and
    the palm moves back past the start."""
    t = np.arange(N_REPLAY)
    q = np.zeros((N_REPLAY, model.n_q))
    for name, deg in zip(("index.mcp", "index.pip", "index.dip"), MOUSE_RAISE, strict=True):
        q[:, model.state_index(name)] = np.radians(deg)
    q[:, model.state_index("palm.x")] = np.interp(t, [0, 12, 30, 36, 49], [0, 0, 80, 80, -60])
    q[:, model.state_index("palm.y")] = np.interp(t, [0, 12, 30, 49], [0, 0, -40, -40])
    pressed = (t >= PRESS[0]) & (t < PRESS[1])
    q[:, model.state_index("thumb.abd")] = np.where(pressed, np.radians(25.0), 0.0)
    return q


@pytest.fixture(scope="module")
def replay_run(tmp_path_factory, model):
    folder = tmp_path_factory.mktemp("replay")
    with StateLogWriter(folder / "states.csv", model) as log:
        for i, q in enumerate(carry_states(model)):
            log.append(i, q, time_s=0.0, lost=False, residual_rms_px=0.5, iterations=5)
    return folder


def page_poles(state: dict) -> np.ndarray:
    return np.array([f["pole"] for f in state["frames"]], dtype=float)


def test_page_ships_its_own_scripts():
    html = static_file("index.html").decode()
    sources = re.findall(r"""(?:src|href)=["']([^"']+)""", html)
    assert sources == ["mouse.js"]
    assert "http" not in static_file("mouse.js").decode().replace("http://127", "")


def test_replay_moves_the_pole_and_carries_the_sphere(driver, replay_run, model):
    child, url = start_mouse_server(["--replay", str(replay_run), "--fps", "20"])
    try:
        assert url.startswith("http://127.0.0.1:")
        with pytest.raises(urllib.error.HTTPError, match="404") as missing:
            urllib.request.urlopen(url + "nothing.js", timeout=5)
        missing.value.close()
        state = watch_until_ended(driver, url, timeout_s=60)
    finally:
        assert stop_server(child) == 0
    frames = state["frames"]
    assert [f["index"] for f in frames] == list(range(N_REPLAY))
    logged = read_state_log(replay_run / "states.csv", model).states
    truth = pole_from_state(model, logged)
    poles = page_poles(state)
    assert np.abs(poles - truth).max() <= 1.0
    assert np.ptp(poles[:, 0]) > 100.0  # the pole really moved
    assert 30.0 < truth[0, 2] < 40.0

    sphere = np.array([f["sphere"] for f in frames])
    held = np.array([f["held"] for f in frames])
    assert not held[:PRESS[0]].any() and held[PRESS[0]:PRESS[1]].all()
    assert not held[PRESS[1]:].any()
    start = np.array([DEFAULT_SPHERE[0], DEFAULT_SPHERE[1], DEFAULT_SPHERE[2]])
    np.testing.assert_allclose(sphere[:PRESS[0]], np.tile(start, (PRESS[0], 1)), atol=1e-9)
    offset = start - truth[PRESS[0]]
    np.testing.assert_allclose(sphere[PRESS[0]:PRESS[1]], truth[PRESS[0]:PRESS[1]] + offset,
                               atol=1.0)
    put_down = truth[PRESS[1] - 1] + offset
    put_down[2] = DEFAULT_SPHERE[2]
    np.testing.assert_allclose(sphere[PRESS[1]:], np.tile(put_down, (N_REPLAY - PRESS[1], 1)),
                               atol=1.0)
    assert np.hypot(*(put_down[:2] - start[:2])) > 80.0  # put down somewhere else
    # Frame-to-page latency: measured and reported here; the 50 ms target is checked by
    # `digiteyes bench mouse` (a loaded test machine delays the headless browser).
    latency = np.array([f["latency_ms"] for f in frames])
    assert np.isfinite(latency).all() and (latency >= 0).all()
    print(f"replay frame-to-page latency: median {np.median(latency):.1f} ms "
          f"(target {LATENCY_TARGET_MS:.0f} ms), max {latency.max():.1f} ms")


def test_scenario_tracked_on_the_fly_until_sigterm(driver, tmp_path, model):
    """No source: the mouse scenario is rendered and tracked as it is served; SIGTERM in
    the middle of the stream stops the server cleanly after the frames it sent."""
    log_path = tmp_path / "streamed.csv"
    child, url = start_mouse_server(["--fps", "10", "--log", str(log_path)])
    try:
        driver.get(url)
        deadline = time.monotonic() + 80
        while len(page_state(driver)["frames"]) < 6 and time.monotonic() < deadline:
            time.sleep(0.1)
        child.send_signal(signal.SIGTERM)
        assert child.wait(timeout=30) == 0
        output = child.stdout.read()
    finally:
        stop_server(child)
    streamed = read_state_log(log_path, model).states
    assert f"served {len(streamed)} frame(s)" in output
    state = page_state(driver)
    assert not state["ended"]  # stopped by the signal, not by the end of the source
    assert len(state["frames"]) == len(streamed) >= 6
    assert state["imageFrames"] == len(streamed)  # every frame's overlay JPEG arrived
    np.testing.assert_allclose(page_poles(state), pole_from_state(model, streamed), atol=1.0)
    latency = np.array([f["latency_ms"] for f in state["frames"]])
    tracking = np.array([f["tracking_ms"] for f in state["frames"]])
    # The page's clock is the browser's (coarsened to a fraction of a millisecond), the
    # tracking time the server's: frame-to-page includes tracking, within that resolution.
    assert (latency >= tracking - 0.5).all(), latency - tracking
    print(f"tracked frame-to-page latency: median {np.median(latency):.1f} ms "
          f"(tracking {np.median(tracking):.1f} ms)")
    assert driver.find_element("id", "pole-height").text != "-"


def test_footage_without_a_hand_says_so_on_the_page_and_in_the_terminal(driver, tmp_path):
    """``digiteyes mouse VIDEO`` whose frames show no hand: the automatic start finds
    none, the page says why it stopped, and the command exits with the one-line error."""
    import cv2

    video = tmp_path / "empty.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (160, 120))
    for _ in range(5):
        writer.write(np.full((120, 160, 3), 90, np.uint8))
    writer.release()
    child, url = start_mouse_server([str(video), "--fps", "50"])
    try:
        state = watch_until_ended(driver, url, timeout_s=60)
        assert child.wait(timeout=30) == 2
        output = child.stdout.read()
    finally:
        stop_server(child)
    assert "no hand found in 5 frame(s)" in state["error"]
    assert "stopped: --init auto: no hand found" in driver.find_element("id",
                                                                         "description").text
    assert "digiteyes: error: --init auto: no hand found in 5 frame(s)" in output
    assert "Traceback" not in output
