"""Model views: view strings, automatic camera placement, shaded and wireframe PNGs."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import load_model
from digiteyes.synth import render_views
from digiteyes.viz.model_view import (
    NAMED_VIEWS,
    ViewError,
    parse_view,
    view_camera,
    write_model_png,
)


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


def test_parse_view_named_and_numeric():
    assert parse_view("front") == (0.0, 0.0, None)
    assert parse_view(" Side ") == (90.0, 0.0, None)
    assert parse_view("30,-20") == (30.0, -20.0, None)
    assert parse_view("10, 5, 700") == (10.0, 5.0, 700.0)


@pytest.mark.parametrize("bad", ["", "sideways", "10", "a,b", "0,100", "0,0,-5", "nan,0",
                                 "1,2,3,4"])
def test_bad_view_strings_raise(bad):
    with pytest.raises(ViewError, match=r"view|elevation|distance"):
        parse_view(bad)


@pytest.mark.parametrize("view, axis", [("front", (0, 0, 1)), ("back", (0, 0, -1)),
                                        ("side", (1, 0, 0)), ("top", (0, 1, 0)),
                                        ("bottom", (0, -1, 0))])
def test_named_views_look_from_their_side(hand, view, axis):
    q = hand.neutral()
    cam = view_camera(hand, q, view)
    forward = cam.T_world_cam[:3, 2]
    np.testing.assert_allclose(-forward, axis, atol=1e-12)
    # fingers (+y) point up in the image for the horizontal views
    if view in ("front", "back", "side"):
        w = cam.project(np.array([[0.0, 0.0, 0.0], [0.0, 50.0, 0.0]]))
        assert w[1, 1] < w[0, 1] - 10


@pytest.mark.parametrize("view", [*NAMED_VIEWS, "200,-40"])
def test_auto_framing_fills_and_centres_the_model(hand, view):
    q = hand.neutral()
    q[hand.state_index("index.mcp")] = 0.8
    cam = view_camera(hand, q, view, width=320, height=240)
    labels = render_views(hand, q, cam)[0].labels
    v, u = np.nonzero(labels >= 0)
    assert u.min() > 0 and v.min() > 0 and u.max() < 319 and v.max() < 239
    span = max((u.max() - u.min()) / 320, (v.max() - v.min()) / 240)
    assert 0.6 < span <= 0.9
    assert abs((u.max() + u.min()) / 2 - 159.5) < 0.15 * 320
    assert abs((v.max() + v.min()) / 2 - 119.5) < 0.15 * 240


def test_explicit_distance_places_the_camera(hand):
    cam = view_camera(hand, hand.neutral(), "0,0,900")
    target_z = 0.0  # the neutral hand's bounding box is centred on z = 0 (palm, fingers)
    assert cam.centre_world[2] - target_z == pytest.approx(900.0, abs=20.0)


@pytest.mark.parametrize("style", ["shaded", "wireframe"])
def test_write_model_png(hand, tmp_path, style):
    path = write_model_png(hand, hand.neutral(), tmp_path / f"{style}.png", view="oblique",
                           style=style, width=200, height=150)
    image = cv2.imread(str(path))
    assert image.shape == (150, 200, 3)
    rgb = cv2.cvtColor(image, cv2.COLOR_BGR2RGB).astype(int)
    background = rgb[0, 0]
    changed = (np.abs(rgb - background).sum(axis=2) > 30).mean()
    assert 0.05 < changed < 0.8
    if style == "shaded":
        skin = rgb[np.abs(rgb - background).sum(axis=2) > 30]
        assert (skin[:, 0] >= skin[:, 2]).mean() > 0.95, "skin is reddish"
    else:
        assert (rgb.sum(axis=2) < 300).any(), "dark outline strokes"


def test_write_model_png_errors(hand, tmp_path):
    with pytest.raises(ViewError, match="style"):
        write_model_png(hand, hand.neutral(), tmp_path / "x.png", style="cartoon")
    with pytest.raises(ViewError, match="view"):
        write_model_png(hand, hand.neutral(), tmp_path / "x.png", view="behind")
    with pytest.raises(DigitEyesError, match="cannot write"):
        write_model_png(hand, hand.neutral(), tmp_path / "missing" / "x.png")


def test_cli_model_render(tmp_path, capsys):
    from digiteyes.cli import main

    out = tmp_path / "hand.png"
    assert main(["model", "render", "hand", "--view", "side", "--size", "160x120",
                 "-o", str(out)]) == 0
    assert cv2.imread(str(out)).shape == (120, 160, 3)
    assert main(["model", "render", "hand", "--view", "upside", "-o", str(out)]) == 2
    assert "view must be one of" in capsys.readouterr().err
