"""KobukiRobot through the Kobuki emulator on a real socket or pseudo-terminal: exploration and faults.

Every run checks what the emulator received last: a stop (Base Control speed 0, radius 0), wherever
the emulator can still receive.
"""

from __future__ import annotations

import json
import math
import random
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robotexp.errors import ConnectionLost
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_on_robot
from robotexp.explorer import Done, Explorer
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import Pose, RobotState, Twist
from robotexp.world.model import World
from robotexp_drivers.kobuki.codec import BaseControl
from robotexp_drivers.kobuki.emulator import EmulatorLaser, KobukiEmulator
from robotexp_drivers.kobuki.robot import KobukiRobot

WaitFor = Callable[..., bool]                # the `wait_for` fixture (conftest.py)
SpecFor = Callable[[str, float], RunSpec]     # the `run_spec` fixture (conftest.py)

STOP = BaseControl(0, 0)
SPEEDUP = 30.0


def test_emulator_vanishing_mid_run(world: World, emulator: KobukiEmulator, tmp_path: Path, run_spec: SpecFor,
                                    cpu_wait: Any) -> None:
    marks: dict[str, float] = {}

    def on_sample(t: float, cov: float | None) -> None:
        if t >= 1.9 and "vanish" not in marks:
            emulator.close()                     # the robot is gone: socket closed mid-run
            marks["vanish"], marks["mark"] = time.perf_counter(), cpu_wait.total()
        marks["last"] = time.perf_counter()      # the run's final sample comes after the stop
        if "mark" in marks:
            marks["waited"] = cpu_wait.since(marks["mark"])

    with KobukiRobot(emulator.address, laser=EmulatorLaser(emulator)) as robot:
        out = run_on_robot(run_spec("kobuki", 60.0), robot, tmp_path, world, on_sample=on_sample)
    assert "vanish" in marks
    # ConnectionLost well within 1 s (EOF); on a loaded machine, plus what the threads waited for a CPU meanwhile
    assert marks["last"] - marks["vanish"] < 1.0 + marks["waited"]
    assert not out.record["completed"] and "robot error" in out.record["reason"]
    lines = (tmp_path / "results.jsonl").read_text().splitlines()
    saved = json.loads(lines[-1])
    # the frames already in flight when the emulator went (the loop may lag the stream) still count
    assert saved["completed"] is False and 1.9 <= saved["robot_time_s"] < 10.0


def test_stalled_link_ends_the_run_and_the_robot_is_stopped(world: World, emulator: KobukiEmulator, wait_for: WaitFor,
                                                            run_spec: SpecFor, cpu_wait: Any) -> None:
    marks: dict[str, float] = {}

    def on_sample(t: float, cov: float | None) -> None:
        if t >= 1.9 and "pause" not in marks:
            emulator.pause_stream()              # the peer stops sending without closing
            marks["pause"], marks["mark"] = time.perf_counter(), cpu_wait.total()
        marks["last"] = time.perf_counter()
        if "mark" in marks:
            marks["waited"] = cpu_wait.since(marks["mark"])

    with KobukiRobot(emulator.address, laser=EmulatorLaser(emulator)) as robot:
        out = run_on_robot(run_spec("kobuki", 60.0), robot, None, world, on_sample=on_sample)
    quiet = marks["last"] - marks["pause"]
    # the 1 s silence timeout, plus one poll (on a loaded machine, plus what the threads waited for a CPU)
    assert 0.95 <= quiet < 1.5 + marks["waited"]
    assert "no data" in out.record["reason"] and not out.record["completed"]
    assert wait_for(lambda: emulator.last_base_control == STOP)


def test_garbage_burst_and_a_few_bad_checksums_are_survived(world: World, emulator: KobukiEmulator, wait_for: WaitFor,
                                                            run_spec: SpecFor) -> None:
    rng = random.Random(7)
    garbage = bytes(rng.randrange(256) for _ in range(3000)) + b"\xaa\x55\x10" + b"\xaa\x55" * 20

    sent: list[float] = []

    def on_sample(t: float, cov: float | None) -> None:
        if t >= 0.9 and not sent:
            emulator.send_raw(garbage)
            emulator.corrupt_frames(3)
            sent.append(t)

    with KobukiRobot(emulator.address, laser=EmulatorLaser(emulator)) as robot:
        out = run_on_robot(run_spec("kobuki", 4.0), robot, None, world, on_sample=on_sample)
        extra = robot.read().extra
    assert sent and out.record["reason"].startswith("time limit"), out.record["reason"]
    assert extra["bad_checksums"] >= 3 and extra["dropped_bytes"] >= 3000
    assert extra["frames"] >= 180              # 4 s = 200 frames: only the corrupted ones are lost
    assert wait_for(lambda: emulator.last_base_control == STOP)


def test_every_checksum_wrong_is_a_protocol_error(world: World, emulator: KobukiEmulator, wait_for: WaitFor,
                                                  run_spec: SpecFor) -> None:
    def on_sample(t: float, cov: float | None) -> None:
        if t >= 0.9:
            emulator.corrupt_frames(10**9)      # from the sample at ~1 s of robot time on

    with KobukiRobot(emulator.address, laser=EmulatorLaser(emulator)) as robot:
        out = run_on_robot(run_spec("kobuki", 60.0), robot, None, world, on_sample=on_sample)
    assert "no valid frame" in out.record["reason"] and "bad checksums" in out.record["reason"]
    assert out.record["robot_time_s"] < 1.5
    assert wait_for(lambda: emulator.last_base_control == STOP)


class _DriveThenCtrlC(Explorer):
    """Drives forward, then the user presses Ctrl-C after 1 s of robot time."""

    t0: float | None = None

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        self.t0 = state.time if self.t0 is None else self.t0
        if state.time - self.t0 > 1.0:
            raise KeyboardInterrupt
        return Twist(0.2, 0.0)


def test_ctrl_c_stops_the_robot(world: World, emulator: KobukiEmulator, wait_for: WaitFor) -> None:
    geo = GridGeometry.covering(-6, -6, 6, 6, cell=0.1)
    with KobukiRobot(emulator.address, laser=EmulatorLaser(emulator)) as robot:
        run = ExplorationRun(robot, _DriveThenCtrlC(), OccupancyGrid(geo), max_time=30).run()
        assert wait_for(lambda: emulator.last_base_control == STOP)     # stopped by the run, still open
    assert run.reason.startswith("interrupted")
    assert 0.1 < run.metrics.path_length < 0.4


def test_pty_drive_odometry_and_vanishing(world: World, start: Pose) -> None:
    with KobukiEmulator(world, pose=start, pty=True, speedup=10.0) as emu:
        assert emu.address.startswith("/dev/")
        robot = KobukiRobot(emu.address, pose=start)
        try:
            assert robot.describe()["firmware"] == "1.2.0"
            clock = robot.make_clock(0.1)
            for _ in range(15):
                robot.command(Twist(0.2, 0.4))
                clock.tick()
            s = robot.read()
            true = emu.sim.read().true_pose
            assert true is not None
            # odometry from encoders and gyro follows the true pose to quantisation (mm, 0.01 deg),
            # give or take the frame the emulator may be ahead (0.2 m/s x 20 ms = 4 mm)
            assert math.hypot(s.pose.x - true.x, s.pose.y - true.y) < 0.006
            assert abs(s.pose.theta - true.theta) < math.radians(0.6)
            assert s.distance > 0.25
            emu.close()                                  # the device disappears
            with pytest.raises(ConnectionLost):
                for _ in range(100):
                    clock.tick()
        finally:
            robot.close()
