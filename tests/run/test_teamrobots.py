"""A team over the real drivers: two emulated P3-DX on TCP and an emulated Kobuki with an RPLidar on
pseudo-terminals, one shared world (`robotexp emulate p3dx,p3dx,kobuki+rplidar:pty`), explored by
`robotexp explore --team BACKEND:ADDRESS,...`; bad team addresses are one line and exit 2."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError
from robotexp.experiment import run_team_on_robots
from robotexp.robot import Twist
from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason
from robotexp.run.spec import RunSpec
from robotexp.run.team import TeamSpec
from robotexp.run.teamrobots import connect_team, emulate_team, parse_emulated, parse_members, team_starts
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.codec import BaseControl
from robotexp_drivers.p3dx.robot import P3DXRobot


@pytest.fixture
def emulated() -> Iterator[dict[str, Any]]:
    """`robotexp emulate p3dx,p3dx,kobuki+rplidar:pty --world ufmg-static --port 0 --speedup 5`."""
    devices = emulate_team(parse_emulated("p3dx,p3dx,kobuki+rplidar:pty"), "ufmg-static", port=0, speedup=5.0)
    try:
        yield dict(devices)
    finally:
        for _, device in reversed(devices):
            device.close()


def _wait(cond: Any, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not cond():
        time.sleep(0.01)
    return bool(cond())


def test_an_emulated_team_explores_one_world_through_the_drivers(tmp_path: Path, emulated: dict[str, Any]) -> None:
    p1, p2, kobuki, lidar = (emulated[k] for k in ("robot 1", "robot 2", "robot 3", "laser 3"))
    assert kobuki.address.startswith("/dev/") and lidar.address.startswith("/dev/")      # pseudo-terminals
    team = f"p3dx:{p1.address},p3dx:{p2.address},kobuki:{kobuki.address}+rplidar:{lidar.address}"
    starts = [d.sim.true_pose for d in (p1, p2, kobuki)]
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["explore", "--world", "ufmg-static", "--team", team, "--coordinator", "greedy",
                                       "--max-time", "20", "--out", str(out)])
    assert result.exit_code == 0, result.output
    (record,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    robots = record["robots"]
    assert record["team_size"] == 3 and record["robot"] == "p3dx,p3dx,kobuki"
    assert [r["robot"] for r in robots] == ["p3dx", "p3dx", "kobuki"]
    assert [r["address"] for r in robots] == [p1.address, p2.address, kobuki.address]
    # one frame: each robot was told it stands where the emulator put it (spread from path1, to the 1 mm of the
    # protocol). Where each ends is not compared: the emulators run on at 5x while the client thinks (0.2 s of
    # wall time is a second of robot time) and until the stop reaches them, so a loaded machine parts the last
    # pose read from the simulator's by tens of centimetres
    for r, start in zip(robots, starts, strict=True):
        assert math.dist(r["start_pose"][:2], (start.x, start.y)) < 2e-3
    # the robots drive (one may stand behind another for most of 20 s: 0.07 m seen)
    paths = [r["path_length_m"] for r in robots]
    assert sum(paths) > 1.5 and sorted(paths)[1] > 0.25, robots
    # every robot explores: the team's map covers what no single start sees, measured on the world's truth
    assert record["coverage"] > 0.15
    # each robot's time is its own stream's: the first robot past 20 s ends the run, and the team's time (robot
    # 1's) is within the client's lag of that (0.6 s seen on a loaded machine)
    assert record["reason"] == "time limit of 20 s reached" and 18.0 < record["robot_time_s"] < 22.0
    # every robot is stopped when the run ends
    assert _wait(lambda: p1.commanded == (0, 0) and p2.commanded == (0, 0))
    assert _wait(lambda: kobuki.last_base_control == BaseControl(0, 0))


def test_emulated_robots_see_each_other_and_collide(emulated: dict[str, Any]) -> None:
    p1, p2 = emulated["robot 1"], emulated["robot 2"]
    # robot 2 stands in robot 1's laser: its beam towards robot 2 ends on robot 2's footprint
    with P3DXRobot(p1.address, laser_range=3.0) as robot:
        a, b = p1.sim.true_pose, p2.sim.true_pose
        robot.move_to(a)            # odometry in the world's frame (the robot stays where it is)
        state = robot.read()
        bearing = math.atan2(b.y - a.y, b.x - a.x) - a.theta
        beam = int(np.argmin(np.abs(state.laser.angles - bearing)))
        sensor = (a.x + state.laser.offset_x * math.cos(a.theta), a.y + state.laser.offset_x * math.sin(a.theta))
        assert state.laser.ranges[beam] == pytest.approx(math.dist(sensor, (b.x, b.y)) - p2.sim.radius, abs=0.03)
        # driven at robot 2 it stops on touching it: one collision, counted as one with a robot
        heading = math.atan2(b.y - a.y, b.x - a.x)
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not p1.sim.robot_collisions:
            s = robot.read()
            turn = math.remainder(heading - s.pose.theta, math.tau)
            robot.command(Twist(0.2 if abs(turn) < 0.1 else 0.0, max(-0.5, min(0.5, 2 * turn))))
            time.sleep(0.01)
        robot.command(Twist.ZERO)
        gap = math.dist((p1.sim.true_pose.x, p1.sim.true_pose.y), (b.x, b.y)) - p1.sim.radius - p2.sim.radius
        assert p1.sim.robot_collisions == 1 and 0.0 <= gap < 0.02


def test_a_robot_lost_mid_run_ends_the_team_run_and_every_robot_stops(emulated: dict[str, Any]) -> None:
    p1, p2, kobuki, lidar = (emulated[k] for k in ("robot 1", "robot 2", "robot 3", "laser 3"))
    members = parse_members(f"p3dx:{p1.address},p3dx:{p2.address},kobuki:{kobuki.address}+rplidar:{lidar.address}")

    class Vanish(RunObserver):
        def on_sample(self, run: Any, t: float, coverage: float | None) -> None:
            if t >= 2.0:
                p2.vanish()             # robot 2's simulator crashes: its link goes silent and closes
    robots = connect_team(members)
    try:
        spec = RunSpec(world="ufmg-static", method="frontier", max_time=30.0, localize="none")
        team = TeamSpec(robots=("p3dx", "p3dx", "kobuki"), members=tuple(m.text for m in members))
        out = run_team_on_robots(spec, team, robots, None, "ufmg-static", observers=[Vanish()], image=False)
        assert out.record.end is EndReason.ROBOT_ERROR and out.record.robot_time_s < 10.0, out.record.reason
        assert out.record.reason.startswith("robot error: robot 2: "), out.record.reason
        assert _wait(lambda: p1.commanded == (0, 0) and kobuki.last_base_control == BaseControl(0, 0))
    finally:
        for robot in robots:
            robot.close()


def test_a_robot_without_a_laser_ends_the_team_run_before_anyone_explores(emulated: dict[str, Any]) -> None:
    # the Kobuki connected without its laser: nothing to map with; the team waits 5 s of robot time for its first
    # scan, then ends as a robot error naming it, and every robot stops
    p1, p2, kobuki = (emulated[k] for k in ("robot 1", "robot 2", "robot 3"))
    members = parse_members(f"p3dx:{p1.address},p3dx:{p2.address},kobuki:{kobuki.address}")
    robots = connect_team(members)
    try:
        spec = RunSpec(world="ufmg-static", method="frontier", max_time=30.0, localize="none")
        team = TeamSpec(robots=("p3dx", "p3dx", "kobuki"), members=tuple(m.text for m in members))
        out = run_team_on_robots(spec, team, robots, None, "ufmg-static", image=False)
        record = out.record
        assert record.end is EndReason.ROBOT_ERROR and record.reason.startswith(
            "robot error: robot 3: the robot sent no laser scan in the first 5 s: frontier has nothing to map with; "
            "mount a laser"), record.reason
        assert 4.8 <= record.robot_time_s < 6.0
        assert record.robots is not None and record.robots[2]["path_length_m"] == 0.0       # the Kobuki stood
        assert _wait(lambda: p1.commanded == (0, 0) and p2.commanded == (0, 0)
                     and kobuki.last_base_control == BaseControl(0, 0))
    finally:
        for robot in robots:
            robot.close()


def test_a_coordinator_assigning_targets_beside_a_reactive_method_is_refused_before_the_robots_move(
        emulated: dict[str, Any]) -> None:
    p1, p2 = emulated["robot 1"], emulated["robot 2"]
    members = parse_members(f"p3dx:{p1.address},p3dx:{p2.address}")
    before = [d.sim.true_pose for d in (p1, p2)]
    robots = connect_team(members)
    try:
        spec = RunSpec(world="ufmg-static", method="bvp", max_time=30.0, localize="none")
        team = TeamSpec(robots=("p3dx", "p3dx"), coordinator="greedy", members=tuple(m.text for m in members))
        with pytest.raises(ConfigError, match="greedy assigns frontier targets, and method 'bvp' does not take"):
            run_team_on_robots(spec, team, robots, None, "ufmg-static", image=False)
        assert [d.sim.true_pose for d in (p1, p2)] == before        # not placed, not driven
    finally:
        for robot in robots:
            robot.close()


@pytest.mark.untimed
def test_both_sides_place_the_team_alike() -> None:
    world = builtin_world("dense")
    starts = team_starts(world, "2", [0.25, 0.25, 0.175])
    assert team_starts(world, "2", [0.25, 0.25, 0.175]) == starts
    assert (starts[0].x, starts[0].y) == (world.poses["2"].x, world.poses["2"].y)
    for i in range(3):
        for j in range(i):
            assert math.dist((starts[i].x, starts[i].y), (starts[j].x, starts[j].y)) >= 2 * 0.25 + 0.3 - 1e-9
    with pytest.raises(ConfigError, match="BACKEND:ADDRESS"):
        parse_members("p3dx:127.0.0.1:8101,kobuki")


@pytest.mark.parametrize(("team", "extra", "words"), [
    ("p3dx:127.0.0.1:8101,roomba:127.0.0.1:8102", ["--world", "dense"], ["robot 2", "unknown robot backend 'roomba'"]),
    ("p3dx:127.0.0.1:8101,p3dx", ["--world", "dense"], ["robot 2 'p3dx'", "BACKEND:ADDRESS"]),
    ("p3dx:/dev/no-such-robot", ["--world", "dense"], ["robot 1", "no device '/dev/no-such-robot'"]),
    ("p3dx:127.0.0.1:70000", ["--world", "dense"], ["TCP port must be 1..65535"]),
    ("p3dx:127.0.0.1:8101,p3dx:127.0.0.1:8101", ["--world", "dense"], ["robot 1's too"]),
    ("kobuki:/dev/null+lidar9:/dev/null", ["--world", "dense"], ["unknown laser 'lidar9'"]),
    ("p3dx:127.0.0.1:8101", [], ["need --world", "--team-poses"]),
    ("p3dx:127.0.0.1:1", ["--world", "dense"], ["robot 1 (p3dx:127.0.0.1:1) cannot be reached"]),
    ("p3dx:127.0.0.1:1", ["--world", "dense", "--localize", "slam"], ["no localizer"]),
])
@pytest.mark.untimed
def test_bad_team_addresses_are_one_line_and_exit_2(tmp_path: Path, team: str, extra: list[str],
                                                    words: list[str], one_line_error) -> None:
    result = CliRunner().invoke(main, ["explore", "--team", team, "--out", str(tmp_path / "out"), *extra])
    one_line_error(result, words, tmp_path / "out")


def test_emulate_serves_a_team_and_prints_the_team_explore_drives() -> None:
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "emulate", "p3dx,kobuki:pty", "--world",
                             "ufmg-static", "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(3)]
    finally:
        proc.send_signal(signal.SIGINT)         # Ctrl-C stops every emulator
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()                         # not left running for the tests after this one
            proc.communicate()
            raise
    assert proc.returncode == 0 and "emulator stopped" in err, err
    assert lines[0].startswith("robot 1: 127.0.0.1:") and lines[1].startswith("robot 2: /dev/"), lines
    assert lines[2].startswith("explore with: --world ufmg-static --team "), lines
    members = parse_members(lines[2].split("--team ")[1].strip())
    assert [m.backend for m in members] == ["p3dx", "kobuki"]
    assert [m.address for m in members] == [lines[0].split(": ")[1].strip(), lines[1].split(": ")[1].strip()]
