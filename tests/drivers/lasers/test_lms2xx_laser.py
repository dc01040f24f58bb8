"""LMS2xx driver <-> emulator end to end, through a real pseudo-terminal (pyserial) and TCP."""

from __future__ import annotations

import math
import time
from typing import Any
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

import pytest
import serial

from robotexp.errors import ConfigError, ConnectionLost, ProtocolError
from robotexp.robot import Pose
from robotexp.sim import mounted_source
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.lasers.lms2xx import LMS2xxLaser
from robotexp_drivers.lasers.lms2xx import codec as k
from robotexp_drivers.lasers.lms2xx import constants as c
from robotexp_drivers.lasers.lms2xx.emulator import LMS2xxEmulator


def room(angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
    """A made-up scene: a curved wall ahead within +-70 deg, nothing (no echo) beyond; 12 m far on the left."""
    r = np.where(np.abs(angles) < math.radians(70), 2.0 + np.sin(3 * angles), np.inf)
    r = np.where(angles > math.radians(80), 12.0, r)
    return np.where(r <= reach, r, np.inf)


@pytest.fixture(params=["pty", "tcp"])
def emulator(request: pytest.FixtureRequest) -> Iterator[LMS2xxEmulator]:
    em = LMS2xxEmulator(room, pty=request.param == "pty").start()
    yield em
    em.close()


def _check_scan(laser: LMS2xxLaser, unit: float) -> None:
    s = laser.wait_scan(-1, 10.0)
    angles = laser.geometry.angles()
    expected = room(angles, laser.geometry.range_max)
    assert s.scan.ranges.shape == angles.shape
    assert np.array_equal(np.isinf(s.scan.ranges), np.isinf(expected))
    finite = np.isfinite(expected)
    assert np.max(np.abs(s.scan.ranges[finite] - expected[finite])) <= unit / 2 + 1e-9


def test_default_session(emulator: LMS2xxEmulator) -> None:
    with LMS2xxLaser(emulator.address) as laser:
        g = laser.geometry
        assert (g.beams, g.angle_min, g.increment, g.range_max) == (181, -math.pi / 2, math.radians(1), 8.0)
        _check_scan(laser, 0.001)
        assert "LMS200;30106" in laser.describe()
        first = laser.wait_scan(-1, 10.0)
        second = laser.wait_scan(first.seq, 10.0)
        assert second.stamp > first.stamp
        if emulator.address.startswith("/dev/"):
            # serial: 181 values = 372 bytes at 38400 baud -> one scan per 96.9 ms (line-limited)
            assert g.period == pytest.approx(0.096875)
            assert emulator.baud == 38400
        else:
            assert g.period == pytest.approx(1 / 75)      # TCP: the mirror's 75 Hz
    time.sleep(0.1)
    assert not emulator.streaming


def test_half_degree_in_cm_reaches_80m(emulator: LMS2xxEmulator) -> None:
    with LMS2xxLaser(emulator.address, resolution=0.5, units="cm", baud=500000) as laser:
        assert (laser.geometry.beams, laser.geometry.range_max) == (361, 80.0)
        assert emulator.config.units == c.Units.CM and emulator.variant == (180, 50)
        _check_scan(laser, 0.01)
        s = laser.wait_scan(-1, 10.0)
        assert s.scan.ranges[-1] == pytest.approx(12.0)          # beyond the 8 m of the mm mode


def test_100_degrees_quarter_and_32m_mode(emulator: LMS2xxEmulator) -> None:
    with LMS2xxLaser(emulator.address, fov=100, resolution=0.25, range_mode=32) as laser:
        g = laser.geometry
        assert (g.beams, g.angle_min, g.range_max) == (401, -math.radians(50), 32.0)
        assert emulator.config.measuring_mode == c.MeasuringMode.M32_FA
        _check_scan(laser, 0.001)


def test_baud_switching_sequence_on_a_pty() -> None:
    with LMS2xxEmulator(room, pty=True).start() as em:
        laser = LMS2xxLaser(em.address, baud=38400)
        assert laser.baud == 38400 and em.baud == 38400
        laser.wait_scan(-1, 10.0)
        laser.close()
        time.sleep(0.15)
        # 9600 at power-on -> 38400 for the session -> 9600 again on close; output stopped
        assert em.baud_log == [38400, 9600]
        assert em.baud == 9600 and not em.streaming
        assert em.requests[:4] == [0x20, 0x31, 0x3A, 0x20]       # stop, status, type, baud
        assert em.requests[-2:] == [0x20, 0x20]                  # stop, 9600
        # a second session starts at 9600 again and finds the LMS where the first left it
        with LMS2xxLaser(em.address) as again:
            again.wait_scan(-1, 10.0)


def test_configuration_written_once(emulator: LMS2xxEmulator) -> None:
    with LMS2xxLaser(emulator.address, units="cm") as laser:
        laser.wait_scan(-1, 10.0)
    assert emulator.requests.count(0x77) == 1
    n = len(emulator.requests)
    with LMS2xxLaser(emulator.address, units="cm") as laser:       # same settings: no EEPROM write
        laser.wait_scan(-1, 10.0)
    assert emulator.requests[n:].count(0x77) == 0


def test_wrong_password_is_a_protocol_error(emulator: LMS2xxEmulator) -> None:
    with pytest.raises(ProtocolError, match="wrong installation password"):
        LMS2xxLaser(emulator.address, units="cm", password="NOT_SICK")


def test_bad_options_before_opening() -> None:
    for options in ({"baud": 57600}, {"fov": 90}, {"fov": 180, "resolution": 0.25}, {"units": "in"},
                    {"range_mode": 10}, {"password": "x"}, {"timeout": 0}):
        with pytest.raises(ConfigError):
            LMS2xxLaser("/dev/does-not-exist", **options)
    with pytest.raises(ConnectionLost, match="cannot open"):
        LMS2xxLaser("/dev/does-not-exist")


@pytest.mark.parametrize("pty", [True, False])
def test_emulator_closed_mid_stream_raises_connection_lost_within_1s(pty: bool, cpu_wait: Any) -> None:
    em = LMS2xxEmulator(room, pty=pty).start()
    laser = LMS2xxLaser(em.address)
    try:
        seq = laser.wait_scan(-1, 10.0).seq
        em.close()
        t0, mark = time.monotonic(), cpu_wait.total()
        with pytest.raises(ConnectionLost):
            while True:
                seq = laser.wait_scan(seq, 10.0).seq
        assert time.monotonic() - t0 < 1.0 + cpu_wait.since(mark)     # (+ a loaded machine's CPU wait)
    finally:
        laser.close()
        em.close()


def test_stalled_stream_raises_connection_lost(emulator: LMS2xxEmulator, cpu_wait: Any) -> None:
    with LMS2xxLaser(emulator.address, timeout=0.3) as laser:
        laser.wait_scan(-1, 10.0)
        emulator.pause_stream()
        t0, mark = time.monotonic(), cpu_wait.total()
        with pytest.raises(ConnectionLost, match="no valid scan"):
            while True:
                laser.wait_scan(laser.wait_scan(-1, 10.0).seq, 10.0)
        assert time.monotonic() - t0 < 1.0 + cpu_wait.since(mark)     # (+ a loaded machine's CPU wait)


def test_garbage_and_corrupt_scans_are_skipped(emulator: LMS2xxEmulator) -> None:
    with LMS2xxLaser(emulator.address) as laser:
        seq = laser.wait_scan(-1, 10.0).seq
        emulator.send_raw(b"\x02\x80\x10\x00garbage\x06\x15" + bytes(range(256)))
        emulator.corrupt_frames(2)
        for _ in range(3):
            seq = laser.wait_scan(seq, 10.0).seq
        _check_scan(laser, 0.001)
        assert laser._dec.bad_crcs >= 2


def test_emulator_protocol_answers_on_a_raw_serial_port() -> None:
    """The emulator as a bare client sees it: ACK before each reply, NAK on a bad CRC, 0x92 for a
    configuration outside installation mode, refused variants, reset -> 0x91 then 0x90."""
    with LMS2xxEmulator(room, pty=True, boot_time=0.05).start() as em, \
            serial.Serial(em.address, 9600, timeout=0.3) as port:
        def ask(frame: bytes, n: int = 1) -> tuple[bytes, list[k.Telegram]]:
            port.write(frame)
            got, out, end = b"", [], time.monotonic() + 1.0
            dec = k.TelegramDecoder()
            while len(out) < n and time.monotonic() < end:
                chunk = port.read(port.in_waiting or 1)
                got += chunk
                out += dec.feed(chunk)
            return got, out
        raw, (t,) = ask(k.req_stop())
        assert raw == b"\x06" + bytes.fromhex("02 80 03 00 A0 00 10 16 0A")     # TL Table 7-20's reply
        bad = bytearray(k.req_status())
        bad[-1] ^= 1
        port.write(bytes(bad))
        assert port.read(1) == b"\x15"
        _, (t,) = ask(k.req_configure(k.LMSConfig.default()))
        assert t.command == c.Reply.NOT_ACKNOWLEDGED
        _, (t,) = ask(k.req_mode(c.Mode.INSTALLATION, b"SICK_LMX"))
        assert k.parse_mode_reply(t) == c.MODE_BAD_PASSWORD
        # ARIA's 32-byte block (blocks A..A3) is accepted in installation mode
        _, (t,) = ask(k.req_installation())
        assert k.parse_mode_reply(t) == c.MODE_OK
        old = k.LMSConfig(k.LMSConfig.default().raw[:32]).with_(measuring_mode=5, units=1)
        _, (t,) = ask(k.req_configure(old))
        ok, cfg = k.parse_config_reply(t)
        assert ok and (cfg.measuring_mode, len(cfg.raw)) == (5, 34)
        bad_variant = k.encode_telegram(c.Cmd.SWITCH_VARIANT, bytes.fromhex("B4 00 19 00"))   # 180 at 0.25
        _, (t,) = ask(bad_variant)
        assert k.parse_variant_reply(t) == (False, 180, 50)
        _, (t,) = ask(k.req_values())
        assert t.command == c.Reply.VALUES and len(k.decode_values(t.data).values) == 361
        st = k.parse_status_reply(ask(k.req_status())[1][0])
        assert (st.mode, st.scan_angle, st.resolution, st.baud, st.measuring_mode) == (0x00, 180, 50, 9600, 5)
        _, (reset, power_on) = ask(k.req_reset(), 2)
        assert (reset.command, power_on.command, power_on.data) == (0x91, 0x90, c.POWER_ON_TEXT)


def test_emulator_on_a_robot_emulators_simulator() -> None:
    """The emulator measures with `mounted_source(sim, mount, lock)` on a Kobuki emulator's simulator and lock
    (how a robot emulator attaches it): the driver's scan equals the simulator's own ray cast within 0.5 mm."""
    mount = Pose(0.1, 0.0, 0.0)
    with KobukiEmulator(builtin_world("ufmg-static"), port=0) as robot:
        source = mounted_source(robot.sim, mount, robot.lock)
        source(np.zeros(1), 8.0)            # compile the ray caster before the driver's 1 s scan timeout runs
        with LMS2xxEmulator(source, pty=True).start() as em, LMS2xxLaser(em.address) as laser:
            s = laser.wait_scan(-1, 10.0)
            truth = source(laser.geometry.angles(), laser.geometry.range_max)
            finite = np.isfinite(truth)
            assert finite.sum() > 50
            assert np.array_equal(np.isfinite(s.scan.ranges), finite)
            assert np.max(np.abs(s.scan.ranges[finite] - truth[finite])) <= 0.0005 + 1e-9


def test_scan_rate_follows_the_line_rate_on_a_pty() -> None:
    """At 38400 baud a 181-value scan (372 bytes) takes 96.9 ms on the line: scans come no faster; at
    500 k the 75 Hz mirror limits (13.3 ms)."""
    with LMS2xxEmulator(room, pty=True).start() as em:
        for baud, period in ((38400, 0.096875), (500000, 1 / 75)):
            with LMS2xxLaser(em.address, baud=baud) as laser:
                first = laser.wait_scan(-1, 10.0)
                s = first
                for _ in range(8):
                    s = laser.wait_scan(s.seq, 10.0)
                mean = (s.stamp - first.stamp) / (s.seq - first.seq)
                assert laser.geometry.period == pytest.approx(period)
                assert 0.9 * period <= mean <= 5 * period          # never faster than the line; loaded hosts lag


def test_driver_resends_after_a_nak(emulator: LMS2xxEmulator) -> None:
    emulator.nak_requests(1)
    with LMS2xxLaser(emulator.address) as laser:
        laser.wait_scan(-1, 10.0)
    assert emulator.naks_sent == 1
    assert emulator.requests[:2] == [0x20, 0x31]          # the NAKed stop was sent again and answered
