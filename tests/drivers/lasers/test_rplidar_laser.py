"""The RPLidar driver against the RPLidar emulator through a real pseudo-terminal and TCP: handshake,
identity, geometry (clockwise device angles in the counter-clockwise laser frame) and ranges of the
ScanSource, the A1's turn rate, STOP on close, health handling, and a laser lost mid-stream."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

import pytest
from scan_sources import BoxSource, seconds_until_lost

from robotexp.errors import ProtocolError
from robotexp_drivers.lasers.rplidar import RPLidarLaser
from robotexp_drivers.lasers.rplidar import constants as C
from robotexp_drivers.lasers.rplidar.codec import Health, Request
from robotexp_drivers.lasers.rplidar.emulator import RPLidarEmulator


@pytest.fixture(params=["pty", "tcp"])
def served(request: pytest.FixtureRequest) -> Iterator[tuple[RPLidarEmulator, BoxSource]]:
    src = BoxSource()
    with RPLidarEmulator(src, pty=request.param == "pty") as emu:
        yield emu, src


def test_driver_reads_the_emulated_a1(served: tuple[RPLidarEmulator, BoxSource], cpu_wait: Any) -> None:
    emu, src = served
    with RPLidarLaser(emu.address) as laser:
        assert laser.info.model == C.A1M8_MODEL and laser.info.firmware == (1, 29) and laser.health.status == 0
        assert "A1 series" in laser.describe()
        g = laser.geometry
        assert g.beams == 360 and g.range_max == 12.0 and g.increment == pytest.approx(math.radians(1))
        first = laser.wait_scan(-1, 10.0)
        mark = cpu_wait.total()
        later = laser.wait_scan(first.seq + 4, 10.0)
        # 360 samples of 508 us: 0.183 s a turn (loose: 2 shared cores; a loaded machine may slow the emulator's
        # turns, and a late reader gets several at once: +- what its threads waited for a CPU)
        turns, took = later.seq - first.seq, later.stamp - first.stamp
        assert abs(took - 0.18288 * turns) <= 0.25 * 0.18288 * turns + cpu_wait.since(mark), (turns, took)
        want = src.ranges(g.angles(), 12.0)
        got = later.scan.ranges
        assert np.all(np.isfinite(got)) and np.max(np.abs(got - want)) <= 0.000125 + 1e-9
        # the room's far wall (+y, 3.2 m) is on the left: beam +90 deg, counter-clockwise
        assert got[270] == pytest.approx(3.2, abs=0.000125) and got[90] == pytest.approx(0.8, abs=0.000125)
    assert emu.requests[-1].cmd == C.CMD_STOP and not emu.scanning


def test_a2_at_high_speed_baud_and_motor_pwm(cpu_wait: Any) -> None:
    src = BoxSource()
    with RPLidarEmulator(src, model="A2M8", samples=720, pty=True) as emu, \
            RPLidarLaser(emu.address, baudrate=C.BAUD_HIGH_SPEED, beams=720, motor_pwm=660) as laser:
        assert emu.motor_pwm == 660 and laser.info.model >> 4 == 2
        a = laser.wait_scan(laser.wait_scan(-1, 10.0).seq, 10.0)
        mark = cpu_wait.total()
        b = laser.wait_scan(a.seq + 3, 10.0)
        # 720 samples of 250 us a turn (+-25 %; on a loaded machine also +- what the threads waited for a CPU:
        # a late reader gets several turns at once, a late emulator makes a turn long)
        turns, took = b.seq - a.seq, b.stamp - a.stamp
        assert abs(took - 720 * 250e-6 * turns) <= 0.25 * 720 * 250e-6 * turns + cpu_wait.since(mark), (turns, took)
        assert np.max(np.abs(b.scan.ranges - src.ranges(laser.geometry.angles(), 12.0))) <= 0.000125 + 1e-9


def test_health_error_is_reset_once() -> None:
    with RPLidarEmulator(BoxSource(), health=Health(C.HEALTH_ERROR, 0x8001)) as emu:
        with RPLidarLaser(emu.address) as laser:        # RESET clears the emulated protection stop
            assert laser.health.status == C.HEALTH_GOOD
            laser.wait_scan(-1, 10.0)
        assert [r.cmd for r in emu.requests][:5] == [C.CMD_STOP, C.CMD_GET_INFO, C.CMD_GET_HEALTH, C.CMD_RESET,
                                                      C.CMD_GET_HEALTH]


def test_health_error_that_stays_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    with RPLidarEmulator(BoxSource(), health=Health(C.HEALTH_ERROR, 0x8001)) as emu:
        monkeypatch.setattr(emu, "_answer", _sticky_error(emu))
        with pytest.raises(ProtocolError, match="hardware error .*0x8001"):
            RPLidarLaser(emu.address)


def _sticky_error(emu: RPLidarEmulator):  # noqa: ANN202 - a test double of the emulator's answer
    answer = emu._answer

    def sticky(req):  # noqa: ANN001, ANN202
        out = answer(req)
        emu.health = Health(C.HEALTH_ERROR, 0x8001)
        return out
    return sticky


def test_laser_lost_mid_stream_raises_within_a_second(served: tuple[RPLidarEmulator, BoxSource],
                                                      cpu_wait: Any) -> None:
    emu, _ = served
    with RPLidarLaser(emu.address, timeout=1.0) as laser:
        assert seconds_until_lost(laser, emu.close, cpu_wait=cpu_wait) < 1.0


def test_garbage_in_the_stream_costs_at_most_the_turn_it_hits() -> None:
    with RPLidarEmulator(BoxSource()) as emu, RPLidarLaser(emu.address) as laser:
        seq = laser.wait_scan(-1, 10.0).seq
        emu.send_raw(bytes(range(7, 250, 3)))
        scans = [laser.wait_scan(seq, 10.0)]
        for _ in range(3):
            scans.append(laser.wait_scan(scans[-1].seq, 10.0))
        assert laser._decoder.dropped_bytes > 0
        good = [np.all(np.isfinite(s.scan.ranges)) for s in scans]
        assert sum(good) >= 3


def test_driver_takes_over_a_lidar_left_scanning() -> None:
    import serial

    from robotexp_drivers.lasers.rplidar.codec import request
    with RPLidarEmulator(BoxSource(), pty=True) as emu:
        with serial.Serial(emu.address, timeout=0.2) as port:      # a previous program's SCAN
            port.write(request(C.CMD_SCAN))
            port.read(2000)
        assert emu.scanning
        time.sleep(0.3)
        with RPLidarLaser(emu.address) as laser:
            assert laser.wait_scan(-1, 10.0).scan.ranges.shape == (360,)


def test_driver_reads_the_express_scan(served: tuple[RPLidarEmulator, BoxSource], cpu_wait: Any) -> None:
    emu, src = served
    with RPLidarLaser(emu.address, express=True) as laser:
        assert laser.geometry.beams == 720
        first = laser.wait_scan(-1, 10.0)
        mark = cpu_wait.total()
        later = laser.wait_scan(first.seq + 4, 10.0)
        # 720 samples of 254 us a turn; turns end on capsule boundaries (+-2 capsules of 16 ms); +-25 %, and a
        # loaded machine may stretch or bunch them by what the threads waited for a CPU
        turns, took = later.seq - first.seq, later.stamp - first.stamp
        assert abs(took - 0.18288 * turns) <= 0.25 * 0.18288 * turns + cpu_wait.since(mark), (turns, took)
        want = src.ranges(laser.geometry.angles(), 12.0)
        assert np.max(np.abs(later.scan.ranges - want)) <= 0.0005 + 1e-9     # express: whole mm
    assert emu.requests[-2] == Request(C.CMD_EXPRESS_SCAN, bytes(5)) and not emu.scanning
