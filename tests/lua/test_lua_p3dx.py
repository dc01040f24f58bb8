"""Lua scripts on a P3-DX address: runs go to a connected P3DXRobot, here our emulator over TCP."""

from __future__ import annotations

import json
import math
import socket
import time

import pytest
from click.testing import CliRunner
from PIL import Image

from robotexp.cli import main
from robotexp.errors import ScriptError
from robotexp.robot import Twist
from robotexp.sim import LaserConfig
from robotexp_drivers.p3dx import constants as c
from robotexp_drivers.p3dx.emulator import P3DXEmulator

LASER = LaserConfig(range_max=3.0)


@pytest.fixture
def emu():
    # lockstep: the emulator steps as soon as the driver has answered a SIP, so a run goes as fast
    # as the client; speedup 1: idle SIPs every 100 ms, well inside the driver's 1 s silence limit
    with P3DXEmulator("ufmg-static", pose="path1", port=0, speedup=1.0, laser=LASER, lockstep=True) as e:
        yield e


def records(runner):
    return [json.loads(line) for line in (runner.out / "results.jsonl").read_text().splitlines()]


def stopped_then_closed(emu):
    """The driver's last words: VEL 0 and RVEL 0 (the stop), then CLOSE; nothing moves the robot."""
    cmds = list(emu.commands)
    assert cmds[-1].cmd == c.CMD_CLOSE and emu.last_command.cmd == c.CMD_CLOSE
    last_vel = next(k for k in reversed(cmds) if k.cmd == c.CMD_VEL)
    last_rvel = next(k for k in reversed(cmds) if k.cmd == c.CMD_RVEL)
    assert last_vel.arg == 0 and last_rvel.arg == 0 and emu.commanded == (0, 0)
    assert emu.sessions == 1                      # one connection for the whole script


def nearest(trail, x, y, theta):
    """The pose of `trail` nearest (x [m], y [m], theta [rad]): a robot turning in place has many
    poses at one point, so a radian counts as a metre."""
    return min(trail, key=lambda p: math.hypot(x - p.x, y - p.y) + abs(math.remainder(theta - p.theta, 2 * math.pi)))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def at_rest(emu, timeout=30.0):
    """Wait (the test is the operator) until the emulated robot stands still and the driver has had a SIP
    since: a run's stop is a command, and the P3-DX then decelerates over several cycles (from a fast turn
    up to half a radian, whenever the run's time limit lands; a loaded machine changes the trajectory)."""
    deadline = time.monotonic() + timeout
    while True:
        sips = emu.sips_sent         # (the emulator's thread owns its simulator: attributes read as they are)
        if emu.sim.commanded == Twist.ZERO:
            break
        assert time.monotonic() < deadline, "the robot still moves after the run"
        time.sleep(0.02)
    while emu.sips_sent < sips + 2:          # that cycle's SIP and one more: the driver has the resting pose
        assert time.monotonic() < deadline, "no SIP after the robot stopped"
        time.sleep(0.02)


def test_script_explores_through_the_emulator(lua, emu):
    trail = []                                  # every true pose of the emulated robot, in order
    advance = emu.sim.advance

    def advance_and_note(dt):
        advance(dt)
        trail.append(emu.sim.true_pose)
    emu.sim.advance = advance_and_note
    script = f"""
robot.setAddress("{emu.address}")
robot.setMaxSpeed(400)
robot.setMaxLaserRange(2500)
robot.moveMobileSim(4200, 4200, -135)
exploration.setMethod(ExplorationMethod.FRONTIER)
exploration.setMaxTime(30000)
exploration.start()
exploration.wait()
print("ended")
local x, y, th = robot.getPose()
print(x, y, th)
print(exploration.elapsedTime(), tostring(exploration.results().coverage))
mapView.saveMapImage("p3dx.png")
exploration.setWorld("ufmg-static")
exploration.setMaxTime(3000)
exploration.start()
exploration.wait()
print("ended")
print(robot.getPose())
"""
    result = lua(script, on_print=lambda line: at_rest(emu) if line == "ended" else None)
    assert result.exit_code == 0
    first, second = records(lua)
    # SIM_SET_POSE went out with the pose in mm, mm, deg, and the emulator's SimRobot was put there:
    # the pose the driver reports at the end (odometry from that pose) is where the SimRobot really
    # is (not moved, they would differ by the 11.9 m and 180 deg from path1); both read once the robot
    # stands still (measured under load 10: 0.1 mm, 0.001 rad)
    assert any(k.cmd == c.CMD_SIM_SET_POSE and k.arg == (4200, 4200, -135) for k in emu.commands)
    assert lua.lines[0] == lua.lines[3] == "ended"
    x, y, th = (float(v) for v in lua.lines[1].split("\t"))
    x2, y2, th2 = (float(v) for v in lua.lines[4].split("\t"))
    truth = emu.sim.true_pose
    assert math.hypot(x2 / 1000 - truth.x, y2 / 1000 - truth.y) < 0.02
    assert abs(math.remainder(math.radians(th2) - truth.theta, 2 * math.pi)) < 0.05
    assert first["start_pose"] == pytest.approx([4.2, 4.2, math.radians(-135)], abs=2e-3)
    assert math.hypot(truth.x - 4.2, truth.y - 4.2) > 0.3       # it explored from there
    assert min(math.hypot(p.x - 4.2, p.y - 4.2) for p in trail) < 0.01   # the SimRobot was put there
    # the record: the robot's, no ground truth, the script's settings applied
    assert first["world"] == "p3dx" and first["robot"] == "p3dx" and first["address"] == emu.address
    assert first["coverage"] is None and first["map_iou"] is None and lua.lines[2] == "30000\tnil"
    assert first["robot_time_s"] == pytest.approx(30.0, abs=0.15) and first["path_length_m"] > 1.0
    assert first["max_speed_m_s"] == 0.4 and first["laser_range_m"] == 2.5 and first["script"] == "script.lua"
    with Image.open(lua.out / "p3dx.png") as img:
        assert img.width > 100 and img.height > 100
    # setWorld on a robot: ground truth only; the robot starts where the first run left it (not at
    # the world's default start, path1): where getPose saw it at rest (measured: 0.6 mm, 0.008 rad)
    assert second["world"] == "ufmg-static" and second["coverage"] is not None and second["coverage"] > 0
    assert math.dist(second["start_pose"][:2], (x / 1000, y / 1000)) < 0.02
    assert abs(math.remainder(second["start_pose"][2] - math.radians(th), 2 * math.pi)) < 0.05
    sx, sy, sth = second["start_pose"]                          # a pose the SimRobot really had
    was = nearest(trail, sx, sy, sth)
    assert math.hypot(sx - was.x, sy - was.y) < 0.05
    assert abs(math.remainder(sth - was.theta, 2 * math.pi)) < 0.1
    stopped_then_closed(emu)


def test_error_and_timeout_stop_the_robot_and_keep_the_run(lua, emu):
    with pytest.raises(ScriptError, match=r"^script.lua:4: boom$"):
        lua(f'robot.setAddress("{emu.address}")\nexploration.setMaxTime(2000)\n'
            'exploration.start(); exploration.wait()\nerror("boom")')
    stopped_then_closed(emu)
    assert records(lua)[0]["robot_time_s"] == pytest.approx(2.0, abs=0.15)


def test_timeout_stops_a_run_on_the_robot(lua, emu):
    with pytest.raises(ScriptError, match=r"stopped by --timeout after 1.5 s; the 1 run"):
        # at 100 mm/s the exploration needs minutes of robot time: still going at the deadline, however
        # fast the lockstep emulator runs (at the default speed it could end within 1.5 s of wall time)
        lua(f'robot.setAddress("{emu.address}")\nrobot.setMaxSpeed(100)\nexploration.setMaxTime(600000)\n'
            'exploration.start(); exploration.wait()\nprint("not reached")', timeout=1.5)
    (rec,) = records(lua)
    assert rec["completed"] is False and "--timeout" in rec["reason"] and rec["robot_time_s"] < 600
    assert lua.lines == []
    stopped_then_closed(emu)


def test_world_option_keeps_the_simulator(lua, emu):
    lua(f'exploration.setMaxTime(2000)\nrobot.setAddress("{emu.address}")\nexploration.start()',
        world="ufmg-static")
    assert emu.sessions == 0 and len(lua.notices) == 1 and "embedded simulator" in lua.notices[0]
    (rec,) = records(lua)
    assert rec["world"] == "ufmg-static" and rec["coverage"] is not None and "address" not in rec


@pytest.mark.untimed
def test_nothing_listening_is_one_error_line(tmp_path):
    port = free_port()
    script = tmp_path / "robot.lua"
    script.write_text(f'print("before")\nrobot.setAddress("127.0.0.1:{port}")\nexploration.start()\n')
    result = CliRunner().invoke(main, ["run", str(script), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("robotexp: error:")]
    assert len(errors) == 1, result.stderr
    assert errors[0].startswith(f"robotexp: error: robot.lua:3: robot.setAddress('127.0.0.1:{port}'): cannot "
                                f"connect to a P3-DX (tcp 127.0.0.1:{port})")
    assert "Traceback" not in result.output and "before" in result.stdout
    assert not (tmp_path / "out" / "results.jsonl").exists()
