"""Malformed recordings: `robotexp replay`, `figure` and `video` each answer one line on stderr that
names the file and what is wrong, with exit status 2 (never a traceback), and a recording cannot
make them allocate more than its limits allow."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from robotexp.bag.schemas import LASER_SCAN, ODOMETRY
from robotexp.cli import main

import crafted_bags as crafted


def _meta(**grid_or_top: Any) -> dict[str, Any]:
    m = crafted.meta()
    for key, value in grid_or_top.items():
        if key.startswith("grid_"):
            m["grid"][key[5:]] = value
        else:
            m[key] = value
    return m


# name -> (how the recording is broken, a word the error line must hold)
CASES: dict[str, tuple[Callable[[Path], Path], str]] = {
    "truncated CDR": (lambda p: crafted.write(p, odom_data=lambda b: b[:20]), "readable"),
    "wrong schema": (lambda p: crafted.write(p, odom_schema=LASER_SCAN), "/odom is a sensor_msgs/msg/LaserScan"),
    "bad schema text": (lambda p: crafted.write(p, odom_schema=("nav_msgs/msg/Odometry", "%% not a message\n")),
                        "readable"),
    "a schema naming a type it never defines": (
        lambda p: crafted.write(p, odom_schema=(ODOMETRY[0], ODOMETRY[1].replace("MSG: std_msgs/Header",
                                                                              "MSG: std_msgs/Heade"))),
        "/odom: its message 1 does not decode as its nav_msgs/msg/Odometry schema says"),
    "a fixed array of 1e20 values": (
        lambda p: crafted.write(p, odom_schema=(ODOMETRY[0], ODOMETRY[1].replace("float64[36] covariance",
                                                                              "float64[99999999999999999999] c"))),
        "/odom: its message 1 does not decode"),
    "truth size mismatch": (lambda p: crafted.write(p, truth=lambda s: (crafted.ROWS, crafted.COLS,
                                                                        s.tobytes()[:-7])), "holds 1593 values"),
    "truth grid 200000 x 200000": (lambda p: crafted.write(p, truth=lambda s: (200000, 200000, s.tobytes())),
                                   "200000 x 200000"),
    "metadata not an object": (lambda p: crafted.write(p, run_meta=[1, 2]), "expected a JSON object"),
    "metadata not JSON": (lambda p: crafted.write(p, raw_meta="{"), "readable"),
    "grid rows as text": (lambda p: crafted.write(p, run_meta=_meta(grid_rows="40")), "rows"),
    "grid cell 0": (lambda p: crafted.write(p, run_meta=_meta(grid_cell=0)), "grid cell"),
    "grid 200000 x 200000": (lambda p: crafted.write(p, run_meta=_meta(grid_rows=200000, grid_cols=200000)),
                             "limit"),
    "grid p_free 0.7": (lambda p: crafted.write(p, run_meta=_meta(grid_p_free=0.7)), "p_free"),
    "sample period 1e-300 s": (lambda p: crafted.write(p, run_meta=_meta(sample_period_s=1e-300)),
                               "sample_period_s"),
    "radius as text": (lambda p: crafted.write(p, run_meta=_meta(radius_m="big")), "radius_m"),
    "start NaN": (lambda p: crafted.write(p, run_meta=_meta(start=[math.nan, 0, 0])), "start"),
    "record not an object": (lambda p: crafted.write(p, run_record="done"), "robotexp.run.record"),
    "collisions as text": (lambda p: crafted.write(p, run_record={**crafted.record(), "collisions": "many"}),
                           "collisions"),
    "pose at 1e300": (lambda p: crafted.write(p, pose=lambda i: (1e300, 0.0, 0.0)), "position"),
    "a stamp 1e8 s late": (lambda p: crafted.write(p, stamp=lambda i: 1e8 if i == 4 else 0.1 * i),
                           "stamps jump by 1e+08 s after robot time 0.3 s"),
    "the first stamp 1e8 s early": (lambda p: crafted.write(p, stamp=lambda i: 0.1 * i + (0 if i == 0 else 1e8)),
                                    "stamps jump by 1e+08 s after robot time 0.0 s"),
    "stamps past the time limit": (lambda p: crafted.write(p, stamp=lambda i: 1000.0 * i),
                                   "past the run's limit of 10 s"),
}


def _one_line(args: list[str], bag: Path, word: str) -> None:
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, (res.output, res.exception)
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert lines[0].startswith("robotexp: error: ") and str(bag) in lines[0] and word in lines[0], lines[0]


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_recording_is_one_line(case: str, tmp_path: Path) -> None:
    make, word = CASES[case]
    bag = make(tmp_path / "bad.mcap")
    _one_line(["replay", str(bag), "-o", str(tmp_path / "out")], bag, word)
    _one_line(["figure", str(bag), "-o", str(tmp_path / "fig")], bag, word)
    _one_line(["video", str(bag), "-o", str(tmp_path / "v.gif")], bag, word)
    assert not (tmp_path / "v.gif").exists()


def test_crafted_recording_replays(tmp_path: Path) -> None:
    """The crafted recording the cases break is itself good: it replays, with the recorded ground truth."""
    bag = crafted.write(tmp_path / "good.mcap")
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    rec = json.loads((tmp_path / "out" / "results.jsonl").read_text().splitlines()[-1])
    assert rec["coverage"] is not None and rec["coverage"] > 0.5


@pytest.mark.parametrize("fps", ["1e-300", "0", "nan", "inf", "1e300"])
def test_video_fps_out_of_range(fps: str, tmp_path: Path) -> None:
    bag = crafted.write(tmp_path / "good.mcap")
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "v.gif"), "--fps", fps])
    assert res.exit_code == 2, (res.output, res.exception)
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "--fps" in lines[0], res.output

