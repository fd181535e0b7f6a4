"""The template overlay draws every window outline, its axis and the tint."""

import numpy as np

from digiteyes.kinematics import forward_kinematics
from digiteyes.occlusion.parts import facing_plane, template_parts
from digiteyes.occlusion.segmentation import segment_image
from digiteyes.occlusion.visibility import predict_visibility
from digiteyes.occlusion.windows import image_windows
from digiteyes.synth.scenarios import build_scenario
from digiteyes.viz.templates import draw_templates


def test_overlay_marks_each_window_and_tints_the_segmentation():
    scenario = build_scenario("two-finger-occlusion", n_frames=1)
    model, cam = scenario.model, scenario.rig[0]
    kin = forward_kinematics(model, scenario.states[0])
    parts = template_parts(model)
    windows = image_windows(parts, [facing_plane(p, kin, cam) for p in parts], kin, cam)
    order = predict_visibility(parts, windows, cam)
    labels = segment_image(windows, order, cam.width, cam.height)
    image = np.zeros((cam.height, cam.width), np.uint8)
    plain = draw_templates(image, windows, order)
    tinted = draw_templates(image, windows, order, labels, [p.name for p in parts])
    assert plain.shape == (cam.height, cam.width, 3) and plain.dtype == np.uint8
    for k in range(len(parts)):
        a = np.round(windows.points[k, 0]).astype(int)
        patch = plain[a[1] - 2:a[1] + 3, a[0] - 2:a[0] + 3]
        assert patch.any(), parts[k].name
    assert (tinted[labels >= 0] > 0).any(axis=-1).all()
