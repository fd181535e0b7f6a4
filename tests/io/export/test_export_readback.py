"""Exports read back by independent readers: BVH with the ``bvh`` package, glTF with
pygltflib, Parquet with pyarrow, CSV with the csv module; joint positions rebuilt from the
files (our own composition of offsets and rotations) must match forward kinematics."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from bvh import Bvh
from scipy.spatial.transform import Rotation

from digiteyes.errors import StateError
from digiteyes.io.export import build_skeleton, export_track
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.joint_angles import joint_angles_deg
from digiteyes.synth.scenarios import build_scenario

FPS = 10.0


@pytest.fixture(scope="module")
def track():
    scenario = build_scenario("whole-hand")
    states = scenario.states[::20][:8]
    return scenario.model, states


def _fk_joint_positions(model, states, mirrored=False):
    """The skeleton and the model's joint positions (T, J, 3) mm; reflected x -> -x for a
    left hand (the mirror image's right hand, reflected back)."""
    skeleton = build_skeleton(model, mirrored)
    kin = forward_kinematics(model, states)
    positions = kin.T_world_frame[:, list(skeleton.rows), :3, :][..., 3]
    return skeleton, positions * ([-1.0, 1.0, 1.0] if mirrored else 1.0)


def _elementary(axis: str, degrees: np.ndarray) -> np.ndarray:
    return Rotation.from_euler(axis.lower(), degrees, degrees=True).as_matrix()


@pytest.mark.parametrize("mirrored", [False, True])
def test_bvh_forward_kinematics_matches_model(track, tmp_path, mirrored):
    model, states = track
    path = export_track(model, np.arange(len(states)), states, np.zeros(len(states)), FPS,
                        tmp_path, "bvh", mirrored)
    mocap = Bvh(path.read_text())
    assert mocap.nframes == len(states)
    assert mocap.frame_time == pytest.approx(1.0 / FPS)
    skeleton, expected = _fk_joint_positions(model, states, mirrored)
    names = mocap.get_joints_names()
    assert names[0] == "palm" and set(names) == set(skeleton.names)
    for t in range(len(states)):
        world: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name in names:  # parents come before children in the file
            channels = mocap.joint_channels(name)
            values = np.array(mocap.frame_joint_channels(t, name, channels), dtype=float)
            R = np.eye(3)
            for channel, value in zip(channels, values, strict=True):
                if channel.endswith("rotation"):
                    R = R @ _elementary(channel[0], value)
            offset = np.array(mocap.joint_offset(name), dtype=float)
            if name == "palm":
                position = values[:3] + offset
                world[name] = (R, position)
            else:
                R_parent, p_parent = world[mocap.joint_parent(name).name]
                world[name] = (R_parent @ R, p_parent + R_parent @ offset)
        got = np.array([world[n][1] for n in skeleton.names])
        np.testing.assert_allclose(got, expected[t], atol=1e-6)


def _accessor(gltf, index: int) -> np.ndarray:
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    data = gltf.binary_blob()
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[accessor.type]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[accessor.componentType]
    start = view.byteOffset + (accessor.byteOffset or 0)
    return np.frombuffer(data, dtype=dtype, count=accessor.count * width,
                         offset=start).reshape(accessor.count, width)


@pytest.mark.parametrize("mirrored", [False, True])
def test_gltf_node_animation_matches_model(track, tmp_path, mirrored):
    pygltflib = pytest.importorskip("pygltflib")
    model, states = track
    path = export_track(model, np.arange(len(states)), states, np.zeros(len(states)), FPS,
                        tmp_path, "gltf", mirrored)
    gltf = pygltflib.GLTF2().load(str(path))
    skeleton, expected = _fk_joint_positions(model, states, mirrored)
    animation = gltf.animations[0]
    rotation = {}
    translation = {}
    times = None
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        times = _accessor(gltf, sampler.input)[:, 0]
        values = _accessor(gltf, sampler.output).astype(float)
        (rotation if channel.target.path == "rotation" else translation)[
            channel.target.node] = values
    np.testing.assert_allclose(times, np.arange(len(states)) / FPS, atol=1e-6)
    by_name = {node.name: i for i, node in enumerate(gltf.nodes)}
    parent = {c: i for i, node in enumerate(gltf.nodes) for c in (node.children or [])}
    for t in range(len(states)):
        world: dict[int, tuple[np.ndarray, np.ndarray]] = {}

        def pose(i: int, t: int = t, world: dict = world) -> tuple[np.ndarray, np.ndarray]:
            if i not in world:
                node = gltf.nodes[i]
                R = Rotation.from_quat(rotation[i][t]).as_matrix()
                p = translation[i][t] if i in translation else np.array(node.translation)
                if i in parent:
                    R_parent, p_parent = pose(parent[i])
                    world[i] = (R_parent @ R, p_parent + R_parent @ p)
                else:
                    world[i] = (R, p)
            return world[i]

        got = np.array([pose(by_name[n])[1] for n in skeleton.names]) * 1000.0
        got_zup = got @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]).T  # (x, y, z) <- (x, -z, y)
        np.testing.assert_allclose(got_zup, expected[t], atol=0.02)  # float32 in metres
    skin = gltf.skins[0]
    assert len(skin.joints) == len(skeleton)
    inverse_bind = _accessor(gltf, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    bind_positions = -np.einsum("jik,jk->ji", inverse_bind[:, :3, :3].transpose(0, 2, 1),
                                inverse_bind[:, :3, 3]) * 1000.0
    np.testing.assert_allclose(bind_positions @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]).T,
                               expected[0], atol=0.02)
    positions = _accessor(gltf, gltf.meshes[0].primitives[0].attributes.POSITION)
    assert len(positions) > 0


def test_tables_csv_and_parquet(track, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    model, states = track
    lost = np.zeros(len(states), dtype=bool)
    lost[3] = True
    frames = np.arange(len(states)) * 20
    csv_path = export_track(model, frames, states, lost, FPS, tmp_path, "csv")
    pq_path = export_track(model, frames, states, lost, FPS, tmp_path, "parquet")
    with open(csv_path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    table = pq.read_table(pq_path).to_pydict()
    names, degrees = joint_angles_deg(model, states)
    _, positions = _fk_joint_positions(model, states)
    for source in (rows, [dict(zip(table, values, strict=True))
                          for values in zip(*table.values(), strict=True)]):
        assert [int(r["frame"]) for r in source] == frames.tolist()
        assert [int(r["lost"]) for r in source] == lost.astype(int).tolist()
        got_states = np.array([[float(r[n]) for n in model.state_names] for r in source])
        np.testing.assert_allclose(got_states, states, rtol=0, atol=1e-12)
        got_angles = np.array([[float(r[f"{n}_deg"]) for n in names] for r in source])
        np.testing.assert_allclose(got_angles, degrees, atol=1e-9)
        tip = np.array([[float(r[f"index.tip_{a}_mm"]) for a in "xyz"] for r in source])
        row = list(build_skeleton(model).names).index("index_tip")
        np.testing.assert_allclose(tip, positions[:, row], atol=1e-9)


def test_models_with_prismatic_states_are_refused(tmp_path):
    model = load_model("mouse-hand")
    with pytest.raises(StateError, match="prismatic"):
        export_track(model, [0], model.neutral()[None], [False], FPS, tmp_path, "bvh")


def _gltf_validator_folder() -> Path | None:
    """The npm ``gltf-validator`` package: under DIGITEYES_GLTF_VALIDATOR
    (``npm install --prefix DIR gltf-validator``) or installed globally (``npm install -g``,
    as ``.ci/run`` does)."""
    if not shutil.which("node"):
        return None
    if os.environ.get("DIGITEYES_GLTF_VALIDATOR"):
        folder = Path(os.environ["DIGITEYES_GLTF_VALIDATOR"]) / "node_modules" / "gltf-validator"
        return folder if folder.is_dir() else None
    npm = shutil.which("npm")
    if not npm:
        return None
    root = subprocess.run([npm, "root", "-g"], capture_output=True, text=True, timeout=60)
    folder = Path(root.stdout.strip()) / "gltf-validator"
    return folder if root.returncode == 0 and folder.is_dir() else None


@pytest.mark.parametrize("mirrored", [False, True])
def test_gltf_passes_the_khronos_validator(track, tmp_path, mirrored):
    """The Khronos glTF-Validator (npm ``gltf-validator``), which ``.ci/run`` installs; a
    left hand's file too."""
    folder = _gltf_validator_folder()
    if folder is None:
        pytest.skip("needs node and the npm gltf-validator (npm install -g gltf-validator)")
    model, states = track
    path = export_track(model, np.arange(len(states)), states, np.zeros(len(states)), FPS,
                        tmp_path, "gltf", mirrored)
    package = json.dumps(str(folder))
    script = (f"const v = require({package});"
              "const fs = require('fs');"
              f"v.validateBytes(new Uint8Array(fs.readFileSync({json.dumps(str(path))})))"
              ".then(r => console.log(JSON.stringify(r.issues)))"
              ".catch(e => { console.error(e); process.exit(1); });")
    done = subprocess.run(["node", "-e", script], capture_output=True, text=True, timeout=60,
                          check=True)
    issues = json.loads(done.stdout)
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
