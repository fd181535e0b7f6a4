"""``digiteyes track-many`` on a local Ray of two workers: every input tracked as by
``digiteyes track``, a failing input reported while the others finish, reruns skip what
is done."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.io import read_state_log
from digiteyes.io.safe_paths import distinct_names
from digiteyes.kinematics import load_model
from digiteyes.track_job import TrackJob, run_track_job
from digiteyes.track_many import (
    DONE_MARKER,
    SUMMARY_FILE,
    ClusterError,
    track_many,
)

FRAMES = 4


@pytest.fixture(scope="module")
def local_ray():
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"NUMBA_NUM_THREADS": "1"}})
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    root = tmp_path_factory.mktemp("inputs")
    folders = []
    for seed in (0, 1):
        folder = root / f"mouse-{seed}"
        assert main(["render", "mouse", "-o", str(folder), "--frames", str(FRAMES),
                     "--seed", str(seed)]) == 0
        folders.append(folder)
    empty = root / "empty-video.mp4"
    empty.write_bytes(b"not a video")
    return folders, empty


def test_output_names_are_distinct(tmp_path):
    (tmp_path / "a").mkdir()
    assert distinct_names([str(tmp_path / "a"), "x/b.mp4", "y/b.mp4", "b.avi"]) == \
        ["a", "b", "b-2", "b-3"]
    # an input already named like a suffixed one keeps its name
    assert distinct_names(["x.mp4", "x.avi", "x-2.mp4"]) == ["x", "x-3", "x-2"]


def test_two_workers_track_every_input_and_report_failures(local_ray, datasets, tmp_path):
    folders, broken = datasets
    out = tmp_path / "many"
    template = TrackJob((), str(out), "mouse-hand", str(folders[0] / "rig.json"),
                        str(folders[0] / "initial_state.json"), overlay=False)
    lines: list[str] = []
    summary = track_many([*map(str, folders), str(broken)], out, template, progress=False,
                         echo=lines.append)
    status = {r.input: r.status for r in summary.results}
    assert status == {str(folders[0]): "done", str(folders[1]): "done", str(broken): "failed"}
    failed = summary.failed[0]
    assert "empty-video" in failed.error and "\n" not in failed.error
    assert any(line.startswith("failed") for line in lines)
    model = load_model("mouse-hand")
    for folder in folders:
        assert (out / folder.name / DONE_MARKER).is_file()
        log = read_state_log(out / folder.name / "states.csv", model)
        assert len(log.states) == FRAMES
    assert not (out / "empty-video" / DONE_MARKER).exists()
    # the same function as `digiteyes track`, run here: the same states
    direct = run_track_job(TrackJob((str(folders[1]),), str(tmp_path / "direct"),
                                    overlay=False, progress=False))
    np.testing.assert_allclose(read_state_log(direct.files["states"], model).states,
                               read_state_log(out / folders[1].name / "states.csv",
                                              model).states, atol=1e-9)
    saved = json.loads((out / SUMMARY_FILE).read_text())
    assert [e["status"] for e in saved["inputs"]] == ["done", "done", "failed"]

    # rerun through the CLI: finished inputs are skipped, the broken one fails again
    code = main(["track-many", *map(str, folders), str(broken), "-o", str(out), "--model",
                 "mouse-hand", "--rig", str(folders[0] / "rig.json"), "--init",
                 str(folders[0] / "initial_state.json"), "--no-overlay", "--quiet"])
    assert code == 2
    saved = json.loads((out / SUMMARY_FILE).read_text())
    assert [e["status"] for e in saved["inputs"]] == ["skipped", "skipped", "failed"]
    assert saved["inputs"][0]["frames"] == FRAMES


def test_missing_ray_is_one_clear_error(monkeypatch, datasets, tmp_path, capsys):
    folders, _ = datasets
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(ClusterError, match=r"pip install 'digiteyes\[cluster\]'"):
        track_many([str(folders[0])], tmp_path / "x", TrackJob((), ""), progress=False)
