"""A third-party RPLidar client reads the RPLidar emulator on a pseudo-terminal: PyPI
`rplidar-roboticia` (module `rplidar`; installed from the `test` extra, never committed). It asks
GET_INFO and GET_HEALTH, sets the motor PWM, starts SCAN, collects turns, and stops."""

from __future__ import annotations

import numpy as np
import pytest
from scan_sources import BoxSource

from robotexp_drivers.lasers.rplidar import constants as C
from robotexp_drivers.lasers.rplidar.emulator import RPLidarEmulator

rplidar = pytest.importorskip("rplidar")


def test_rplidar_roboticia_reads_the_emulator() -> None:
    src = BoxSource()
    with RPLidarEmulator(src, pty=True) as emu:
        lidar = rplidar.RPLidar(emu.address, timeout=1)
        # The A1's USB adapter spins the motor from DTR; a pseudo-terminal has no modem lines and the
        # kernel refuses the ioctl (ENOTTY), so the client's DTR calls become no-ops here.
        lidar._serial.setDTR = lambda level: None
        try:
            info = lidar.get_info()
            assert info == {"model": 24, "firmware": (1, 29), "hardware": 7,
                            "serialnumber": emu.serial.hex().upper()}
            assert lidar.get_health() == ("Good", 0)
            turns = []
            for scan in lidar.iter_scans(min_len=100):
                turns.append(scan)
                if len(turns) == 3:
                    break
            assert emu.motor_pwm == 660
            for scan in turns:
                quality, angle_cw, dist_mm = np.array(scan).T
                assert len(scan) == 360 and np.all(quality == 47)
                want = src.ranges(np.radians(-angle_cw), 12.0) * 1000.0    # clockwise -> laser frame
                assert np.max(np.abs(dist_mm - want)) <= 0.125 + 1e-6
        finally:
            lidar.stop()
            lidar.stop_motor()
            lidar.disconnect()
        assert not emu.scanning and emu.requests[-2].cmd == C.CMD_STOP and emu.motor_pwm == 0


def test_rplidar_roboticia_reads_the_express_scan() -> None:
    src = BoxSource()
    with RPLidarEmulator(src, pty=True) as emu:
        lidar = rplidar.RPLidar(emu.address, timeout=1)
        lidar._serial.setDTR = lambda level: None          # no DTR on a pseudo-terminal (see above)
        try:
            rows = []
            for _, _, angle_cw, dist_mm in lidar.iter_measures(scan_type="express"):
                rows.append((angle_cw, dist_mm))
                if len(rows) == 1500:
                    break
        finally:
            lidar.stop()
            lidar.stop_motor()
            lidar.disconnect()
    angle_cw, dist_mm = np.array(rows).T
    assert np.allclose(np.diff(angle_cw[:100]) % 360, 0.5)          # 720 samples a turn
    # Its sample k of a capsule lies at start + (k + 1) * step, one sample past Slamtec's SDK rule
    # (start + k * step); with that the distances agree to the millimetre the capsule carries.
    want = np.rint(src.ranges(np.radians(-(angle_cw - 0.5)), 12.0) * 1000.0)
    assert np.array_equal(dist_mm, want)
