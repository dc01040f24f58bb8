"""A recording names its run in its metadata; what a command writes from it stays in the folder it was given
(`robotexp figure`, `robotexp replay`), and so does what a results file names its worlds (box figures): a name
like "../../x" or "/tmp/x" is made a plain file name."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

import crafted_bags
from robotexp.cli import main


def _bag(path: Path, run: object) -> Path:
    """A crafted recording (crafted_bags) whose `robotexp.run` metadata names the run `run`."""
    return crafted_bags.write(path, run_meta={**crafted_bags.meta(), "run": run})


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize("run", ["../../x", "ABSOLUTE", ".hidden/../../y"])
def test_figure_writes_only_into_its_folder(tmp_path: Path, run: object) -> None:
    root = tmp_path / "root"
    figs = root / "a" / "b" / "figs"
    figs.mkdir(parents=True)
    if run == "ABSOLUTE":
        run = str(tmp_path / "elsewhere" / "x")
        (tmp_path / "elsewhere").mkdir()
    bag = _bag(root / "a" / "b" / "rec.mcap", run)
    before = _files(tmp_path)
    res = CliRunner().invoke(main, ["figure", str(bag), "-o", str(figs), "--format", "png"])
    assert res.exit_code == 0, res.output
    new = _files(tmp_path) - before
    assert len(new) == 1, new
    (made,) = new
    assert Path(made).parent == figs.relative_to(tmp_path), made      # in the folder given, no deeper, no higher
    assert made.endswith(".map.png") and not Path(made).name.startswith(".")
    assert f"written: {tmp_path / made}" in res.output


def test_replay_names_its_run_safely_without_an_out_folder(tmp_path: Path) -> None:
    from robotexp.bag.replay import read_bag, replay_bag
    from robotexp.output.safefile import safe_name

    run = replay_bag(read_bag(_bag(tmp_path / "rec.mcap", "../../x")), None)
    assert run.info.name == safe_name("../../x") and "/" not in run.info.name


def test_safe_name() -> None:
    from robotexp.output.safefile import safe_name

    assert safe_name("ufmg-static_frontier_A_300mms_s0") == "ufmg-static_frontier_A_300mms_s0"
    assert safe_name("../../x") == "x"
    assert safe_name("/etc/passwd") == "etc-passwd"
    assert safe_name("a b:c") == "a-b-c"
    for bad in ("", "..", "/", "...", "-"):
        assert safe_name(bad) == "run"
    assert len(safe_name("x" * 1000)) <= 120
    assert os.sep not in safe_name("a" + os.sep + "b")


def test_campaign_figures_name_worlds_safely(tmp_path: Path) -> None:
    """A results file's world names its box figures: "../../x" or an absolute path stays a file name."""
    figs = tmp_path / "a" / "b" / "figs"
    figs.mkdir(parents=True)
    results = figs / "results.jsonl"
    lines = []
    for i, world in enumerate(["../../../x", "../../../x", "/tmp/abs", "/tmp/abs"]):
        lines.append(json.dumps({"run": f"r{i}", "method": "frontier", "world": world, "start_pose": [0, 0, 0],
                                 "max_speed_m_s": 0.3, "path_length_m": 10.0 + i, "robot_time_s": 100.0 + i,
                                 "wall_time_s": 1.0, "coverage": 0.5, "collisions": 0, "nodes": None,
                                 "visited_cells": 10, "seed": i, "completed": True, "reason": "explored",
                                 "map_iou": 0.5, "cell_m": 0.1}))
    results.write_text("\n".join(lines) + "\n")
    before = _files(tmp_path)
    res = CliRunner().invoke(main, ["figure", str(results), "--format", "svg"])
    assert res.exit_code == 0, res.output
    new = _files(tmp_path) - before
    assert new and all(Path(p).parent == figs.relative_to(tmp_path) for p in new), new
    assert {Path(p).name for p in new} >= {"box_coverage_x.svg", "box_coverage_tmp-abs.svg"}
