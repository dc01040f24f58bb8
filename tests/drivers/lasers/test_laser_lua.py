"""A laser in Lua (`robot.setLaser`): a script run through `robotexp run` explores with the Kobuki
emulator and the RPLidar emulator on two pseudo-terminals; the laser's address obeys the sandbox's
address rule; a malformed laser spec is one ScriptError with script:line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from robotexp.errors import ScriptError
from robotexp.lua import run_script
from robotexp_drivers.kobuki.codec import BaseControl

CLI = [sys.executable, "-m", "robotexp.cli"]


def _explore(tmp_path: Path, kobuki: str, laser: str | None, max_time_ms: int,
             status: int = 0) -> tuple[dict, subprocess.CompletedProcess]:
    """Run a frontier exploration script on the Kobuki at `kobuki` (with `laser` mounted 0, 0, 0 when
    given) through `robotexp run --robot kobuki`, which exits with `status`; its record and the process."""
    out = tmp_path / ("with" if laser else "without")
    script = tmp_path / "laser.lua"
    mount = f'robot.setLaser("rplidar:{laser}", 0, 0, 0)\n' if laser else ""
    script.write_text(f'robot.setAddress("{kobuki}")\n{mount}exploration.setWorld("ufmg-static")\n'
                      "exploration.setMethod(ExplorationMethod.FRONTIER)\n"
                      f"exploration.setMaxTime({max_time_ms})\nexploration.start()\nexploration.wait()\n"
                      'print(string.format("coverage %.4f", exploration.results().coverage))\n')
    done = subprocess.run(CLI + ["run", str(script), "--robot", "kobuki", "--out", str(out)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == status, done.stdout + done.stderr
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 1
    assert status or f"coverage {records[0]['coverage']:.4f}" in done.stdout
    return records[0], done


def test_script_explores_with_a_kobuki_and_an_rplidar_on_ptys(devices, tmp_path: Path) -> None:
    kobuki, lidar = devices
    record, _ = _explore(tmp_path, kobuki.address, lidar.address, 25000)
    assert record["robot"] == "kobuki" and record["address"] == kobuki.address and record["world"] == "ufmg-static"
    # 25 s of robot time at 0.3 m/s from path1 with a 360 deg laser maps a good part of ufmg-static
    assert 0.25 < record["coverage"] <= 1.0 and record["path_length_m"] > 1.0, record
    assert kobuki.last_base_control == BaseControl(0, 0)          # stopped at the end of the script
    # the Kobuki reports no scan of its own: from the same place the base alone has nothing to map with. The run
    # holds it for 5 s of robot time, ends as a robot error, and the script stops there, its record written
    alone, done = _explore(tmp_path, kobuki.address, None, 30000, status=1)
    assert alone["end"] == "robot error" and alone["path_length_m"] == 0.0 and alone["robot_time_s"] < 6.0, alone
    assert (f"laser.lua:6: exploration.wait: run {alone['run']} ended: robot error: the robot sent no laser scan in "
            "the first 5 s: frontier has nothing to map with; mount a laser") in done.stderr, done.stderr
    assert "coverage" not in done.stdout
    assert kobuki.last_base_control == BaseControl(0, 0)


def _script(tmp_path: Path, code: str, **kwargs: object) -> None:
    path = tmp_path / "s.lua"
    path.write_text(code)
    run_script(path, out=tmp_path / "out", emit=lambda _: None, notice=lambda _: None, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("call, message", [
    ('robot.setLaser("/dev/ttyUSB0", 0, 0, 0)', "NAME:ADDRESS"),
    ('robot.setLaser("nolaser:/dev/ttyUSB0", 0, 0, 0)', "unknown laser 'nolaser'; available: "),
    ('robot.setLaser("rplidar:/dev/ttyUSB0", 0, 0)', "expected 4 argument(s), got 3"),
    ('robot.setLaser("rplidar:/dev/ttyUSB0", 0, "a", 0)', "argument 3 must be a number"),
    ('robot.setLaser("rplidar:/dev/ttyUSB0", 0, 0, 0/0)', "argument 4 must be a number (finite)"),
])
@pytest.mark.untimed
def test_a_malformed_laser_is_one_script_error_with_its_line(tmp_path: Path, call: str, message: str) -> None:
    with pytest.raises(ScriptError) as err:
        _script(tmp_path, f'robot.setAddress("/dev/ttyUSB9")\n{call}\n')
    text = str(err.value)
    assert text.startswith("s.lua:2:") and "robot.setLaser(" in text and message in text and "\n" not in text


def test_sandbox_refuses_a_laser_address_not_allowed(devices, tmp_path: Path) -> None:
    kobuki, lidar = devices
    both = (kobuki.address, lidar.address)

    def mount(address: str, allowed: tuple[str, ...]) -> None:
        _script(tmp_path, f'robot.setAddress("{kobuki.address}")\nrobot.setLaser("rplidar:{address}", 0, 0, 0)\n'
                "exploration.setMaxTime(2000)\nexploration.start()\n", robot="kobuki", sandbox=True,
                allow_addresses=allowed)

    refused = r"s\.lua:2: robot\.setLaser\(.*\): refused by --sandbox"
    with pytest.raises(ScriptError, match=refused):
        mount(lidar.address, (kobuki.address,))               # the robot allowed, not the laser
    for url in (f"spy://{lidar.address}", "socket://127.0.0.1:2112", f"{lidar.address}?logging=debug"):
        with pytest.raises(ScriptError, match=refused):       # pyserial URL handlers: never, even for an allowed device
            mount(url, both)
    assert not (tmp_path / "out" / "results.jsonl").exists()
    mount(lidar.address, both)                                # allowed: the run goes through the laser
    record = json.loads((tmp_path / "out" / "results.jsonl").read_text().splitlines()[-1])
    assert record["robot"] == "kobuki" and record["path_length_m"] > 0.05


@pytest.mark.untimed
def test_on_the_embedded_simulator_the_laser_is_not_used_and_said_once(tmp_path: Path) -> None:
    path = tmp_path / "sim.lua"
    path.write_text('robot.setLaser("rplidar:/dev/ttyUSB0", 100, 0, 0)\nexploration.setMaxTime(1000)\n'
                    "exploration.start()\nexploration.start()\n")
    notices: list[str] = []
    run_script(path, out=tmp_path / "out", emit=lambda _: None, notice=notices.append)
    assert len(notices) == 1 and "robot.setLaser('rplidar:/dev/ttyUSB0')" in notices[0]
    records = (tmp_path / "out" / "results.jsonl").read_text().splitlines()
    assert len(records) == 2 and all("address" not in json.loads(r) for r in records)
