"""Run observers, end reasons and the loop's checks of a plugin, on the SimRobot
in the corridor of test_run_loop: what observers are told and when, that one that raises never keeps
the robot from being stopped nor loses the record, and that a `step` returning something other than
a Twist or Done ends the run with one line naming the plugin."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import pytest
from test_run_loop import GEO, RANGE, START, WORLD, RecordingSim, Straight

from robotexp.errors import PluginError, Terminated
from robotexp.run.spec import RunSpec, plan_run
from robotexp.experiment import run_on_robot
from robotexp.explorer import Done, Explorer
from robotexp.run.loop import TERMINATED_REASON, ExplorationRun, RunInfo
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import ground_truth
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.run.record import EndReason, RunRecord
from robotexp.robot import RobotState, Twist


class Log(RunObserver):
    """Keeps every call."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, Any]] = []

    def on_start(self, run: ExplorationRun) -> None:
        self.calls.append(("start", run.robot_time))

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        self.calls.append(("step", step))

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        self.calls.append(("sample", (time, coverage)))

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        self.calls.append(("end", record))


class Raises(RunObserver):
    """Raises in `hook`; counts its calls."""

    def __init__(self, hook: str, critical: bool = False) -> None:
        self.hook, self.count = hook, 0
        self.critical = critical        # type: ignore[misc]

    def _maybe(self, hook: str) -> None:
        self.count += 1
        if hook == self.hook:
            raise ValueError(f"observer broke in {hook}")

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        self._maybe("on_step")

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        self._maybe("on_sample")

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        self._maybe("on_end")


def _run(robot: RecordingSim, explorer: Explorer, *observers: RunObserver, **kw: Any) -> ExplorationRun:
    truth = ground_truth(WORLD, GEO, robot_radius=0.25, laser_range=RANGE, start=START)
    return ExplorationRun(robot, explorer, OccupancyGrid(GEO, range_max=RANGE), truth=truth,
                          observers=observers, **kw).run()


def test_observers_see_each_step_sample_and_the_end_in_order() -> None:
    log = Log()
    with RecordingSim() as robot:
        run = _run(robot, Straight(x_end=3.0), log, info=RunInfo(name="c1", method="straight", world="corridor"))
    kinds = [k for k, _ in log.calls]
    assert kinds[0] == "start" and kinds[-1] == "end" and kinds.count("start") == kinds.count("end") == 1
    steps = [v for k, v in log.calls if k == "step"]
    # one step per state read, the last one Done; every other decision is the Twist the robot was sent
    assert len(steps) == robot.reads
    assert [s.decision for s in steps[:-1]] == robot.commands[:len(steps) - 1]
    assert all(isinstance(s.decision, Twist) for s in steps[:-1])
    assert steps[-1].decision == Done("scripted end", explored=False)
    assert all(s.map_updated for s in steps) and [s.time for s in steps] == sorted(s.time for s in steps)
    # the samples are the run's coverage curve (one per second of robot time, and the final one)
    samples = [v for k, v in log.calls if k == "sample"]
    assert {t for t, _ in samples} == {t for t, _, _ in run.metrics.curve}
    assert samples[-1] == (run.robot_time, run.coverage()) and samples[-1][1] == run.metrics.curve[-1][2]
    record = log.calls[-1][1]
    assert record is run.record and record.run == "c1" and record.end is EndReason.EXPLORED
    assert robot.commands[-1] == Twist.ZERO                   # stopped before on_end


def test_a_raising_observer_is_detached_the_run_goes_on_and_the_robot_is_stopped(
        caplog: pytest.LogCaptureFixture) -> None:
    broken, log = Raises("on_step"), Log()
    with RecordingSim() as robot, caplog.at_level(logging.ERROR):
        run = _run(robot, Straight(x_end=3.0), broken, log)
    assert broken.count == 2                  # the first sample, the first step that raised: detached
    assert run.completed and run.end is EndReason.EXPLORED   # the run went on to its end
    assert robot.commands[-1] == Twist.ZERO
    assert [type(o) for o, _ in run.observer_errors] == [Raises]
    assert log.calls[-1][0] == "end"                           # the others got everything
    assert "Raises raised in on_step" in caplog.text and "observer broke in on_step" in caplog.text


def test_a_raising_observer_never_loses_the_record(tmp_path: Path) -> None:
    spec = RunSpec(world="corridor", method="straight", speed=0.5, laser_range=RANGE, max_time=30.0)
    with RecordingSim() as robot:
        plan = plan_run(spec, WORLD, robot.radius, explorer=Straight(x_end=3.0))
        out = run_on_robot(spec, robot, tmp_path, WORLD, plan=plan,
                           observers=[Raises("on_sample"), Raises("on_end")])
        assert robot.commands[-1] == Twist.ZERO
    (line,) = (tmp_path / "results.jsonl").read_text().splitlines()
    assert json.loads(line) == out.record.as_dict() and out.record.end is EndReason.EXPLORED
    # a critical observer's error reaches the caller, after the record was written
    with RecordingSim() as robot:
        plan = plan_run(spec, WORLD, robot.radius, explorer=Straight(x_end=3.0))
        with pytest.raises(ValueError, match="observer broke in on_end"):
            run_on_robot(spec, robot, tmp_path, WORLD, plan=plan, observers=[Raises("on_end", critical=True)])
        assert robot.commands[-1] == Twist.ZERO
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 2


class Returns(Explorer):
    """Drives for `after` steps, then returns `value` from step."""

    def __init__(self, value: object, after: int = 5) -> None:
        self.value, self.after, self.steps = value, after, 0

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        self.steps += 1
        return Twist(0.3, 0.0) if self.steps <= self.after else self.value  # type: ignore[return-value]


@pytest.mark.parametrize("value", [None, (0.3, 0.0), "stop"])
def test_a_step_that_returns_neither_twist_nor_done_is_one_line_naming_the_plugin(value: object,
                                                                                   tmp_path: Path) -> None:
    spec = RunSpec(world="corridor", method="returns-junk", speed=0.5, laser_range=RANGE, max_time=30.0)
    with RecordingSim() as robot:
        plan = plan_run(spec, WORLD, robot.radius, explorer=Returns(value))
        with pytest.raises(PluginError) as err:
            run_on_robot(spec, robot, tmp_path, WORLD, plan=plan)
        assert robot.commands[-1] == Twist.ZERO and robot.commands[-2] == Twist(0.3, 0.0)
    message = str(err.value)
    assert "\n" not in message and "'returns-junk'" in message and "test_observers.Returns" in message
    assert f"step returned {value!r}" in message and "must return a robotexp.Twist or robotexp.Done" in message
    (record,) = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert record["reason"] == message and record["completed"] is False
    assert RunRecord.from_dict(record).end is EndReason.PLUGIN_ERROR


def test_an_explorer_that_raises_ends_the_run_as_a_plugin_error() -> None:
    with RecordingSim() as robot:
        run = _run(robot, Straight(fail_at=4, fail=ZeroDivisionError("boom")))
        assert robot.commands[-1] == Twist.ZERO
    assert run.end is EndReason.PLUGIN_ERROR and isinstance(run.error, ZeroDivisionError)
    assert run.reason.startswith("plugin error: explorer 'Straight'") and "ZeroDivisionError: boom" in run.reason
    assert run.record is not None and run.record.end is EndReason.PLUGIN_ERROR


def _ctrl_c_in_a_kernel(interrupt: KeyboardInterrupt | None = None) -> SystemError:
    """What CPython makes of a SIGINT (or SIGTERM's `Terminated`) that lands while a numba dispatcher
    returns: a SystemError caused by the KeyboardInterrupt."""
    try:
        try:
            raise interrupt or KeyboardInterrupt()
        except KeyboardInterrupt as interrupt:
            raise SystemError("CPUDispatcher(<function label8>) returned a result with an exception set") \
                from interrupt
    except SystemError as error:
        return error


@pytest.mark.parametrize("interrupt, reason", [(KeyboardInterrupt(), "interrupted (Ctrl-C)"),
                                               (Terminated(), TERMINATED_REASON)])
def test_ctrl_c_inside_an_explorers_kernel_is_an_interruption_not_a_plugin_error(
        interrupt: KeyboardInterrupt, reason: str) -> None:
    with RecordingSim() as robot:
        run = _run(robot, Straight(fail_at=4, fail=_ctrl_c_in_a_kernel(interrupt)))
        assert robot.commands[-1] == Twist.ZERO
    assert run.end is EndReason.INTERRUPTED and run.error is None and run.reason == reason
    assert run.record is not None and run.record.end is EndReason.INTERRUPTED and not run.record.completed


@pytest.mark.parametrize("interrupt, reason", [(KeyboardInterrupt(), "interrupted (Ctrl-C)"),
                                               (Terminated(), TERMINATED_REASON)])
def test_ctrl_c_inside_an_observers_kernel_interrupts_the_run(interrupt: KeyboardInterrupt, reason: str) -> None:
    class KernelInterrupted(RunObserver):
        pressed = False

        def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
            if time >= 2.0 and not self.pressed:        # one Ctrl-C
                self.pressed = True
                raise _ctrl_c_in_a_kernel(interrupt)

    with RecordingSim() as robot:
        run = _run(robot, Straight(x_end=3.0), KernelInterrupted())
        assert robot.commands[-1] == Twist.ZERO
    assert run.end is EndReason.INTERRUPTED and run.observer_errors == [] and run.reason == reason


def test_request_stop_ends_the_run_with_the_reason_given() -> None:
    class StopAt(RunObserver):
        def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
            if time >= 2.0:
                run.request_stop("no progress for 2 s", EndReason.STALLED)

    with RecordingSim() as robot:
        run = _run(robot, Straight(), StopAt())
    assert run.end is EndReason.STALLED and run.reason == "stalled: no progress for 2 s"
    assert run.robot_time == pytest.approx(2.0) and not run.completed
    assert EndReason.classify(False, run.reason) is EndReason.STALLED
    with pytest.raises(Exception, match="not one an observer can give"):
        run.request_stop("x", EndReason.EXPLORED)


def test_the_loop_builds_step_events_only_for_observers_that_read_them() -> None:
    from robotexp.run.observers import Observers

    class SamplesOnly(RunObserver):
        def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None: ...

    class Steps(RunObserver):
        def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
            raise ValueError("no")

    group = Observers([RunObserver(), SamplesOnly()])
    assert not group.listening("on_step") and group.listening("on_sample") and not group.listening("on_end")
    group.add(Steps())
    assert group.listening("on_step")
    group.notify("on_step", None, None)              # Steps raises: detached, nobody listens any more
    assert not group.listening("on_step") and [type(o) for o, _ in group.errors] == [Steps]
