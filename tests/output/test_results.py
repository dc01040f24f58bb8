"""robotexp.output.results: the JSONL results file, run names and the coverage curve CSV."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from robotexp.explorer import Done, Explorer
from robotexp.run.loop import ExplorationRun, RunInfo
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import ground_truth
from robotexp.run.record import EndReason
from robotexp.output.results import RESULT_KEYS, append_jsonl, read_jsonl, run_id, write_curve_csv
from robotexp.run.loop import make_record
from robotexp.robot import Pose, RobotState, Twist
from robotexp.sim import LaserConfig, SimRobot
from robotexp.world.model import World, segment_box

# -- JSON lines ----------------------------------------------------------------------------

RECORDS = [
    {"run": "a", "coverage": 0.5, "completed": True, "start_pose": [1.0, -2.0, 0.25], "nodes": None},
    {"run": "b", "coverage": None, "reason": "robot error: link \"lost\"\nat 3 s", "unicode": "µm ✓"},
]


def test_append_then_read_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "deep" / "dir" / "results.jsonl"          # parents are created
    for record in RECORDS:
        append_jsonl(path, record)
    assert read_jsonl(path) == RECORDS
    lines = path.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 2                                     # one line per record, newlines escaped
    assert json.loads(lines[1]) == RECORDS[1]


def test_append_keeps_earlier_records(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    append_jsonl(path, RECORDS[0])
    first = path.read_bytes()
    append_jsonl(path, RECORDS[1])
    assert path.read_bytes().startswith(first)


def test_torn_last_line_is_skipped(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    for record in RECORDS:
        append_jsonl(path, record)
    with open(path, "a", encoding="utf-8") as f:
        f.write('{"run": "c", "coverage": 0.9')                # killed while writing
    assert read_jsonl(path) == RECORDS


def test_blank_lines_are_ignored(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    path.write_text('\n{"run": "a"}\n\n   \n{"run": "b"}\n', encoding="utf-8")
    assert read_jsonl(path) == [{"run": "a"}, {"run": "b"}]


# -- run names -----------------------------------------------------------------------------

def test_run_id_is_file_safe(tmp_path: Path) -> None:
    name = run_id("my lab/x.map", "frontier", "1500,-200,90", 0.3, 7, tmp_path)
    # runs of characters outside [A-Za-z0-9_.-] become one '-'; ",-" -> "--" since '-' is kept
    assert name == "my-lab-x.map_frontier_1500--200-90_300mms_s7"
    assert re.fullmatch(r"[A-Za-z0-9_.-]+", name)


def test_run_id_strips_leading_and_trailing_dashes(tmp_path: Path) -> None:
    assert run_id("/data/", "srt-laser", "home", 0.1, 0, tmp_path) == "data-_srt-laser_home_100mms_s0"
    assert run_id("dense", "frontier", "1", 0.0254, 3, tmp_path) == "dense_frontier_1_25mms_s3"


def test_run_id_is_unique_when_files_exist(tmp_path: Path) -> None:
    base = "dense_frontier_1_300mms_s0"
    assert run_id("dense", "frontier", "1", 0.3, 0, tmp_path) == base
    (tmp_path / f"{base}.png").write_bytes(b"")
    assert run_id("dense", "frontier", "1", 0.3, 0, tmp_path) == f"{base}_2"
    (tmp_path / f"{base}_2.coverage.csv").write_text("")      # either file takes the name
    assert run_id("dense", "frontier", "1", 0.3, 0, tmp_path) == f"{base}_3"
    (tmp_path / "results.jsonl").write_text("")                # other files do not matter
    assert run_id("dense", "frontier", "2", 0.3, 0, tmp_path) == "dense_frontier_2_300mms_s0"


# -- curve CSV -----------------------------------------------------------------------------

def test_write_curve_csv_by_hand(tmp_path: Path) -> None:
    path = tmp_path / "run.coverage.csv"
    write_curve_csv(path, [(0.0, 0.0, 0.25), (1.0, 0.123456, 0.9876543), (2.5, 10.0, -1.0)])
    assert path.read_bytes() == (b"robot_time_s,path_length_m,coverage\r\n"
                                 b"0.000,0.0000,0.25000\r\n"
                                 b"1.000,0.1235,0.98765\r\n"
                                 b"2.500,10.0000,-1.00000\r\n")


def test_write_curve_csv_empty(tmp_path: Path) -> None:
    path = tmp_path / "empty.csv"
    write_curve_csv(path, [])
    assert path.read_bytes() == b"robot_time_s,path_length_m,coverage\r\n"


# -- the record of a real run --------------------------------------------------------------

class _Forward(Explorer):
    """Drive straight at 0.5 m/s until x reaches `x_end`."""

    def __init__(self, x_end: float) -> None:
        self.x_end = x_end

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        return Done("at the end") if state.pose.x >= self.x_end else Twist(0.5, 0.0)


def test_make_record_of_a_short_run() -> None:
    t = 0.1
    world = World("box", np.array([segment_box(0, 0, 4, 0, t), segment_box(0, 2, 4, 2, t),
                                   segment_box(0, 0, 0, 2, t), segment_box(4, 0, 4, 2, t)]))
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    x0, y0 = geo.center_of(*geo.cell_of(0.6, 1.0))
    start = Pose(x0, y0, 0.0)
    truth = ground_truth(world, geo, robot_radius=0.25, laser_range=2.0, start=start)
    grid = OccupancyGrid(geo, range_max=2.0)
    laser = LaserConfig(beams=360, fov=2 * math.pi, range_max=2.0)
    with SimRobot(world, pose=start, laser=laser, max_speed=0.5, sonar=False) as robot:
        info = RunInfo(name="r1", method="fwd", world="box", max_speed=0.5, robot="p3dx")
        run = ExplorationRun(robot, _Forward(3.0), grid, truth=truth, seed=4, info=info).run()
    rec = run.record
    assert rec is not None and make_record(run) == rec
    assert rec.end is EndReason.EXPLORED
    assert set(RESULT_KEYS) <= set(rec)
    assert rec["run"] == "r1" and rec["method"] == "fwd" and rec["world"] == "box" and rec["seed"] == 4
    assert rec["robot"] == "p3dx" and rec["cell_m"] == 0.1 and rec["nodes"] is None
    assert rec["start_pose"] == [x0, y0, 0.0]
    assert rec["completed"] is True and rec["reason"] == "at the end"
    assert rec["path_length_m"] == pytest.approx(run.metrics.path[-1][0] - x0, abs=1e-4)
    assert rec["coverage"] == pytest.approx(run.coverage(), abs=1e-5)
    assert rec["coverage"] > 0.99 and 0.0 < rec["map_iou"] <= 1.0
    assert rec["collisions"] == 0 and rec["visited_cells"] == len(run.metrics.visited)
    for level in ("90", "95", "99"):
        hit = run.metrics.milestones[int(level) / 100]
        assert hit is not None
        assert rec[f"time_to_coverage_{level}_s"] == round(hit[0], 3)
        assert rec[f"path_to_coverage_{level}_m"] == round(hit[1], 4)
    json.dumps(rec.as_dict())                                  # plain JSON types only
