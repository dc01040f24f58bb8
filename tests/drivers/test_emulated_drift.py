"""Emulated robots whose odometry drifts (`robotexp emulate ... --odometry-error`), and the simulator's
ground truth read back through the P3-DX driver (MobileSim's SIMSTAT packet)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError
from robotexp.robot import Pose, Twist
from robotexp.sim import odometry_error
from robotexp.world.builtin import builtin_world
from robotexp_drivers.emulation import odometry_model
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.p3dx.emulator import P3DXEmulator
from robotexp_drivers.p3dx.robot import P3DXRobot


def _drive(robot: P3DXRobot, seconds: float) -> None:
    """An arc, then a stop held until the robot stands: at least 1 s of robot time, and its reported velocity
    zero for 0.5 s of it (robot time, from the robot's own states; a busy host delays the stop's packets)."""
    t0 = robot.read().time
    while robot.read().time - t0 < seconds:
        robot.command(Twist(0.3, 0.15))
        time.sleep(0.02)
    t1 = still = robot.read().time
    while True:
        robot.command(Twist.ZERO)
        time.sleep(0.02)
        state = robot.read()
        if abs(state.velocity.v) > 1e-4 or abs(state.velocity.w) > 1e-4:
            still = state.time
        if state.time - t1 >= 1.0 and state.time - still >= 0.5:
            return
        assert state.time - t1 < 20.0, "the robot did not stop within 20 s of robot time"


def _gap(a: Pose, b: Pose) -> float:
    return math.hypot(a.x - b.x, a.y - b.y)


@pytest.mark.parametrize("error", [None, "p3dx"])
def test_p3dx_driver_reports_drifting_odometry_and_the_simulators_truth(error: str | None) -> None:
    world = builtin_world("ufmg-static")
    start = world.poses["path1"]
    with P3DXEmulator(world, pose=start, port=0, speedup=8.0, odometry=error) as emu:
        with P3DXRobot(emu.address, laser=False) as robot:
            robot.move_to(start)
            _drive(robot, 6.0)
            state = robot.read()
            assert state.extra["collisions"] == 0 and state.distance > 1.5
            truth = emu.sim.true_pose            # the robot stands: the serving thread moves nothing
            assert state.true_pose is not None, "a simulator's SIMSTAT truth reaches the state"
            # the truth as the simulator has it (SIMSTAT: mm and whole degrees)
            assert _gap(state.true_pose, truth) < 0.002
            assert abs(math.remainder(state.true_pose.theta - truth.theta, math.tau)) < math.radians(0.6)
            drift = _gap(state.pose, state.true_pose)
            if error is None:
                assert drift < 0.01, f"exact encoders: odometry {state.pose} vs truth {state.true_pose}"
            else:
                # the P3-DX preset over ~3 m of arc: centimetres of drift, as the embedded simulator has
                assert drift > 0.02, f"the odometry error did not reach the driver (gap {drift * 1000:.1f} mm)"


def test_ground_truth_can_be_declined() -> None:
    world = builtin_world("ufmg-static")
    with P3DXEmulator(world, pose=world.poses["path1"], port=0, speedup=4.0) as emu:
        with P3DXRobot(emu.address, laser=False, ground_truth=False) as robot:
            time.sleep(0.3)
            assert robot.read().true_pose is None


@pytest.mark.untimed
def test_each_emulator_takes_an_odometry_error() -> None:
    world = builtin_world("ufmg-static")
    pose = world.poses["path1"]
    for cls in (P3DXEmulator, KobukiEmulator, MavlinkEmulator):
        assert "odometry" in cls.options
        emu = cls(world, pose=pose, port=0, odometry="kobuki:drift=0.5")
        try:
            assert emu.sim.odometry_error == odometry_error("kobuki:drift=0.5")
        finally:
            emu.close()
    assert odometry_model(None) is None
    with pytest.raises(ConfigError, match="unknown preset 'warp'"):
        odometry_model("warp")


@pytest.mark.parametrize("args, words", [
    (["emulate", "p3dx", "--odometry-error", "warp"], "unknown preset 'warp'"),
    (["emulate", "kobuki", "--odometry-error", "slip=abc"], "is not a number"),
    (["emulate", "rplidar", "--odometry-error", "p3dx"], "--odometry-error is not an option of the 'rplidar'"),
])
def test_bad_odometry_errors_are_one_line_and_exit_2(args: list[str], words: str) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert words in result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1


def test_explore_on_a_robot_without_a_laser_says_nothing_of_scan_matching(tmp_path: Path) -> None:
    # a Kobuki connected without a laser has no scan to match: the run ends as a robot error (nothing to map
    # with), and no line says that scan matching corrects its odometry
    world = builtin_world("ufmg-static")
    with KobukiEmulator(world, pose=world.poses["path1"], speedup=30.0) as emu:
        result = CliRunner().invoke(main, ["explore", "--robot", "kobuki", "--address", emu.address, "--world",
                                           "ufmg-static", "--max-time", "10", "--out", str(tmp_path)])
    assert result.exit_code == 1, result.output
    assert "nothing to map with" in result.output and "scan matching" not in result.output, result.output


def test_explore_on_a_robot_says_auto_localization_is_on(tmp_path: Path) -> None:
    world = builtin_world("ufmg-static")
    with P3DXEmulator(world, pose=world.poses["path1"], port=0, speedup=8.0, odometry="p3dx") as emu:
        result = CliRunner().invoke(main, ["explore", "--robot", "p3dx", "--address", emu.address, "--world",
                                           "ufmg-static", "--max-time", "3", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "--localize auto: scan matching corrects the robot's odometry" in result.output
    record = (tmp_path / "results.jsonl").read_text().splitlines()[-1]
    assert '"localize": "scan-match"' in record and '"ate_m": null' not in record   # SIMSTAT gives the truth
