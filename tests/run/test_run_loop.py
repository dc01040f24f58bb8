"""ExplorationRun: how runs end, and what they measure, with scripted explorers on the SimRobot.

The world is a closed corridor 10 x 1.5 m; a 360 degree laser of 2 m sees everything the robot
passes, so driving straight along it raises coverage steadily to 1. The robot fakes are SimRobot
subclasses that record what the run does with them (a real backend, not a method mock).
"""

from __future__ import annotations

import itertools
import math
import signal
import time
from collections.abc import Iterator

import numpy as np
import pytest

from robotexp.errors import ConfigError, ConnectionLost, RobotError, Terminated
from robotexp.explorer import Done, Explorer, ExplorerContext
from robotexp.run.record import COVERAGE_MILESTONES, EndReason
from robotexp.run.loop import TERMINATED_REASON, ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import GroundTruth, ground_truth
from robotexp.robot import Pose, RobotState, Twist
from robotexp.sim import LaserConfig, SimRobot
from robotexp.world.model import World, segment_box

T = 0.1
RANGE = 2.0
SPEED = 0.5
WORLD = World("corridor", np.array([segment_box(0, 0, 10, 0, T), segment_box(0, 1.5, 10, 1.5, T),
                                    segment_box(0, 0, 0, 1.5, T), segment_box(10, 0, 10, 1.5, T)]))
GEO = GridGeometry.covering(*WORLD.bounds, cell=0.1, margin=0.5)
START = Pose(*GEO.center_of(*GEO.cell_of(0.55, 0.75)), 0.0)      # a cell centre near the left end
LASER = LaserConfig(beams=360, fov=2 * math.pi, range_max=RANGE)


class RecordingSim(SimRobot):
    """A SimRobot that keeps every command it was sent and every true pose it reported."""

    def __init__(self, *, fail_after: int | None = None) -> None:
        self.commands: list[Twist] = []
        self.true_poses: list[Pose] = []
        self.reads = 0
        self.fail_after = fail_after
        super().__init__(WORLD, pose=START, laser=LASER, max_speed=SPEED, sonar=False)

    def _read(self) -> RobotState:
        self.reads += 1
        if self.fail_after is not None and self.reads > self.fail_after:
            raise ConnectionLost(f"sim: link lost after {self.fail_after} reads")
        state = super()._read()
        assert state.true_pose is not None
        self.true_poses.append(state.true_pose)
        return state

    def _command(self, twist: Twist) -> None:
        self.commands.append(twist)
        super()._command(twist)


class Straight(Explorer):
    """Drive straight ahead until x >= x_end; optionally raise `fail` at step `fail_at`."""

    def __init__(self, x_end: float = 9.0, fail_at: int | None = None,
                 fail: BaseException | None = None) -> None:
        self.x_end, self.fail_at, self.fail = x_end, fail_at, fail
        self.steps = 0

    def reset(self, ctx: ExplorerContext) -> None:
        super().reset(ctx)
        self.first_draw = float(ctx.rng.random())

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        self.steps += 1
        if self.fail_at is not None and self.steps >= self.fail_at:
            assert self.fail is not None
            raise self.fail
        if state.pose.x >= self.x_end:
            return Done("scripted end", explored=False)     # a scripted stop, not a claim of exploration
        return Twist(SPEED, 0.0)


@pytest.fixture(scope="module")
def truth() -> GroundTruth:
    return ground_truth(WORLD, GEO, robot_radius=0.25, laser_range=RANGE, start=START)


@pytest.fixture
def robot() -> Iterator[RecordingSim]:
    with RecordingSim() as r:
        yield r


def new_grid() -> OccupancyGrid:
    return OccupancyGrid(GEO, range_max=RANGE)


# -- how runs end --------------------------------------------------------------------------

def test_done_ends_the_run_completed(robot: RecordingSim, truth: GroundTruth) -> None:
    explorer = Straight(x_end=3.0)
    run = ExplorationRun(robot, explorer, new_grid(), truth=truth, seed=11).run()
    assert run.completed and run.reason == "scripted end"
    assert robot.true_poses[-1].x >= 3.0
    assert robot.commands[-1] == Twist.ZERO                   # stopped at the end
    assert robot.commands[0] == Twist(SPEED, 0.0)
    # the context told the explorer what it may know
    ctx = explorer.ctx
    assert ctx.radius == 0.25 and ctx.laser_range == RANGE and ctx.period == 0.1
    assert ctx.start == START and ctx.limits == robot.limits and not ctx.sonar
    assert explorer.first_draw == np.random.default_rng(11).random()
    assert run.start_pose == START
    assert not robot.closed                                    # the run stops the robot but leaves it open


def test_max_time_ends_the_run_incomplete(robot: RecordingSim, truth: GroundTruth) -> None:
    run = ExplorationRun(robot, Straight(), new_grid(), truth=truth, max_time=5.0).run()
    assert not run.completed
    assert run.reason == "time limit of 5 s reached"
    assert run.robot_time == pytest.approx(5.0, abs=0.05)     # the tick at the limit, not one later
    assert robot.commands[-1] == Twist.ZERO
    # 5 s at 0.5 m/s after the 0.3 m/s^2 ramp (1.67 s, 0.42 m): 0.42 + 3.33 * 0.5 = 2.08 m, give or take a tick
    assert run.metrics.path_length == pytest.approx(2.08, abs=0.06)


def test_an_explorer_raising_robot_error_ends_the_run(robot: RecordingSim, truth: GroundTruth) -> None:
    failing = Straight(fail_at=20, fail=RobotError("bumper: emergency stop pressed"))
    run = ExplorationRun(robot, failing, new_grid(), truth=truth).run()
    assert not run.completed
    assert run.reason == "robot error: bumper: emergency stop pressed"
    assert robot.commands[:19] == [Twist(SPEED, 0.0)] * 19
    assert robot.commands[-1] == Twist.ZERO and len(robot.commands) == 20
    assert run.robot_time == pytest.approx(1.9)
    assert run.metrics.curve[-1][0] == pytest.approx(1.9)     # a last sample where it ended


def test_a_connection_lost_mid_run_ends_the_run(truth: GroundTruth) -> None:
    with RecordingSim(fail_after=30) as robot:
        run = ExplorationRun(robot, Straight(), new_grid(), truth=truth).run()
        assert not run.completed
        assert run.reason == "robot error: sim: link lost after 30 reads"
        assert isinstance(ConnectionLost("x"), RobotError)
        assert robot.reads == 31
        assert robot.commands[-1] == Twist.ZERO                # the run still tried to stop it
        assert robot.commands[:-1] == [Twist(SPEED, 0.0)] * 30     # one per good read
        assert run.robot_time == pytest.approx(2.9)            # the state of the last good read
        assert len(run.metrics.path) == 30


def test_ctrl_c_ends_the_run_and_stops(robot: RecordingSim, truth: GroundTruth) -> None:
    run = ExplorationRun(robot, Straight(fail_at=10, fail=KeyboardInterrupt()), new_grid(), truth=truth).run()
    assert not run.completed and run.reason == "interrupted (Ctrl-C)"
    assert robot.commands[-1] == Twist.ZERO


class InterruptedInKernel(RecordingSim):
    """At read 10 a SIGINT lands while a numba kernel of the read runs (a localizer's scan matcher): CPython
    raises SystemError "returned a result with an exception set", the KeyboardInterrupt (or `terminated`,
    SIGTERM's) as its cause."""

    def __init__(self, interrupt: KeyboardInterrupt) -> None:
        super().__init__()
        self.interrupt = interrupt

    def _read(self) -> RobotState:
        if self.reads == 9:
            self.reads += 1
            try:
                raise self.interrupt
            except KeyboardInterrupt as exc:
                raise SystemError("CPUDispatcher(<function hit_points>) returned a result with an exception "
                                  "set") from exc
        return super()._read()


@pytest.mark.parametrize("interrupt, reason", [(KeyboardInterrupt(), "interrupted (Ctrl-C)"),
                                               (Terminated(), TERMINATED_REASON)])
def test_ctrl_c_inside_a_kernel_of_the_robots_read_ends_the_run_and_stops(
        truth: GroundTruth, interrupt: KeyboardInterrupt, reason: str) -> None:
    with InterruptedInKernel(interrupt) as robot:
        run = ExplorationRun(robot, Straight(), new_grid(), truth=truth).run()
    assert run.end is EndReason.INTERRUPTED and run.reason == reason and not run.completed
    stops = robot.commands[9:]                                # nine good reads drove; then it was stopped
    assert robot.commands[:9] == [Twist(SPEED, 0.0)] * 9 and stops and set(stops) == {Twist.ZERO}
    assert run.record is not None and run.record.end is EndReason.INTERRUPTED


def test_a_systemerror_without_a_ctrl_c_behind_it_is_not_taken_for_one(truth: GroundTruth) -> None:
    class Broken(RecordingSim):
        def _read(self) -> RobotState:
            if self.reads == 5:
                raise SystemError("a kernel failed")
            return super()._read()

    with Broken() as robot, pytest.raises(SystemError, match="a kernel failed"):
        ExplorationRun(robot, Straight(), new_grid(), truth=truth).run()
    assert robot.commands[-1] == Twist.ZERO                   # stopped all the same


class SwallowsCtrlC(Straight):
    """At step 10 a SIGINT reaches the process while the step runs, and the step swallows the
    KeyboardInterrupt (as C code's callbacks do: llvmlite's object cache while numba compiles)."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        if self.steps == 9:
            try:
                signal.raise_signal(signal.SIGINT)
            except KeyboardInterrupt:
                pass
        return super().step(state, grid)


def test_a_ctrl_c_swallowed_inside_a_step_still_ends_the_run(robot: RecordingSim, truth: GroundTruth) -> None:
    before = signal.getsignal(signal.SIGINT)
    explorer = SwallowsCtrlC()
    run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
    assert run.reason == "interrupted (Ctrl-C)" and not run.completed
    assert explorer.steps == 10 and len(robot.commands) == 11      # ten steps commanded, then the stop
    assert robot.commands[-1] == Twist.ZERO
    assert signal.getsignal(signal.SIGINT) is before                # the run's handler is put back


class SignalsMidStep(Straight):
    """At step `at` the process gets `count` signals `sig` in the middle of the step, which then does the rest
    of its work (`finished` counts the steps that got to their end)."""

    def __init__(self, at: int = 10, count: int = 1, sig: int = signal.SIGINT, done: bool = False) -> None:
        super().__init__()
        self.at, self.count, self.sig, self.done = at, count, sig, done
        self.finished = 0

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        out = super().step(state, grid)
        if self.steps == self.at:
            for _ in range(self.count):
                signal.raise_signal(self.sig)
            if self.done:
                out = Done("scripted end", explored=False)
        self.finished += 1
        return out


def test_a_ctrl_c_during_a_step_ends_the_run_at_the_next_step_not_inside_it(
        robot: RecordingSim, truth: GroundTruth) -> None:
    # the handler's exception starts in the loop, never inside a plugin's step or a call into compiled code
    before = signal.getsignal(signal.SIGINT)
    explorer = SignalsMidStep(at=10)
    run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
    assert run.end is EndReason.INTERRUPTED and run.reason == "interrupted (Ctrl-C)"
    assert explorer.steps == 10 and explorer.finished == 10            # step 10 ran to its end
    assert robot.commands[:10] == [Twist(SPEED, 0.0)] * 10 and robot.commands[10:] == [Twist.ZERO]
    assert signal.getsignal(signal.SIGINT) is before


def test_a_second_ctrl_c_cuts_the_step_at_once(robot: RecordingSim, truth: GroundTruth) -> None:
    explorer = SignalsMidStep(at=10, count=2)
    run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
    assert run.end is EndReason.INTERRUPTED and run.reason == "interrupted (Ctrl-C)"
    assert explorer.steps == 10 and explorer.finished == 9              # the second one raised inside step 10
    assert robot.commands[-1] == Twist.ZERO and len(robot.commands) == 10


def test_a_sigterm_during_a_step_ends_the_run_at_the_next_step(robot: RecordingSim, truth: GroundTruth) -> None:
    def terminate(signum: int, frame: object) -> None:     # as the commands take SIGTERM (cli.common.watch_sigterm)
        raise Terminated

    before = signal.signal(signal.SIGTERM, terminate)
    try:
        explorer = SignalsMidStep(at=10, sig=signal.SIGTERM)
        run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
        assert signal.getsignal(signal.SIGTERM) is terminate
    finally:
        signal.signal(signal.SIGTERM, before)
    assert run.end is EndReason.INTERRUPTED and run.reason == TERMINATED_REASON
    assert explorer.finished == 10 and robot.commands[-1] == Twist.ZERO and len(robot.commands) == 11


def test_a_ctrl_c_at_the_last_step_still_interrupts_the_run(robot: RecordingSim, truth: GroundTruth) -> None:
    explorer = SignalsMidStep(at=10, done=True)
    run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
    assert run.end is EndReason.INTERRUPTED and run.reason == "interrupted (Ctrl-C)" and not run.completed
    assert explorer.finished == 10 and robot.commands[-1] == Twist.ZERO
    assert run.record is not None and run.record.end is EndReason.INTERRUPTED


def test_a_ctrl_c_kept_when_the_link_is_lost_still_interrupts_the_run(truth: GroundTruth) -> None:
    # Ctrl-C at step 30, then the next read loses the link: the user's Ctrl-C is not dropped for the robot error
    with RecordingSim(fail_after=30) as robot:
        explorer = SignalsMidStep(at=30)
        run = ExplorationRun(robot, explorer, new_grid(), truth=truth).run()
        assert robot.reads == 31 and explorer.finished == 30
        assert run.end is EndReason.INTERRUPTED and run.reason == "interrupted (Ctrl-C)"
        assert robot.commands[-1] == Twist.ZERO


def test_bad_run_settings(robot: RecordingSim) -> None:
    for bad in ({"period": 0.0}, {"max_time": -1.0}, {"sample_period": 0.0}, {"period": math.nan}):
        with pytest.raises(ConfigError, match="run: period, max_time and sample_period must be > 0 s"):
            ExplorationRun(robot, Straight(), new_grid(), **bad)  # type: ignore[arg-type]


# -- what runs measure ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def straight_run(truth: GroundTruth) -> tuple[ExplorationRun, list[Pose], list[tuple[float, float | None]]]:
    samples: list[tuple[float, float | None]] = []
    with RecordingSim() as robot:
        run = ExplorationRun(robot, Straight(x_end=9.0), new_grid(), truth=truth,
                             on_sample=lambda t, c: samples.append((t, c))).run()
        poses = list(robot.true_poses)
    return run, poses, samples


def test_milestones_are_the_first_samples_reaching_each_level(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, _, _ = straight_run
    curve, milestones = run.metrics.curve, run.metrics.milestones
    assert set(milestones) == set(COVERAGE_MILESTONES) == {0.90, 0.95, 0.99}
    assert run.coverage() == 1.0 and curve[-1][2] == 1.0
    for level in COVERAGE_MILESTONES:
        first = next(s for s in curve if s[2] >= level)
        assert milestones[level] == (first[0], first[1])
        assert all(s[2] < level for s in curve[:curve.index(first)])
    hits = [milestones[level] for level in COVERAGE_MILESTONES]
    assert all(h is not None for h in hits)
    times = [h[0] for h in hits if h is not None]
    paths = [h[1] for h in hits if h is not None]
    assert times == sorted(times) and paths == sorted(paths)
    assert times[0] < times[-1]                                # the levels are reached at different times
    assert [c for _, _, c in curve] == sorted(c for _, _, c in curve)   # driving on only adds coverage


def test_one_curve_sample_per_second_of_robot_time(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, _, _ = straight_run
    times = [t for t, _, _ in run.metrics.curve]
    whole = math.floor(run.robot_time + 1e-9)
    # 0, 1, 2, ... s on the tick of each whole second, then one last sample where the run ended
    assert len(times) == whole + 2
    assert times[:-1] == pytest.approx(list(range(whole + 1)), abs=1e-6)
    assert times[-1] == pytest.approx(run.robot_time)
    # path lengths along the curve: 0.5 m per second at full speed
    paths = [s for _, s, _ in run.metrics.curve]
    assert paths[0] == 0.0
    assert paths[8] - paths[7] == pytest.approx(SPEED * 1.0, abs=1e-9)


def test_sample_period(truth: GroundTruth) -> None:
    with RecordingSim() as robot:
        run = ExplorationRun(robot, Straight(x_end=2.0), new_grid(), truth=truth, sample_period=0.5).run()
    times = [t for t, _, _ in run.metrics.curve]
    assert times[:-1] == pytest.approx([0.5 * k for k in range(len(times) - 1)], abs=1e-6)
    assert run.robot_time - 0.5 < times[-2] <= run.robot_time


def test_on_sample_sees_every_sample(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, _, samples = straight_run
    assert samples == [(t, c) for t, _, c in run.metrics.curve]


def test_path_length_is_the_sum_of_true_steps(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, poses, _ = straight_run
    steps = sum(a.distance_to(b) for a, b in zip(poses, poses[1:], strict=False))
    assert run.metrics.path_length == pytest.approx(steps, rel=1e-12)
    # a straight drive: the path is the distance between the ends
    assert run.metrics.path_length == pytest.approx(poses[-1].x - START.x, abs=1e-9)
    assert run.metrics.path == [(p.x, p.y) for p in poses]


def test_visited_cells_by_hand(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, poses, _ = straight_run
    row, c0 = GEO.cell_of(START.x, START.y)
    _, c1 = GEO.cell_of(poses[-1].x, poses[-1].y)
    assert run.metrics.visited == {(row, c) for c in range(c0, c1 + 1)}
    assert len(run.metrics.visited) == c1 - c0 + 1 > 80


def test_the_grid_gets_every_scan(straight_run) -> None:  # type: ignore[no-untyped-def]
    run, poses, _ = straight_run
    assert run.grid.scans == len(poses)


def test_without_ground_truth(robot: RecordingSim) -> None:
    samples: list[tuple[float, float | None]] = []
    run = ExplorationRun(robot, Straight(x_end=2.0), new_grid(),
                         on_sample=lambda t, c: samples.append((t, c))).run()
    assert run.completed and run.coverage() is None
    assert all(c == -1.0 for _, _, c in run.metrics.curve)
    assert all(hit is None for hit in run.metrics.milestones.values())
    assert samples and all(c is None for _, c in samples)


def test_collisions_are_counted(truth: GroundTruth) -> None:
    # drive into the far wall: one contact, however long the robot keeps pushing
    with RecordingSim() as robot:
        robot.move_to(Pose(8.5, 0.75, 0.0))
        run = ExplorationRun(robot, Straight(x_end=20.0), new_grid(), truth=truth, max_time=8.0).run()
    assert run.metrics.collisions == 1
    assert run.reason == "time limit of 8 s reached"
    # stopped with its edge at the wall's face (x = 9.95 m): centre at 9.7 m
    assert run.metrics.path[-1][0] == pytest.approx(9.95 - 0.25, abs=0.02)


class SlowLaserSim(RecordingSim):
    """A SimRobot whose laser is half as fast as its states: every scan comes in two states, with
    its stamp (as a driver's newest scan does until the next one)."""

    def __init__(self) -> None:
        self.last: object = None
        super().__init__()

    def _read(self) -> RobotState:
        from dataclasses import replace

        state = super()._read()
        assert state.laser is not None
        if self.reads % 2 == 1:
            self.last = replace(state.laser, stamp=float(self.reads))
        return replace(state, laser=self.last)


def test_a_scan_handed_out_twice_is_mapped_once(truth: GroundTruth) -> None:
    """Mapping a repeated scan again would count its hits twice (one stray hit would look like a wall
    seen twice): the loop maps each stamp once, and says so in its step events."""
    from robotexp.run.observers import RunObserver

    class Steps(RunObserver):
        def __init__(self) -> None:
            self.updated: list[bool] = []

        def on_step(self, run: ExplorationRun, step: object) -> None:
            self.updated.append(step.map_updated)           # type: ignore[attr-defined]

    steps = Steps()
    with SlowLaserSim() as robot:
        grid = new_grid()
        r = ExplorationRun(robot, Straight(x_end=3.0), grid, truth=truth, max_time=60.0, observers=[steps]).run()
    assert r.reason == "scripted end"
    n = len(steps.updated)
    assert n >= 40 and grid.scans == sum(steps.updated) == (n + 1) // 2
    assert steps.updated[:4] == [True, False, True, False]


def test_an_explorer_whose_reset_fails_keeps_its_own_error() -> None:
    from robotexp.run.loop import ExplorationRun
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.run.record import EndReason

    class SetUpInReset(Straight):
        """Counts what `reset` sets up, and `reset` fails first."""

        def reset(self, ctx) -> None:
            raise RuntimeError("no map of the building")

        def result_fields(self) -> dict[str, object]:
            return {"legs": len(self.legs)}              # type: ignore[attr-defined]  # set in reset

    with RecordingSim() as robot:
        run = ExplorationRun(robot, SetUpInReset(), OccupancyGrid(GEO)).run()
    assert run.end is EndReason.PLUGIN_ERROR and isinstance(run.error, RuntimeError)
    assert run.reason.endswith("reset raised RuntimeError: no map of the building")
    assert run.record is not None and run.record.end is EndReason.PLUGIN_ERROR
    assert "legs" not in run.record.method_fields


class JumpingClockSim(RecordingSim):
    """A SimRobot whose clock jumps 1e9 s ahead at its 20th state (a real robot's clock set anew)."""

    def _read(self) -> RobotState:
        from dataclasses import replace

        state = super()._read()
        return replace(state, time=state.time + (1e9 if self.reads >= 20 else 0.0))


def test_a_jump_of_the_robots_clock_costs_no_sample_by_sample_catch_up(truth: GroundTruth) -> None:
    """The run's clock is the robot's: after a jump of 1e9 s the next sample is the next second after the
    jump, found at once (not 1e9 samples later), and the run ends at its time limit there."""
    t0 = time.process_time()
    with JumpingClockSim() as robot:
        run = ExplorationRun(robot, Straight(x_end=9.0), new_grid(), truth=truth, max_time=1e9 + 5.0).run()
    assert time.process_time() - t0 < 30.0
    assert run.end is EndReason.TIME_LIMIT and 1e9 + 4.9 <= run.robot_time <= 1e9 + 5.1
    times = [t for t, _, _ in run.metrics.curve]
    assert times[0] == 0.0 and times[1] == pytest.approx(1.0) and times[2] >= 1e9
    assert all(b - a <= 1.0 + 1e-6 for a, b in itertools.pairwise(times[2:-1]))
