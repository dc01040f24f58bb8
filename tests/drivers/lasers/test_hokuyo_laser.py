"""The Hokuyo driver against the Hokuyo emulator through a real pseudo-terminal and TCP: handshake,
identity, geometry and ranges of the ScanSource, the scan rate, QT on close, the emulator's SCIP
replies byte for byte, and a laser that goes away mid-stream."""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from scan_sources import BoxSource, seconds_until_lost

from robotexp.errors import ConnectionLost
from robotexp_drivers.lasers.hokuyo import HokuyoLaser
from robotexp_drivers.lasers.hokuyo import codec as k
from robotexp_drivers.lasers.hokuyo.emulator import HokuyoEmulator


@pytest.fixture(params=["pty", "tcp"])
def served(request: pytest.FixtureRequest) -> Iterator[tuple[HokuyoEmulator, BoxSource]]:
    src = BoxSource()
    with HokuyoEmulator(src, pty=request.param == "pty") as emu:
        yield emu, src


def test_driver_reads_the_emulated_urg04lx(served: tuple[HokuyoEmulator, BoxSource]) -> None:
    emu, src = served
    with HokuyoLaser(emu.address) as laser:
        g = laser.geometry
        assert g.beams == 682 and g.range_max == 4.0 and g.range_min == 0.02
        assert math.degrees(g.angle_min) == pytest.approx(-119.53125)
        assert math.degrees(g.increment) == pytest.approx(360 / 1024)
        assert "URG-04LX" in laser.describe() and "H0000001" in laser.describe()
        first = laser.wait_scan(-1, 10.0)
        later = laser.wait_scan(first.seq + 4, 10.0)
        # 10 Hz: 5 scans in ~0.5 s
        assert 0.35 < later.stamp - first.stamp < 0.65      # loose: 2 shared cores
        want = src.ranges(g.angles(), 5.6)                # echoes out to PP's DMAX, past the rated 4 m
        got = later.scan.ranges
        assert np.array_equal(np.isfinite(got), np.isfinite(want))
        fin = np.isfinite(want)
        assert fin.sum() > 500 and np.max(np.abs(got[fin] - want[fin])) <= 0.0005 + 1e-9
        np.testing.assert_array_equal(later.scan.angles, g.angles())
    assert emu.commands[-1] == b"QT"
    assert not emu.streaming and not emu.laser_on


def test_driver_reads_a_wall_at_5_m_from_the_urg04lx() -> None:
    # rated 4 m, PP DMAX 5600 mm: a real URG-04LX returns the echoes of 4.0-5.6 m, and so does the emulator
    src = BoxSource(-1.0, 5.0, -3.0, 3.0)
    with HokuyoEmulator(src) as emu, HokuyoLaser(emu.address) as laser:
        scan = laser.wait_scan(laser.wait_scan().seq, 10.0).scan
    ahead = np.abs(scan.angles) < math.radians(2.0)
    assert ahead.sum() == 11
    assert scan.ranges[ahead].tolist() == pytest.approx((5.0 / np.cos(scan.angles[ahead])).tolist(), abs=0.0005 + 1e-9)
    assert scan.ranges[ahead].min() == pytest.approx(5.0, abs=0.0005)


def test_driver_reads_the_emulated_utm30lx_with_clusters() -> None:
    src = BoxSource(-6.0, 25.0, -9.0, 12.0)
    with HokuyoEmulator(src, model="UTM-30LX") as emu, HokuyoLaser(emu.address, cluster=2, encoding="MS") as laser:
        g = laser.geometry
        assert g.beams == 541 and g.range_max == 30.0 and g.period == pytest.approx(0.025)
        assert math.degrees(g.fov) == pytest.approx(270.0)   # 541 beams of 2 steps of 0.25 deg
        scan = laser.wait_scan(laser.wait_scan().seq, 10.0).scan
        want = src.ranges(g.angles(), 30.0)
        # MS carries at most 4.095 m: farther walls come back clipped at the encoding's top
        want = np.minimum(want, 4.095)
        assert np.max(np.abs(scan.ranges - want)) <= 0.0005 + 1e-9
        assert emu.commands[-1].startswith(b"MS0000108002")


def test_laser_lost_mid_stream_raises_within_a_second(served: tuple[HokuyoEmulator, BoxSource],
                                                      cpu_wait: Any) -> None:
    emu, _ = served
    with HokuyoLaser(emu.address, timeout=1.0) as laser:
        assert seconds_until_lost(laser, emu.close, cpu_wait=cpu_wait) < 1.0


def test_stalled_stream_raises(cpu_wait: Any) -> None:
    with HokuyoEmulator(BoxSource()) as emu:
        laser = HokuyoLaser(emu.address, timeout=0.4)
        try:
            seq = laser.wait_scan(-1, 10.0).seq
            emu.pause_stream()
            t0, mark = time.monotonic(), cpu_wait.total()
            with pytest.raises(ConnectionLost, match="no valid scan"):
                while True:
                    seq = laser.wait_scan(seq, 10.0).seq
            assert time.monotonic() - t0 < 0.7 + cpu_wait.since(mark)     # (+ a loaded machine's CPU wait)
        finally:
            laser.close()


def _talk(sock: socket.socket, line: bytes, blocks: int = 1, timeout: float = 2.0) -> list[bytes]:
    sock.sendall(line)
    buf = bytearray()
    out: list[bytes] = []
    end = time.monotonic() + timeout
    while len(out) < blocks and time.monotonic() < end:
        sock.settimeout(max(0.01, end - time.monotonic()))
        try:
            buf += sock.recv(65536)
        except TimeoutError:
            break
        out += k.split_blocks(buf)[0]
    return out


def test_emulator_replies_as_scip_2_0() -> None:
    src = BoxSource()
    with HokuyoEmulator(src) as emu:
        host, port = emu.address.split(":")
        with socket.create_connection((host, int(port))) as sock:
            assert _talk(sock, b"GD0044072500\n") == [b"GD0044072500\n10Q"]     # laser off: denied
            assert _talk(sock, b"BM\n") == [b"BM\n00P"]
            assert _talk(sock, b"BM\n") == [b"BM\n02R"]
            assert _talk(sock, b"XX\n") == [b"XX\n0Ee"]
            assert _talk(sock, b"MD0044080001000\n") == [b"MD0044080001000\n04T"]   # past AMAX
            assert _talk(sock, b"MD0300020001000\n") == [b"MD0300020001000\n05U"]   # end before start
            assert _talk(sock, b"MD00440725A1000\n") == [b"MD00440725A1000\n03S"]
            assert _talk(sock, b"TM1\n") == [b"TM1\n04T"]
            assert _talk(sock, b"TM0\n") == [b"TM0\n00P"]
            tm1 = _talk(sock, b"TM1\n")[0].split(b"\n")
            assert tm1[:2] == [b"TM1", b"00P"] and k.sum_ok(tm1[2]) and len(tm1[2]) == 5
            assert _talk(sock, b"TM2\n") == [b"TM2\n00P"]
            gd = _talk(sock, b"GD0384038500;hi\n")[0].split(b"\n")
            assert gd[0] == b"GD0384038500;hi" and gd[1] == b"00P"
            assert k.decode_values(gd[3][:-1], 3)[0] == round(src.ranges(np.zeros(1))[0] * 1000)
            # three scans of steps 380..390, every other one: remaining 02, 01, 00, then nothing
            replies = _talk(sock, b"MD0380039001103\n", blocks=4, timeout=1.5)
            assert replies[0] == b"MD0380039001103\n00P"
            assert [r.split(b"\n")[0] for r in replies[1:]] == [b"MD0380039001102", b"MD0380039001101",
                                                               b"MD0380039001100"]
            assert _talk(sock, b"", blocks=1, timeout=0.3) == []
            assert not emu.streaming
            assert _talk(sock, b"QT\n") == [b"QT\n00P"]
            # II: TIME is the millisecond counter in hex; 10 ms, in the scans' encoding "000:", would
            # break every parser that splits KEY:value (hokuyolx failed on it)
            emu._now_ms = lambda: 10            # type: ignore[method-assign]  # (QT above: the laser is off)
            ii = k.parse_params(k.parse_reply(_talk(sock, b"II\n")[0]))
            assert ii["TIME"] == "00000A" and ii["LASR"] == "OFF" and ii["MODL"].startswith("URG-04LX")
            pp = k.parse_params(k.parse_reply(_talk(sock, b"PP\n")[0]))
            assert pp == {"MODL": "URG-04LX(Hokuyo Automatic Co.,Ltd.)", "DMIN": "20", "DMAX": "5600",
                          "ARES": "1024", "AMIN": "44", "AMAX": "725", "AFRT": "384", "SCAN": "600"}


def _soon(cond: Callable[[], bool], timeout: float = 10.0) -> bool:
    """`cond()` once it holds, polled for up to `timeout` s (the emulator's thread may run late under load)."""
    deadline = time.monotonic() + timeout
    while not cond() and time.monotonic() < deadline:
        time.sleep(0.01)
    return cond()


def test_driver_takes_over_a_sensor_left_streaming() -> None:
    import serial
    with HokuyoEmulator(BoxSource(), pty=True) as emu:
        with serial.Serial(emu.address, timeout=0.2) as port:      # a previous program's unlimited MD
            port.write(k.md_command(44, 725))
            port.read(4000)
            assert _soon(lambda: emu.streaming)
        time.sleep(0.25)                                            # scans pile up unread
        with HokuyoLaser(emu.address) as laser:
            assert laser.wait_scan(-1, 10.0).scan.ranges.shape == (682,)
        assert _soon(lambda: emu.commands.count(b"QT") == 2)        # the takeover's and the close's
        assert emu.commands.count(b"QT") == 2
