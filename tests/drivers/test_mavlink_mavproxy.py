"""MAVProxy (PyPI `MAVProxy`, from the `test` extra) flies the emulated rover as it flies ArduPilot Rover:
its `position` command (SET_POSITION_TARGET_LOCAL_NED, BODY_NED, type mask 3576: position only) and its
`guided LAT LON ALT` command (COMMAND_INT MAV_CMD_DO_REPOSITION with the CHANGE_MODE flag) move the
rover, and its fence module reports no breach at connect (SYS_STATUS geofence healthy). MAVProxy runs
as a subprocess, commands written to its standard input."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from robotexp.robot import Pose
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from test_mavlink_ardupilot_checks import HALL

try:
    import MAVProxy  # noqa: F401  (the third-party ground station these tests drive)
except ImportError:
    if os.environ.get("CI"):      # .ci/run installs it: there a missing peer is a failure, not a skip
        raise
    pytest.skip("MAVProxy is not installed: pip install --no-deps MAVProxy pynmeagps defusedxml",
                allow_module_level=True)
MAVPROXY = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent)) or shutil.which("mavproxy.py")


def _wait(cond: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


@pytest.fixture
def mavproxy(tmp_path: Path) -> Iterator[tuple[MavlinkEmulator, Callable[[str], None], Callable[[], str]]]:
    if MAVPROXY is None:
        if os.environ.get("CI"):
            pytest.fail("mavproxy.py is not on the PATH of this environment")
        pytest.skip("mavproxy.py is not on the PATH of this environment")
    with MavlinkEmulator(HALL, pose=Pose(0.0, 0.0, 0.0), speedup=10.0, origin=C.DEFAULT_ORIGIN) as emu:
        port = emu.address.rsplit(":", 1)[1]
        proc = subprocess.Popen(
            [sys.executable, MAVPROXY, f"--master=udpout:127.0.0.1:{port}", "--default-modules=",
             "--load-module=mode,arm,cmdlong,fence", f"--state-basedir={tmp_path}", f"--logfile={tmp_path / 'm.tlog'}",
             "--nowait"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            cwd=tmp_path)
        lines: list[str] = []

        def read() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()

        def say(cmd: str) -> None:
            assert proc.stdin is not None
            proc.stdin.write(cmd + "\n")
            proc.stdin.flush()

        def output() -> str:
            return "".join(lines)

        try:
            yield emu, say, output
        finally:
            proc.kill()                  # MAVProxy lets SIGTERM wait; it has nothing to save here
            proc.wait(timeout=10)
            reader.join(5)
            for pipe in (proc.stdin, proc.stdout):
                if pipe is not None:
                    pipe.close()


def test_mavproxy_position_and_guided_move_the_rover(
        mavproxy: tuple[MavlinkEmulator, Callable[[str], None], Callable[[], str]]) -> None:
    emu, say, output = mavproxy
    # MAVProxy has seen the vehicle's HEARTBEAT: its commands now carry system 1 as their target
    assert _wait(lambda: "online system 1" in output(), 30.0), output()
    say("mode GUIDED")
    assert _wait(lambda: emu.mode == C.ROVER_MODE_GUIDED, 5.0)
    say("arm throttle")
    assert _wait(lambda: emu.armed, 5.0)
    # `position 2 0 0`: 2 m ahead in BODY_NED; the rover faces east (NED yaw 90 deg)
    say("position 2 0 0")
    assert _wait(lambda: emu.sim.read().pose.x > 1.9 and emu.sim.read().velocity.v == 0.0, 10.0)
    p = emu.sim.read().pose
    assert (p.x, p.y) == pytest.approx((2.0, 0.0), abs=0.06)
    # `guided LAT LON 0`: 3 m north of the start (DO_REPOSITION, COMMAND_INT, latitude/longitude in degE7)
    lat0, lon0, _ = C.DEFAULT_ORIGIN
    lat = lat0 + math.degrees(3.0 / 6378137.0)
    say(f"guided {lat:.8f} {lon0:.8f} 0")
    assert _wait(lambda: emu.sim.read().pose.y > 2.9 and emu.sim.read().velocity.v == 0.0, 10.0)
    p = emu.sim.read().pose
    assert (p.x, p.y) == pytest.approx((0.0, 3.0), abs=0.06)
    assert emu.received["COMMAND_INT"] >= 1 and emu.acks[-1].result == C.MAV_RESULT_ACCEPTED
    assert "fence breach" not in output()      # SYS_STATUS: the geofence is healthy
