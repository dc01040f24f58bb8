"""A P3-DX with a laser device mounted (`robotexp.run.laser_mount.connect_with_laser`): the driver never
asks the P3-DX emulator for MobileSim's simulated laser, so the emulator sends no laser packets and
every scan comes from the LMS2xx emulator on its own pseudo-terminal."""

from __future__ import annotations

import time

from robotexp.run.laser_mount import LaserMountedRobot, connect_with_laser, robot_options
from robotexp.sim import mounted_source
from robotexp_drivers.lasers.lms2xx.emulator import LMS2xxEmulator
from robotexp_drivers.p3dx import constants as c
from robotexp_drivers.p3dx.emulator import P3DXEmulator

_LASER_COMMANDS = {c.CMD_SIM_LRF_ENABLE, c.CMD_OLD_SIM_LRF_ENABLE}


def test_p3dx_with_an_lms2xx_gets_no_simulated_laser_packets() -> None:
    assert robot_options("p3dx", True) == {"laser": False} and robot_options("p3dx", False) == {}
    assert robot_options("kobuki", True) == {}
    with P3DXEmulator("dense", pty=True, speedup=5.0) as p3dx, \
            LMS2xxEmulator(mounted_source(p3dx.sim), pty=True, speedup=5.0) as lms:
        with connect_with_laser("p3dx", p3dx.address, f"lms2xx:{lms.address}", "0,0,0") as robot:
            assert isinstance(robot, LaserMountedRobot)
            # a scan is paired once the pose history (every SIP since the laser was mounted) spans its
            # stamp; the scans taken before the mount are given the oldest pose
            deadline = time.monotonic() + 3.0
            state = robot.read()
            while robot.paired < 1 and time.monotonic() < deadline:
                time.sleep(0.01)
                state = robot.read()
            assert state.laser is not None and robot.paired >= 1
            # the LMS200's 181 beams over 180 deg, as the driver reads them from its own link
            assert state.laser.ranges.shape == (181,) and 0.1 < state.laser.nearest() < 8.0
            assert robot.robot._scan is None                     # type: ignore[attr-defined]
        sent = {cmd.cmd for cmd in p3dx.commands}
        assert c.CMD_VEL in sent or c.CMD_RVEL in sent         # the session went on (the stop at the end)
        assert not sent & _LASER_COMMANDS
    # without a mounted laser, the same driver asks for the simulated laser (the commands above matter)
    with P3DXEmulator("dense", pty=True, speedup=5.0) as p3dx:
        with connect_with_laser("p3dx", p3dx.address, None, None) as robot:
            assert robot.read().laser is not None
        assert {cmd.cmd for cmd in p3dx.commands} & _LASER_COMMANDS
