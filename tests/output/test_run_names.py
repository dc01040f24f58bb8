"""Runs that share an output folder get names of their own, even when they run at once: the name is taken
with an exclusive create of the run's coverage file, so no run's files overwrite another's and results.jsonl
never holds two records of one name."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from robotexp.output.results import CURVE_HEADER, read_jsonl, run_id


def test_run_id_takes_the_name_it_gives(tmp_path: Path) -> None:
    names = [run_id("ufmg-static", "frontier", "A", 0.3, 0, tmp_path) for _ in range(3)]
    assert names == ["ufmg-static_frontier_A_300mms_s0", "ufmg-static_frontier_A_300mms_s0_2",
                     "ufmg-static_frontier_A_300mms_s0_3"]
    for name in names:      # held by a coverage file with its header (a run that writes nothing leaves no samples)
        assert (tmp_path / f"{name}.coverage.csv").read_text().splitlines() == [",".join(CURVE_HEADER)]


def test_two_explore_processes_into_one_folder(tmp_path: Path) -> None:
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "robotexp.cli", "explore", "-w", "ufmg-static", "--max-time", "5", "--out", str(out)]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for _ in range(2)]
    outputs = [p.communicate(timeout=120)[0] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outputs
    runs = [r["run"] for r in read_jsonl(out / "results.jsonl")]
    assert sorted(runs) == ["ufmg-static_frontier_path1_300mms_s0", "ufmg-static_frontier_path1_300mms_s0_2"]
    for name in runs:
        for suffix in (".coverage.csv", ".path.csv", ".map.yaml", ".map.pgm", ".png", ".coverage.png"):
            assert (out / f"{name}{suffix}").is_file(), name + suffix
        assert len((out / f"{name}.coverage.csv").read_text().splitlines()) > 3       # the run's own samples
        assert f"{name}:" in "".join(outputs)


def test_a_robot_other_than_the_default_is_in_the_run_name(tmp_path: Path) -> None:
    from robotexp.experiment import run_experiment
    from robotexp.run.spec import RunSpec

    names = [run_experiment(RunSpec(world="ufmg-static", method="frontier", robot=robot, max_time=1.0),
                            tmp_path).record["run"] for robot in ("p3dx", "kobuki", "p3dx-body")]
    assert names == ["ufmg-static_frontier_path1_300mms_s0", "ufmg-static_frontier-kobuki_path1_300mms_s0",
                     "ufmg-static_frontier-p3dx-body_path1_300mms_s0"]
