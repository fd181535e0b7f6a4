"""Every command on a table of bad inputs (issue 12): exactly one line
``digiteyes: error: ...`` on stderr, exit code 2, and nothing written outside the output
folder (the whole scratch tree is snapshotted before and after)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from digiteyes.cli import main

# Each row: the arguments, with {w} the scratch folder holding the bad inputs and {o} the
# output folder, which may be written.
CASES = {
    # global
    "no command option": ["--bogus"],
    # demo
    "demo bad scenario": ["demo", "-o", "{o}", "--scenario", "bogus"],
    "demo frames 0": ["demo", "-o", "{o}", "--frames", "0"],
    "demo over a file": ["demo", "-o", "{w}/model.dh", "--frames", "2"],
    "demo foreign folder": ["demo", "-o", "{w}/foreign", "--frames", "2"],
    # model
    "model show missing": ["model", "show", "{w}/nope.dh"],
    "model show garbage": ["model", "show", "{w}/garbage.dh"],
    "model show deep": ["model", "show", "{w}/huge.dh"],
    "model show long name": ["model", "show", "x" * 5000],
    "model list extra": ["model", "list", "extra"],
    "model render bad state": ["model", "render", "hand", "--state", "{w}/big-int.json",
                               "-o", "{o}/m.png"],
    "model render bad view": ["model", "render", "hand", "--view", "sideways",
                              "-o", "{o}/m.png"],
    "model render bad size": ["model", "render", "hand", "--size", "60000x60000",
                              "-o", "{o}/m.png"],
    "model render bad suffix": ["model", "render", "hand", "-o", "{o}/m.xyz"],
    "model render device": ["model", "render", "hand", "-o", "/dev/full"],
    # render
    "render bad scenario": ["render", "bogus", "-o", "{o}"],
    "render trap force": ["render", "mouse", "-o", "{w}/trap", "--force", "--frames", "1"],
    "render resume foreign": ["render", "mouse", "-o", "{w}/foreign", "--resume"],
    "render force resume": ["render", "mouse", "-o", "{o}", "--force", "--resume"],
    "render bad noise": ["render", "mouse", "-o", "{o}", "--noise", "-1"],
    "render over a file": ["render", "mouse", "-o", "{w}/model.dh", "--frames", "1"],
    # track
    "track no input": ["track", "-o", "{o}"],
    "track missing input": ["track", "{w}/nope", "-o", "{o}"],
    "track bad sequence": ["track", "{w}/badseq", "-o", "{o}"],
    "track escaping sequence": ["track", "{w}/escape", "-o", "{o}"],
    "track video without rig": ["track", "{w}/a.mkv", "-o", "{o}"],
    "track bad rig": ["track", "{w}/a.mkv", "--model", "hand", "--rig", "{w}/big-int.json",
                      "--init", "{w}/big-int.json", "-o", "{o}"],
    "track bad yaml": ["track", "{w}/a.mkv", "--model", "hand", "--rig", "{w}/nocols.yml",
                       "--init", "{w}/big-int.json", "-o", "{o}"],
    "track bad model": ["track", "{w}/a.mkv", "--model", "{w}/garbage.dh", "--rig",
                        "{w}/nocols.yml", "--init", "{w}/big-int.json", "-o", "{o}"],
    # evaluate
    "evaluate missing": ["evaluate", "{w}/nope", "{w}/nope"],
    "evaluate no log": ["evaluate", "{w}/foreign", "{w}/badseq"],
    "evaluate deep json": ["evaluate", "{w}/foreign", "{w}/deepseq"],
    # bench
    "bench unknown": ["bench", "nope"],
    "bench json to a folder": ["bench", "kinematics", "--json", "{w}"],
    "bench workers elsewhere": ["bench", "kinematics", "--workers", "2"],
    "bench no workers": ["bench", "accuracy", "--workers", "0"],
    "bench seed elsewhere": ["bench", "smc", "--seed", "1"],
    "bench negative seed": ["bench", "accuracy", "--seed", "-1"],
    "bench seeds elsewhere": ["bench", "accuracy", "--seeds", "4"],
    "bench one seed": ["bench", "auto-start", "--seeds", "1"],
}


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    """Bad inputs, built once; tests copy them (commands must not touch them anyway)."""
    w = tmp_path_factory.mktemp("bad-inputs")
    (w / "model.dh").write_text("model m\n")
    (w / "garbage.dh").write_text("model g\n[frames]\n0 - q0 0 nope\n")
    rows = "\n".join(f"{i} l{i} 0 0 1 0 cyl(1) {i + 1}" for i in range(3000))
    (w / "huge.dh").write_text(f"model huge\n[frames]\n{rows}\n")
    (w / "big-int.json").write_text('{"cameras": ' + "9" * 5000 + "}")
    (w / "nocols.yml").write_text("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n"
                                  "  dt: d\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
                                  "image_width: abc\nimage_height: 4\n")
    (w / "a.mkv").write_bytes(b"\x1a\x45\xdf\xa3 not really a video")
    (w / "foreign").mkdir()
    (w / "foreign" / "thesis.tex").write_text("years of work")
    (w / "trap").mkdir()
    (w / "trap" / "sequence.json").write_text(json.dumps(
        {"cameras": ["../foreign"], "frames": {"kind": "png", "files": {"x": "../model.dh"}}}))
    (w / "badseq").mkdir()
    (w / "badseq" / "sequence.json").write_text('{"format": "digiteyes-sequence", "n_frames": '
                                               + "1" * 500 + "}")
    (w / "deepseq").mkdir()
    (w / "deepseq" / "sequence.json").write_text("[" * 200_000)
    (w / "escape").mkdir()
    (w / "escape" / "sequence.json").write_text(json.dumps({
        "format": "digiteyes-sequence", "version": 1, "model": "../garbage.dh",
        "rig": "r.json", "initial_state": "s.json", "fps": 10, "n_frames": 1,
        "cameras": ["c"], "frames": {"kind": "png"}}))
    return w


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() if p.is_file() else b"<dir>"
            for p in sorted(root.rglob("*"))}


@pytest.mark.parametrize("case", CASES)
def test_bad_input_is_one_line_exit_2_and_writes_nothing_outside(case, scratch, tmp_path,
                                                                 monkeypatch, capsys):
    root = tmp_path / "root"
    work = root / "w"
    shutil.copytree(scratch, work)
    out = root / "out"
    monkeypatch.chdir(root)
    before = _tree(root)
    argv = [a.format(w=work, o=out) for a in CASES[case]]
    assert main(argv) == 2, case
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error: "), (case, err)
    after = {k: v for k, v in _tree(root).items() if not (k == "out" or k.startswith("out/"))}
    assert after == before, f"{case}: wrote or deleted outside its output folder"
