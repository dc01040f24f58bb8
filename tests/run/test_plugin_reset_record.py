"""An explorer that fails in reset, or whose result_fields fails, still gets its run's record
written, and the record names its own error (srt-laser on a robot without a laser used to end in
an AttributeError about `rescues` and no record)."""

from __future__ import annotations

import json
from pathlib import Path

from robotexp.bag.replay import ReplayRobot, Tick
from robotexp.explorer import Done, Explorer, ExplorerContext
from robotexp.run.loop import ExplorationRun, RunInfo
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.run.record import EndReason
from robotexp.registry import make_explorer
from robotexp.output.results import ResultsWriter
from robotexp.robot import Pose, RobotState, Twist


def _run(explorer: Explorer, out: Path) -> dict[str, object]:
    ticks = [Tick(0.1 * i, Pose(0.0, 0.0, 0.0), Twist(0.0, 0.0)) for i in range(5)]     # no laser
    robot = ReplayRobot(ticks)
    run = ExplorationRun(robot, explorer, OccupancyGrid(GridGeometry(-1.0, -1.0, 0.1, 20, 20)), max_time=10.0,
                         info=RunInfo(name="r", method="m", world="w", pose="p", robot="replay", max_speed=0.3,
                                      laser_range=0.0), observers=[ResultsWriter(out, image=False)])
    with robot:
        run.run()
    (line,) = (out / "results.jsonl").read_text().splitlines()
    return json.loads(line)


def test_srt_laser_without_laser_writes_its_own_error(tmp_path: Path) -> None:
    rec = _run(make_explorer("srt-laser", {}), tmp_path)
    assert EndReason.classify(False, str(rec["reason"])) is EndReason.PLUGIN_ERROR and not rec["completed"]
    assert "reset raised ConfigError" in rec["reason"] and "needs a laser" in rec["reason"], rec["reason"]
    assert "rescues" not in rec["reason"]


class _BadFields(Explorer):
    needs_range = False         # steps on the replay's states without a laser

    def reset(self, ctx: ExplorerContext) -> None:
        pass

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        return Done("explored")

    def result_fields(self) -> dict[str, object]:
        raise KeyError("oops")


def test_failing_result_fields_still_writes_the_record(tmp_path: Path) -> None:
    rec = _run(_BadFields(), tmp_path)
    assert EndReason.classify(False, str(rec["reason"])) is EndReason.PLUGIN_ERROR
    assert "result_fields raised KeyError" in rec["reason"]
