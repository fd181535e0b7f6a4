"""Real-data benchmark on the STB stereo sample (Stereo Tracking Benchmark, B1Counting, BB rig).

Usage::

    python benchmarks/real_stb.py [--data ../shared/data] [--json FILE] [--out DIR]

What it measures (docs/real-data.md explains the set-up and the results):

1. **Model adequacy.** The shipped ``hand`` model (Rehg's hand, thesis Appendix A) is fitted
   to the 21 STB 3D joints by Gauss-Newton on 3D point residuals (mm): nominal model, the
   model scaled by one global factor, and variants that show the correspondence choices
   (fingertip sphere centre vs finger end; the unmirrored left hand). Then all 1500 frames
   of the sequence are fitted with the scaled model, warm-starting from the previous frame.
2. **Image measurement on real clutter.** At the frame-0 fit, link lines and tip points are
   measured in both images (``measure_features``); the ``FeatureTracker`` then runs 10
   Gauss-Newton iterations on the stereo pair from the fit and from seeded perturbations of
   it, and the 3D joint error against the STB labels is reported before and after.

STB shows the subject's **left** hand (palm towards the camera, thumb on the image's left);
the model is a right hand. The benchmark mirrors the world (x -> -x) and flips the images
left-right, with the principal point moved to ``W - 1 - cx``: an exact equivalence (checked
by projection), after which the right-hand model applies.

The data are read from ``<data>/stb_sample``; nothing derived from them is stored in the
package. Without the folder the script prints why and exits with status 0.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import scipy.io

from digiteyes import load_model
from digiteyes.camera import Camera, Rig
from digiteyes.camera.mirror import mirrored_rig, unmirror_points
from digiteyes.features import FeatureOptions, feature_residuals, measure_features, prepare_image
from digiteyes.kinematics import (
    KinematicModel,
    clip_to_limits,
    difference,
    forward_kinematics,
    integrate,
    point_jacobian,
)
from digiteyes.kinematics.keypoints import keypoint_names
from digiteyes.kinematics.procrustes import kabsch
from digiteyes.kinematics.rotations import quaternion_from_matrix
from digiteyes.kinematics.scaling import scaled_model
from digiteyes.solvers import GaussNewtonOptions, gauss_newton
from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions
from digiteyes.viz.overlay import draw_features

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SAMPLE = "stb_sample"
LABELS = "labels/B1Counting_BB.mat"
IMAGES = ("images/B1Counting/BB_left_0.png", "images/B1Counting/BB_right_0.png")

# STB joint order (verified by projection, docs/real-data.md): 0 palm centre, then MCP ->
# tip for little (1-4), ring (5-8), middle (9-12), index (13-16), thumb base -> tip (17-20).
STB_JOINTS = (
    "palm",
    *(f"{finger}.{part}" for finger in ("little", "ring", "middle", "index")
      for part in ("proximal.base", "middle.base", "distal.base", "tip")),
    "thumb.metacarpal.base", "thumb.proximal.base", "thumb.distal.base", "thumb.tip",
)
STB_FINGERS = {"palm": [0], "little": [1, 2, 3, 4], "ring": [5, 6, 7, 8],
               "middle": [9, 10, 11, 12], "index": [13, 14, 15, 16],
               "thumb": [17, 18, 19, 20]}
# Joints fixed in the palm frame: the Kabsch/Procrustes initialisation uses them.
PALM_JOINTS = (0, 1, 5, 9, 13)


# ----------------------------------------------------------------------------- data
def load_stb(data_dir: Path) -> dict | None:
    """Labels (N, 21, 3) mm in the left camera frame, camera parameters and the two images
    (RGB uint8) of frame 0, or None when the sample is absent."""
    root = Path(data_dir) / SAMPLE
    if not (root / LABELS).is_file():
        return None
    hand = scipy.io.loadmat(root / LABELS)["handPara"]  # (3, 21, N)
    params = json.loads((root / "camera_params.json").read_text())["BB2Stereo"]
    images = []
    for name in IMAGES:
        bgr = cv2.imread(str(root / name), cv2.IMREAD_COLOR)
        if bgr is None:
            raise FileNotFoundError(root / name)
        images.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    return {"joints": np.transpose(hand, (2, 1, 0)).astype(float), "camera": params,
            "images": images, "root": str(root)}


def stb_rig(params: dict, width: int = 640, height: int = 480, mirrored: bool = False) -> Rig:
    """The BB stereo rig with the left camera as the world frame.

    The right camera is the left one translated by the baseline along +x, so its
    ``T_cam_world`` has ``t = (-baseline, 0, 0)``. ``mirrored=True`` gives the rig that sees
    the mirrored world (x -> -x) in left-right flipped images
    (:func:`digiteyes.camera.mirror.mirrored_rig`).
    """
    K = np.array([[params["fx"], 0.0, params["tx"]], [0.0, params["fy"], params["ty"]],
                  [0.0, 0.0, 1.0]])
    T_right = np.eye(4)
    T_right[0, 3] = -params["baseline"]
    rig = Rig((Camera.create("left", K, width, height, np.eye(4)),
               Camera.create("right", K, width, height, T_right)))
    return mirrored_rig(rig) if mirrored else rig


def mirror(points: np.ndarray) -> np.ndarray:
    """Mirror points (..., 3) in the camera's y-z plane (x -> -x)."""
    return unmirror_points(points)


# ----------------------------------------------------------------------------- model
def joint_points(model: KinematicModel, tip_at_end: bool) -> tuple[np.ndarray, np.ndarray]:
    """Shape-frame rows and points (21, 3) mm of the model joints matching the STB joints.

    The points are those of :func:`digiteyes.kinematics.keypoints.keypoints` (link bases, tip
    sphere centres, palm box centre). With ``tip_at_end`` a fingertip is the end of the
    finger instead (the STB labels mark the end): the tip centre moved along the distal
    axis by the end radius ``max(tip radius, distal radius)``, the capsule's cap.
    """
    names = keypoint_names(model)
    links = [model.links[names.index(name)] for name in STB_JOINTS]
    radius_of = {link.name: link.radius for link in model.links}
    rows, points = [], []
    for link in links:
        rows.append(link.row)
        if link.kind == "palm":
            points.append(link.centre)
        elif link.kind == "tip" and tip_at_end:
            distal = link.name.replace(".tip", ".distal")
            points.append((max(link.radius, radius_of[distal]), 0.0, 0.0))
        else:
            points.append((0.0, 0.0, 0.0))
    return np.array(rows), np.array(points, dtype=float)


def model_joints(model: KinematicModel, q: np.ndarray, tip_at_end: bool = True) -> np.ndarray:
    """The model's 21 STB-ordered joints (21, 3) mm at state ``q``."""
    rows, points = joint_points(model, tip_at_end)
    return forward_kinematics(model, q).points(rows, points)


class JointFitProblem:
    """3D joint residuals ``s * p_k(q) - y_k`` (mm) as a LeastSquaresProblem.

    ``x = (q, s)``: ``q`` is a state of the *unscaled* model and ``s`` a global scale, so the
    points of the scaled model (:func:`scaled_model`) are ``s * p(q)`` at the state whose
    translation is ``s`` times ``q``'s. With ``fit_scale=False`` the scale is held; the step
    then has ``n_v`` of the model, otherwise one more (d r / d s = p(q), exact).
    """

    def __init__(self, model: KinematicModel, target: np.ndarray, fit_scale: bool,
                 tip_at_end: bool) -> None:
        self.model = model
        self.target = np.asarray(target, dtype=float)
        self.fit_scale = fit_scale
        self.rows, self.points = joint_points(model, tip_at_end)
        self.n_v = model.n_v + int(fit_scale)

    def residuals(self, x: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        q, s = x[:-1], x[-1]
        p, J = point_jacobian(forward_kinematics(self.model, q), self.rows, self.points)
        r = (s * p - self.target).ravel()
        if not jacobian:
            return r, None
        J = s * J.reshape(len(r), self.model.n_v)
        if self.fit_scale:
            J = np.hstack([J, p.reshape(-1, 1)])
        return r, J

    def retract(self, x: np.ndarray, dv: np.ndarray) -> np.ndarray:
        s = x[-1] + (dv[-1] if self.fit_scale else 0.0)
        return np.append(integrate(self.model, x[:-1], dv[:self.model.n_v]), s)

    def project(self, x: np.ndarray) -> np.ndarray:
        return np.append(clip_to_limits(self.model, x[:-1]), max(x[-1], 0.1))


def initial_state(model: KinematicModel, target: np.ndarray, scale: float) -> np.ndarray:
    """Neutral joints with the palm pose from a Kabsch fit of the palm-fixed joints (palm
    centre and the four MCPs) of the model scaled by ``scale`` to ``target``."""
    q = model.neutral()
    palm = model_joints(model, q)[list(PALM_JOINTS)]  # palm frame = world at the neutral pose
    R, t, _ = kabsch(scale * palm, target[list(PALM_JOINTS)])
    base = model.base_state
    q[base:base + 4] = quaternion_from_matrix(R)
    q[base + 4:base + 7] = t / scale
    return q


def fit_joints(model: KinematicModel, target: np.ndarray, *, fit_scale: bool,
               tip_at_end: bool, scale: float = 1.0, x0: np.ndarray | None = None,
               iterations: int = 100) -> tuple[np.ndarray, float, np.ndarray, int]:
    """Fit the model to one frame of joints. Returns the state of the (scaled) model, the
    scale, the per-joint residual distances (21,) mm and the solver iterations."""
    problem = JointFitProblem(model, target, fit_scale, tip_at_end)
    if x0 is None:
        x0 = np.append(initial_state(model, target, scale), scale)
    options = GaussNewtonOptions(max_iterations=iterations, damping="levenberg-marquardt",
                                 step_tolerance=1e-9, cost_tolerance=1e-12)
    x, summary = gauss_newton(problem, x0, options)
    r, _ = problem.residuals(x, False)
    distances = np.linalg.norm(r.reshape(-1, 3), axis=1)
    return x, float(x[-1]), distances, summary.iterations


def scaled_state(model: KinematicModel, x: np.ndarray) -> np.ndarray:
    """The state of ``scaled_model(model, s)`` equivalent to ``x = (q, s)``."""
    q = np.array(x[:-1])
    k = model.base_state
    q[k + 4:k + 7] *= x[-1]
    return q


def summary_mm(distances: np.ndarray) -> dict:
    return {"rms_mm": float(np.sqrt(np.mean(distances ** 2))),
            "max_mm": float(distances.max()),
            "worst_joint": STB_JOINTS[int(np.argmax(distances))]}


# ----------------------------------------------------------------------------- stage 1
def model_adequacy(model: KinematicModel, joints: np.ndarray) -> dict:
    frame0 = mirror(joints[0])
    variants = {}
    specs = [
        ("nominal, tip = sphere centre", False, False, frame0),
        ("nominal, tip = finger end", False, True, frame0),
        ("scaled, tip = sphere centre", True, False, frame0),
        ("scaled, tip = finger end", True, True, frame0),
        ("scaled, finger end, NOT mirrored", True, True, joints[0]),
    ]
    fits = {}
    for name, fit_scale, tip_at_end, target in specs:
        x, s, dist, iters = fit_joints(model, target, fit_scale=fit_scale, tip_at_end=tip_at_end)
        variants[name] = {**summary_mm(dist), "scale": s, "iterations": iters,
                          "per_finger_rms_mm": {f: float(np.sqrt(np.mean(dist[i] ** 2)))
                                                for f, i in STB_FINGERS.items()}}
        fits[name] = (x, dist)
    x_best, dist_best = fits["scaled, tip = finger end"]
    per_joint = {name: float(d) for name, d in zip(STB_JOINTS, dist_best, strict=True)}
    return {"variants": variants, "per_joint_mm": per_joint, "x": x_best}


def sequence_fit(model: KinematicModel, joints: np.ndarray, scale: float, x0: np.ndarray,
                 mirrored: bool = True, step: int = 1) -> dict:
    """Fit every ``step``-th frame with the scale held, warm-starting from the previous one
    (``mirrored=False`` fits the right-hand model to the unmirrored left hand)."""
    start = time.perf_counter()
    targets = mirror(joints[::step]) if mirrored else joints[::step]
    n = len(targets)
    rms, worst, per_joint = np.empty(n), np.empty(n), np.empty((n, len(STB_JOINTS)))
    iterations = np.empty(n, dtype=int)
    x = np.array(x0)
    x[-1] = scale
    for i, target in enumerate(targets):
        x, _, dist, iterations[i] = fit_joints(model, target, fit_scale=False, tip_at_end=True,
                                               scale=scale, x0=x, iterations=30)
        rms[i], worst[i] = np.sqrt(np.mean(dist ** 2)), dist.max()
        per_joint[i] = dist
    seconds = time.perf_counter() - start
    finger = {f: float(np.median(np.sqrt(np.mean(per_joint[:, i] ** 2, axis=1))))
              for f, i in STB_FINGERS.items()}
    return {
        "frames": n, "step": step, "mirrored": mirrored, "seconds": seconds,
        "mean_iterations": float(iterations.mean()),
        "rms_median_mm": float(np.median(rms)), "rms_p95_mm": float(np.percentile(rms, 95)),
        "rms_max_mm": float(rms.max()), "worst_frame": int(np.argmax(rms)) * step,
        "joint_median_mm": float(np.median(per_joint)),
        "joint_p95_mm": float(np.percentile(per_joint, 95)),
        "max_median_mm": float(np.median(worst)), "max_p95_mm": float(np.percentile(worst, 95)),
        "per_finger_median_rms_mm": finger,
        "rms_series_mm": rms.round(3).tolist(),
    }


# ----------------------------------------------------------------------------- stage 2
def projection_check(rig: Rig, rig_m: Rig, joints0: np.ndarray, width: int) -> dict:
    """Pixels of the labels in both images, and the mirrored set-up's agreement (px)."""
    result = {}
    for cam, cam_m in zip(rig, rig_m, strict=True):
        w = cam.project(joints0)
        w_m = cam_m.project(mirror(joints0))
        result[cam.name] = {
            "min_px": w.min(0).round(1).tolist(), "max_px": w.max(0).round(1).tolist(),
            "mirror_error_px": float(np.abs((width - 1 - w_m[:, 0]) - w[:, 0]).max()
                                     + np.abs(w_m[:, 1] - w[:, 1]).max()),
        }
    return result


def measure_at(model: KinematicModel, q: np.ndarray, rig: Rig, images: list[np.ndarray],
               features: FeatureOptions) -> tuple[dict, list]:
    kin = forward_kinematics(model, q)
    out, measurements = {}, []
    r_all = []
    for cam, image in zip(rig, images, strict=True):
        meas = measure_features(prepare_image(image), cam, model, kin, features)
        r, _, layout = feature_residuals(meas, cam, kin, jacobian=False)
        r_all.append(r)
        measurements.append((meas, layout))
        reasons = {}
        for reason in [*meas.link_reason, *meas.tip_reason]:
            reasons[str(reason)] = reasons.get(str(reason), 0) + 1
        out[cam.name] = {"links_valid": int(meas.link_valid.sum()),
                         "links": len(meas.link_valid),
                         "tips_valid": int(meas.tip_valid.sum()), "tips": len(meas.tip_valid),
                         "residual_rms_px": float(np.sqrt(np.mean(r ** 2))) if len(r) else None,
                         "reasons": reasons}
    r = np.concatenate(r_all)
    n_valid = sum(v["links_valid"] + v["tips_valid"] for v in out.values())
    n_all = sum(v["links"] + v["tips"] for v in out.values())
    out["valid_fraction"] = n_valid / n_all
    out["residual_rms_px"] = float(np.sqrt(np.mean(r ** 2))) if len(r) else None
    return out, measurements


def perturb(model: KinematicModel, q: np.ndarray, rng: np.random.Generator,
            joint_deg: float, rotation_deg: float, translation_mm: float) -> np.ndarray:
    """Joints moved by U(-joint_deg, joint_deg) each; the palm turned by rotation_deg about a
    random axis and shifted by translation_mm in a random direction."""
    dv = np.zeros(model.n_v)
    k = model.base_state
    axis = rng.normal(size=3)
    shift = rng.normal(size=3)
    dv[k:k + 3] = np.radians(rotation_deg) * axis / np.linalg.norm(axis)
    dv[k + 3:k + 6] = translation_mm * shift / np.linalg.norm(shift)
    joints = np.ones(model.n_v, dtype=bool)
    joints[k:k + 6] = False
    dv[joints] = np.radians(rng.uniform(-joint_deg, joint_deg, joints.sum()))
    return clip_to_limits(model, integrate(model, q, dv))


def joint_error(model: KinematicModel, q: np.ndarray, truth: np.ndarray) -> dict:
    d = np.linalg.norm(model_joints(model, q) - truth, axis=1)
    return {"rms_mm": float(np.sqrt(np.mean(d ** 2))), "max_mm": float(d.max()),
            "tips_rms_mm": float(np.sqrt(np.mean(d[[4, 8, 12, 16, 20]] ** 2)))}


def track_once(model: KinematicModel, rig: Rig, images: list[np.ndarray], q0: np.ndarray,
               q_fit: np.ndarray, truth: np.ndarray, features: FeatureOptions
               ) -> tuple[dict, object]:
    tracker = FeatureTracker(model, rig, FeatureTrackerOptions(iterations_per_frame=10,
                                                               features=features))
    tracker.reset(q0)
    result = tracker.step(images)
    k = model.base_state
    fit_to_end = difference(model, q_fit, result.state)
    return {"palm_turn_from_fit_deg": np.degrees(fit_to_end[k:k + 3]).round(2).tolist(),
            "palm_shift_from_fit_mm": fit_to_end[k + 3:k + 6].round(2).tolist(),
            "before": joint_error(model, q0, truth), "after": joint_error(model, result.state,
                                                                          truth),
            "residual_rms_px": float(result.residual_rms_px),
            "valid_features": int(result.details.n_valid_links + result.details.n_valid_tips),
            "features": int(result.details.n_features), "lost": bool(result.lost),
            "loss_reason": result.loss_reason, "seconds": float(result.timings["total"])}, result


def image_stage(model: KinematicModel, data: dict, x_fit: np.ndarray, trials: int,
                out_dir: Path | None) -> dict:
    params = data["camera"]
    height, width = data["images"][0].shape[:2]
    rig = stb_rig(params, width, height)
    rig_m = stb_rig(params, width, height, mirrored=True)
    flipped = [np.ascontiguousarray(im[:, ::-1]) for im in data["images"]]
    truth = mirror(data["joints"][0])
    hand = scaled_model(model, x_fit[-1])
    q_fit = scaled_state(model, x_fit)
    result = {"projection": projection_check(rig, rig_m, data["joints"][0], width),
              "fit_error": joint_error(hand, q_fit, truth), "measure": {}}
    at_fit = {}
    for polarity in (True, False):
        features = FeatureOptions(bright_object=polarity)
        measured, at_fit[polarity] = measure_at(hand, q_fit, rig_m, flipped, features)
        result["measure"]["bright hand" if polarity else "dark hand"] = measured
    bright = max((True, False), key=lambda b: result["measure"][
        "bright hand" if b else "dark hand"]["valid_fraction"])
    features = FeatureOptions(bright_object=bright)
    result["polarity_used"] = "bright hand" if bright else "dark hand"
    from_fit, res_fit = track_once(hand, rig_m, flipped, q_fit, q_fit, truth, features)
    result["track_from_fit"] = from_fit
    runs = []
    res_first = None
    for seed in range(trials):
        q0 = perturb(hand, q_fit, np.random.default_rng(seed), 5.0, 3.0, 4.0)
        run, res = track_once(hand, rig_m, flipped, q0, q_fit, truth, features)
        runs.append(run)
        if seed == 0:
            res_first = (q0, res)
    result["track_from_perturbed"] = runs
    result["perturbation"] = "joints U(-5, 5) deg each, palm 3 deg about a random axis, 4 mm"
    if out_dir is not None:
        result["images"] = write_images(out_dir, hand, q_fit, truth, rig_m, flipped,
                                        at_fit[bright], res_fit, res_first)
    return result


# ----------------------------------------------------------------------------- pictures
CROP = ((140, 420, 360, 560), (140, 420, 210, 410))  # y0, y1, x0, x1 per original image


def _unflip_crop(image: np.ndarray, index: int, scale: int) -> np.ndarray:
    """Flip an overlay (drawn on the flipped image) back and crop it round the hand."""
    y0, y1, x0, x1 = CROP[index]
    back = image[:, ::-1]
    return np.ascontiguousarray(back[y0 * scale:y1 * scale, x0 * scale:x1 * scale])


def _label(image: np.ndarray, text: str) -> np.ndarray:
    cv2.putText(image, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 0), 1,
                cv2.LINE_AA)
    return image


def _save_png(path: Path, rgb: np.ndarray, colours: int = 96) -> int:
    """Write a palette PNG (keeps photos of cloth under 200 KB); returns the size in bytes."""
    from PIL import Image

    Image.fromarray(rgb).quantize(colours, method=Image.Quantize.MEDIANCUT).save(
        path, optimize=True)
    return path.stat().st_size


def _wireframe(image: np.ndarray, model: KinematicModel, q: np.ndarray, cam: Camera,
               truth: np.ndarray, scale: int) -> np.ndarray:
    """Model axes, capsule sides, tips, palm box and the STB labels on a magnified image."""
    canvas = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
    kin = forward_kinematics(model, q)
    T = kin.T_world_shape[0]

    def px(p):
        return tuple(round(float(v)) for v in (np.asarray(p) + 0.5) * scale - 0.5)

    for link in model.links:
        R, o = T[link.row][:3, :3], T[link.row][:3, 3]
        if link.kind == "link":
            end = o + link.length * R[:, 0]
            a, b = cam.project(np.stack([o, end]))
            cv2.line(canvas, px(a), px(b), (0, 255, 255), 2, cv2.LINE_AA)
            ray = o - cam.centre_world
            side = np.cross(R[:, 0], ray)
            side = link.radius * side / np.linalg.norm(side)
            for sign in (-1.0, 1.0):
                a, b = cam.project(np.stack([o + sign * side, end + sign * side]))
                cv2.line(canvas, px(a), px(b), (0, 200, 255), 1, cv2.LINE_AA)
        elif link.kind == "tip":
            c = cam.project(o)
            r = cam.K[0, 0] * link.radius / cam.depth(o)
            cv2.circle(canvas, px(c), round(float(r) * scale), (0, 200, 255), 1, cv2.LINE_AA)
        else:
            signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
            corners = cam.project(o + (np.asarray(link.centre) + 0.5 * signs
                                       * np.asarray(link.size)) @ R.T)
            for i in range(8):
                for j in range(i + 1, 8):
                    if np.abs(signs[i] - signs[j]).sum() == 2:
                        cv2.line(canvas, px(corners[i]), px(corners[j]), (255, 160, 0), 1,
                                 cv2.LINE_AA)
    model_pts, truth_pts = cam.project(model_joints(model, q)), cam.project(truth)
    for m, t in zip(model_pts, truth_pts, strict=True):
        cv2.line(canvas, px(m), px(t), (255, 0, 0), 1, cv2.LINE_AA)
        cv2.circle(canvas, px(t), 3, (0, 255, 0), -1, cv2.LINE_AA)
        cv2.circle(canvas, px(m), 2, (255, 0, 255), -1, cv2.LINE_AA)
    return canvas


def write_images(out_dir: Path, model: KinematicModel, q_fit: np.ndarray, truth: np.ndarray,
                 rig: Rig, images: list[np.ndarray], measured_at_fit: list, res_fit,
                 res_first) -> dict:
    """The three overlay PNGs of docs/real-data.md; returns their sizes in bytes."""
    out_dir.mkdir(parents=True, exist_ok=True)
    scale = 2
    sizes = {}

    def wire(q: np.ndarray, title: str) -> np.ndarray:
        drawn = _wireframe(images[0], model, q, rig[0], truth, scale)
        return _label(_unflip_crop(drawn, 0, scale), title)

    path = out_dir / "real-stb-fit.png"
    sizes[path.name] = _save_png(path, wire(q_fit, "left: fit to the STB joints"))
    panels = []
    for index, (cam, image) in enumerate(zip(rig, images, strict=True)):
        meas, layout = measured_at_fit[index]
        drawn = draw_features(image, meas, None, layout, scale=scale, show_slices=False)
        panels.append(_label(_unflip_crop(drawn, index, scale), f"{cam.name}: features at fit"))
    path = out_dir / "real-stb-features.png"
    sizes[path.name] = _save_png(path, np.hstack(panels))
    q0, res = res_first
    path = out_dir / "real-stb-tracked.png"
    sizes[path.name] = _save_png(path, np.hstack([
        wire(res_fit.state, "fit + 10 iterations"), wire(q0, "perturbed start"),
        wire(res.state, "perturbed + 10 iterations")]))
    return sizes


# ----------------------------------------------------------------------------- report
def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__}


def format_table(result: dict) -> str:
    m = result["machine"]
    lines = [f"STB B1Counting (BB stereo), real data from {result['data']}",
             f"machine: {m['cpu']}, {m['cores']} cores, python {m['python']}, "
             f"numpy {m['numpy']}", "", "1. model adequacy, frame 0 (3D joint residuals, mm)",
             f"  {'variant':<34} {'scale':>6} {'RMS':>6} {'max':>6}  worst joint"]
    for name, v in result["adequacy"]["variants"].items():
        lines.append(f"  {name:<34} {v['scale']:6.3f} {v['rms_mm']:6.1f} {v['max_mm']:6.1f}"
                     f"  {v['worst_joint']}")
    seq = result["sequence"]
    lines += ["", f"  all {seq['frames']} frames, scale held, warm start "
              f"({seq['seconds']:.1f} s, {seq['mean_iterations']:.1f} iterations/frame):",
              f"  {'':<22} {'median':>7} {'95th pct':>9} {'max':>7}",
              f"  {'per-frame RMS (mm)':<22} {seq['rms_median_mm']:7.1f} "
              f"{seq['rms_p95_mm']:9.1f} {seq['rms_max_mm']:7.1f}",
              f"  {'per-frame max (mm)':<22} {seq['max_median_mm']:7.1f} "
              f"{seq['max_p95_mm']:9.1f}",
              f"  {'single joint (mm)':<22} {seq['joint_median_mm']:7.1f} "
              f"{seq['joint_p95_mm']:9.1f}",
              "  median RMS per finger: " + ", ".join(
                  f"{f} {v:.1f}" for f, v in seq["per_finger_median_rms_mm"].items())]
    raw = result.get("sequence_unmirrored")
    if raw:
        lines.append(f"  right-hand model on the UNMIRRORED left hand (every {raw['step']}th "
                     f"frame): per-frame RMS median {raw['rms_median_mm']:.1f}, 95th pct "
                     f"{raw['rms_p95_mm']:.1f}, max {raw['rms_max_mm']:.1f} mm")
    img = result.get("images")
    if img:
        lines += ["", "2. image measurement at the frame-0 fit (mirrored world, flipped images)",
                  "  labels projected: " + ", ".join(
                      f"{c} x {v['min_px'][0]:.0f}..{v['max_px'][0]:.0f} px, y "
                      f"{v['min_px'][1]:.0f}..{v['max_px'][1]:.0f} px, mirror check "
                      f"{v['mirror_error_px']:.1e} px" for c, v in img["projection"].items()),
                  f"  {'polarity':<12} {'left links/tips':>16} {'right links/tips':>17}"
                  f" {'valid':>6} {'RMS px':>7}"]
        for name, v in img["measure"].items():
            rms = v["residual_rms_px"]
            lines.append(
                f"  {name:<12} {v['left']['links_valid']:>7}/{v['left']['links']} "
                f"{v['left']['tips_valid']}/{v['left']['tips']:<5} "
                f"{v['right']['links_valid']:>8}/{v['right']['links']} "
                f"{v['right']['tips_valid']}/{v['right']['tips']:<5}"
                f"{100 * v['valid_fraction']:5.0f}% {rms if rms is None else f'{rms:7.2f}'}")
        lines += [f"  FeatureTracker, 10 iterations on the pair ({img['polarity_used']}):",
                  f"  {'start':<16} {'RMS before':>10} {'after':>7} {'max before':>11} "
                  f"{'after':>7} {'tips after':>10} {'res px':>7} {'valid':>7} {'lost':>5}"
                  "  palm turn vs fit (deg)"]
        runs = [("fit", img["track_from_fit"])] + [
            (f"perturbed #{i}", r) for i, r in enumerate(img["track_from_perturbed"])]
        for name, r in runs:
            lines.append(
                f"  {name:<16} {r['before']['rms_mm']:10.1f} {r['after']['rms_mm']:7.1f} "
                f"{r['before']['max_mm']:11.1f} {r['after']['max_mm']:7.1f} "
                f"{r['after']['tips_rms_mm']:10.1f} {r['residual_rms_px']:7.2f} "
                f"{r['valid_features']:>3}/{r['features']:<3} {r['lost']!s:>5}  "
                + " ".join(f"{a:+.1f}" for a in r["palm_turn_from_fit_deg"]))
    return "\n".join(lines)


def run(data_dir: Path, json_path: str | None = None, out_dir: Path | None = None,
        trials: int = 5, sequence: bool = True) -> dict | None:
    """Run the benchmark; returns the result dict, or None when the data are absent."""
    data = load_stb(data_dir)
    if data is None:
        return None
    model = load_model("hand")
    result: dict = {"data": data["root"], "machine": machine()}
    adequacy = model_adequacy(model, data["joints"])
    x_fit = adequacy.pop("x")
    result["adequacy"] = adequacy
    if sequence:
        result["sequence"] = sequence_fit(model, data["joints"], float(x_fit[-1]), x_fit)
        variant = adequacy["variants"]["scaled, finger end, NOT mirrored"]
        x_raw, _, _, _ = fit_joints(model, data["joints"][0], fit_scale=True, tip_at_end=True)
        unmirrored = sequence_fit(model, data["joints"], variant["scale"], x_raw,
                                  mirrored=False, step=5)
        unmirrored.pop("rms_series_mm")
        result["sequence_unmirrored"] = unmirrored
    result["images"] = image_stage(model, data, x_fit, trials, out_dir)
    if json_path:
        Path(json_path).write_text(json.dumps(result, indent=1))
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA,
                        help="folder holding stb_sample/ (default: ../shared/data)")
    parser.add_argument("--json", help="write the results to this JSON file")
    parser.add_argument("--out", type=Path, help="write the overlay PNGs into this folder")
    parser.add_argument("--trials", type=int, default=5, help="perturbed starts (seeds 0..)")
    args = parser.parse_args(argv)
    result = run(args.data, args.json, args.out, args.trials)
    if result is None:
        print(f"STB sample not found under {args.data / SAMPLE}: nothing to measure (the real "
              "data live beside the project, not in it)")
        return 0
    print(format_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
