"""Campaigns on a robot with a laser (`address`, `laser`, `laser_pose` keys of a set): a campaign
process drives the Kobuki emulator and the RPLidar emulator through two pseudo-terminals, one run
after another whatever --jobs, asks for the robot to be placed between runs (the test is the
operator: it carries the emulated robot back to the start), stops the robot between runs and on
Ctrl-C, and refuses bad keys before any run (one line naming the file and the key, exit 2)."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.campaign.spec import load_campaign
from robotexp.cli import main
from robotexp.robot import Pose
from robotexp_drivers.kobuki.codec import BaseControl

CLI = [sys.executable, "-m", "robotexp.cli"]


def _campaign(tmp_path: Path, robot: str, laser: str, *, seeds: str = "[0, 1]", max_time: int = 12,
              extra: str = "") -> Path:
    path = tmp_path / "robot.toml"
    path.write_text(f'[campaign]\nname = "onrobot"\nmax_time_s = {max_time}\nseeds = {seeds}\n\n[[set]]\n'
                    f'world = "ufmg-static"\nposes = ["path1"]\nmethods = ["frontier"]\nrobot = "kobuki"\n'
                    f'address = "{robot}"\nlaser = "rplidar:{laser}"\nlaser_pose = [0, 0, 0]\n{extra}')
    return path


def _records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def test_a_campaign_runs_one_after_another_on_a_kobuki_with_an_rplidar(devices, start: Pose, tmp_path: Path) -> None:
    kobuki, lidar = devices
    out = tmp_path / "out"
    proc = subprocess.Popen(CLI + ["campaign", "run", str(_campaign(tmp_path, kobuki.address, lidar.address)),
                                   "--jobs", "4", "--out", str(out)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdin is not None and proc.stderr is not None
    said = []
    try:
        for line in proc.stderr:                 # the campaign's lines until it asks for the robot
            said.append(line)
            if "put it at" in line:
                break
        text = "".join(said)
        assert f"runs on kobuki at {kobuki.address} with rplidar:{lidar.address}" in text, text
        assert "one run at a time" in text and "--jobs 4 does not apply" in text and "2 runs, 1 jobs" in text
        assert "1/2 " in text and "run 2/2 (frontier): the kobuki is stopped; put it at path1" in text, text
        # the first run is written before the second starts, and the robot was stopped after it
        assert len(_records(out)) == 1 and kobuki.last_base_control == BaseControl(0, 0)
        with kobuki.lock:                          # the operator carries the robot back to path1
            kobuki.sim.move_to(start)
        proc.stdin.write("\n")
        proc.stdin.flush()
        rest = proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, text + rest
    records = _records(out)
    assert [r["seed"] for r in records] == [0, 1]
    for r in records:
        assert r["robot"] == "kobuki" and r["address"] == kobuki.address and r["world"] == "ufmg-static"
        assert r["laser"] == f"rplidar:{lidar.address}" and r["laser_pose"] == "0,0,0", r
        # 12 s at 0.3 m/s from path1 with a 360 deg laser maps a tenth of ufmg-static (the base alone: < 0.05)
        assert r["coverage"] > 0.1 and r["path_length_m"] > 0.5 and r["collisions"] == 0, r
    assert kobuki.last_base_control == BaseControl(0, 0)          # stopped at the end


def test_ctrl_c_ends_a_campaign_on_a_robot_with_the_robot_stopped(devices, tmp_path: Path) -> None:
    kobuki, lidar = devices
    out = tmp_path / "out"
    path = _campaign(tmp_path, kobuki.address, lidar.address, max_time=600)
    proc = subprocess.Popen(CLI + ["campaign", "run", str(path), "--out", str(out)], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        with kobuki.lock:
            origin = kobuki.sim.true_pose
        while True:                  # exploring: the robot has driven 5 cm (a forward command alone is not
            with kobuki.lock:        # travel yet; under load the record could be taken before it moved)
                here = kobuki.sim.true_pose
            if math.hypot(here.x - origin.x, here.y - origin.y) > 0.05:
                break
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        # then the campaign's control loop decides anew (a command other than the one in force: the reader only
        # repeats that one), so it has read states since the robot moved, not stalled (a kernel compiling)
        driving = kobuki.last_base_control
        while kobuki.last_base_control in (driving, BaseControl(0, 0)):
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    records = _records(out)
    assert len(records) == 1 and records[0]["reason"].startswith("interrupted") and records[0]["path_length_m"] > 0
    assert kobuki.last_base_control == BaseControl(0, 0)


@pytest.mark.untimed
def test_laser_pose_is_read_as_the_command_line_reads_it(tmp_path: Path) -> None:
    simulated_set = '\n[[set]]\nworld = "ufmg-static"\nposes = ["path1"]\nmethods = ["frontier"]\nseeds = [5]\n'
    camp = load_campaign(_campaign(tmp_path, "/dev/ttyUSB0", "/dev/ttyUSB1", seeds="[0]", extra=simulated_set))
    on_robot, simulated = camp.runs
    devices = camp.devices_of(on_robot)
    assert devices is not None and camp.devices_of(simulated) is None
    assert (devices.backend, devices.address, devices.laser, devices.laser_pose) == (
        "kobuki", "/dev/ttyUSB0", "rplidar:/dev/ttyUSB1", "0,0,0")


@pytest.mark.parametrize("keys, where, message", [
    ('laser = "rplidar:/dev/ttyUSB1"', "[[set]] #1.laser", "give `address`"),
    ('laser_pose = "0,0,0"', "[[set]] #1.laser_pose", "give `address`"),
    ('address = "/dev/ttyUSB0"\nrobot = "roomba"', "[[set]] #1.robot", "no robot backend 'roomba'"),
    ('address = 5\nrobot = "kobuki"', "[[set]] #1.address", "expected the robot's address"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nlaser = "rplidar"', "[[set]] #1.laser", "NAME:ADDRESS"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nlaser = "sonarx:/dev/ttyUSB1"', "[[set]] #1.laser",
     "unknown laser 'sonarx'"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nlaser = "rplidar:/dev/ttyUSB1"\nlaser_pose = "1,2"',
     "[[set]] #1.laser_pose", "X,Y,THETA"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nlaser = "rplidar:/dev/ttyUSB1"\nlaser_pose = [1, 2]',
     "[[set]] #1.laser_pose", "[X, Y, THETA]"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nlaser_pose = "1,2,3"', "[[set]] #1.laser_pose", "needs `laser`"),
    ('address = "/dev/ttyUSB0"\nrobot = "kobuki"\nposes = ["nowhere"]', "[[set]] #1.poses", "no pose 'nowhere'"),
])
def test_bad_robot_keys_are_one_line_before_any_run(tmp_path: Path, keys: str, where: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(f'[[set]]\nworld = "ufmg-static"\nmethods = ["frontier"]\n{keys}\n')
    result = CliRunner().invoke(main, ["campaign", "run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert result.output.count("\n") == 1 and f"{path}: {where}: " in result.output and message in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.untimed
def test_a_campaign_on_a_robot_refuses_a_cluster(tmp_path: Path) -> None:
    path = _campaign(tmp_path, "/dev/ttyUSB0", "/dev/ttyUSB1")
    result = CliRunner().invoke(main, ["campaign", "run", str(path), "--cluster", "local:2",
                                       "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "run without --cluster" in result.output and str(path) in result.output


@pytest.mark.untimed
def test_a_robot_that_cannot_be_reached_ends_the_campaign_with_one_line(tmp_path: Path) -> None:
    path = _campaign(tmp_path, str(tmp_path / "no-kobuki"), str(tmp_path / "no-rplidar"))
    result = CliRunner().invoke(main, ["campaign", "run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    last = result.output.splitlines()[-1]
    assert last.startswith("robotexp: error: kobuki: cannot open ") and "no-kobuki" in last
