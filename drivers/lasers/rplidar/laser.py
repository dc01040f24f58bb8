"""Slamtec RPLidar A1/A2 laser driver: the RPLidar serial protocol at 115200 (A1, A2M8) or 256000 baud.

`RPLidarLaser(address)` spins the motor (DTR low on the A1/A2 USB adapter; SET_MOTOR_PWM when
asked), stops a scan left running (STOP), reads the identity (GET_INFO) and health (GET_HEALTH;
a protection stop is reset once), then starts SCAN (or EXPRESS_SCAN); a reader thread decodes the
5-byte nodes (`codec.ScanDecoder`; capsules: `codec.ExpressDecoder`), bins each turn to `beams`
beams and stamps it when the next turn begins. The device measures clockwise from its front; scans
come out in the laser frame (0 forward, counter-clockwise, metres; NaN: no node fell in that beam
this turn). `close()` sends STOP and stops the motor. Protocol notes: docs/protocols/rplidar.md.
"""

from __future__ import annotations

import struct
import time
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, ConnectionLost, ProtocolError
from robotexp_drivers.backend import reads_until
from robotexp_drivers.lasers.base import LaserLink, StreamLaser
from robotexp_drivers.lasers.rplidar import constants as C
from robotexp_drivers.lasers.rplidar.codec import (
    DeviceInfo,
    ExpressDecoder,
    Health,
    ScanDecoder,
    geometry,
    parse_descriptor,
    request,
)

__all__ = ["RPLidarLaser"]


class RPLidarLaser(StreamLaser):
    """A Slamtec RPLidar A1/A2 (see the module docstring).

    Args:
        address: a serial device (/dev/ttyUSB0), or "host:port" / socket://host:port (a serial server).
        timeout: no complete turn for this long [s] fails the laser (ConnectionLost).
        baudrate: 115200 (A1, A2M8) or 256000 (A2M7/A2M12, A3).
        beams: how many beams a turn is binned into (default 360, 1 deg, about the A1's samples per
            turn in SCAN; 720 with `express`).
        express: stream EXPRESS_SCAN capsules (A1: 4000 samples/s) instead of SCAN nodes (2000/s).
        range_min, range_max: [m] the device's range (A1/A2: 0.15 .. 12 m).
        motor_pwm: send SET_MOTOR_PWM with this duty (0..1023) before scanning (A2/A3), None: don't.
        reply_timeout: how long to wait for each reply of the handshake [s].

    Raises:
        ConnectionLost: the port cannot be opened or the device does not answer.
        ProtocolError: a reply that is not what the request calls for, or a health error that a
            reset does not clear.
        ConfigError: an option out of range.
    """

    name: ClassVar[str] = "rplidar"

    def __init__(self, address: str, *, timeout: float = 1.0, baudrate: int = C.BAUD_A1, beams: int | None = None,
                 express: bool = False, range_min: float = C.A1_RANGE_MIN_MM / 1000.0,
                 range_max: float = C.A1_RANGE_MAX_MM / 1000.0, motor_pwm: int | None = None,
                 reply_timeout: float = 1.0) -> None:
        if beams is None:
            beams = 720 if express else 360
        if not 8 <= beams <= 8192:
            raise ConfigError(f"rplidar: beams must be 8..8192, got {beams}")
        if not 0 <= range_min < range_max:
            raise ConfigError(f"rplidar: need 0 <= range_min < range_max, got {range_min}, {range_max} m")
        if motor_pwm is not None and not 0 <= motor_pwm <= 1023:
            raise ConfigError(f"rplidar: motor_pwm must be 0..1023, got {motor_pwm}")
        self.address = address
        self._pending = bytearray()
        self._link = LaserLink(self.name, address, baudrate=baudrate)
        try:
            self._handshake(motor_pwm, reply_timeout, express)
        except BaseException:
            self._link.close()
            raise
        # the period is nominal until turns arrive (A1 5.5 Hz)
        self.geometry = geometry(beams, range_min, range_max, 1 / 5.5)
        self.express = express
        self._decoder: ScanDecoder | ExpressDecoder = (ExpressDecoder(beams, range_min=range_min) if express
                                                       else ScanDecoder(beams, range_min=range_min))
        self._start_reader(timeout)

    # -- handshake -----------------------------------------------------------------------------------
    def _fill(self, n: int, deadline: float, what: str) -> None:
        for _ in reads_until(deadline):
            if len(self._pending) >= n:
                return
            self._pending += self._link.read_some()
        if len(self._pending) < n:
            raise ConnectionLost(f"rplidar: no {what} from {self.address!r}; check the cable, the baud rate "
                                 "and that the device is powered")

    def _read_exact(self, n: int, deadline: float, what: str) -> bytes:
        self._fill(n, deadline, what)
        out = bytes(self._pending[:n])
        del self._pending[:n]
        return out

    def _ask(self, cmd: int, dtype: int, length: int | None, mode: int, timeout: float, payload: bytes = b"") -> bytes:
        """Send `cmd`, check the descriptor (type, length, send mode), return the data (b"" for a
        multiple response, whose data then streams)."""
        self._link.write(request(cmd, payload))
        deadline = time.monotonic() + timeout
        name = f"reply to 0x{cmd:02X}"
        # skip whatever precedes the descriptor (a scan still draining after STOP)
        while True:
            self._fill(2, deadline, name)
            if self._pending[0] == C.SYNC_BYTE and self._pending[1] == C.SYNC_BYTE2:
                break
            del self._pending[0]
        got_len, got_mode, got_type = parse_descriptor(self._read_exact(C.DESCRIPTOR_LEN, deadline, name))
        if got_type != dtype or got_mode != mode or (length is not None and got_len != length):
            raise ProtocolError(f"rplidar: request 0x{cmd:02X} answered with type 0x{got_type:02X}, length "
                                f"{got_len}, mode {got_mode}; expected 0x{dtype:02X}, {length}, {mode}")
        return self._read_exact(got_len, deadline, name) if mode == C.SEND_MODE_SINGLE else b""

    def _handshake(self, motor_pwm: int | None, reply_timeout: float, express: bool) -> None:
        self._link.set_dtr(False)                       # spin the motor (A1/A2 USB adapter)
        if motor_pwm is not None:
            self._link.write(request(C.CMD_SET_MOTOR_PWM, struct.pack("<H", motor_pwm)))
        self._link.write(request(C.CMD_STOP))
        time.sleep(max(C.STOP_WAIT, 0.02))              # let a running scan's tail arrive, then drop it
        self._link.reset_input()
        self.info = DeviceInfo.decode(self._ask(C.CMD_GET_INFO, C.ANS_TYPE_DEVINFO, C.DEVINFO_LEN,
                                                C.SEND_MODE_SINGLE, reply_timeout))
        self.health = Health.decode(self._ask(C.CMD_GET_HEALTH, C.ANS_TYPE_DEVHEALTH, C.HEALTH_LEN,
                                              C.SEND_MODE_SINGLE, reply_timeout))
        if self.health.status == C.HEALTH_ERROR:
            self._link.write(request(C.CMD_RESET))
            time.sleep(max(C.RESET_WAIT, 0.5))
            self._link.reset_input()
            self._pending.clear()
            self.health = Health.decode(self._ask(C.CMD_GET_HEALTH, C.ANS_TYPE_DEVHEALTH, C.HEALTH_LEN,
                                                  C.SEND_MODE_SINGLE, reply_timeout))
            if self.health.status == C.HEALTH_ERROR:
                raise ProtocolError(f"rplidar at {self.address!r} reports a hardware error (code "
                                    f"0x{self.health.error_code:04X}) that a reset did not clear")
        if express:
            self._ask(C.CMD_EXPRESS_SCAN, C.ANS_TYPE_MEASUREMENT_CAPSULED, C.EXPRESS_CAPSULE_LEN, C.SEND_MODE_MULTI,
                      reply_timeout, C.EXPRESS_PAYLOAD)
        else:
            self._ask(C.CMD_SCAN, C.ANS_TYPE_MEASUREMENT, C.NODE_LEN, C.SEND_MODE_MULTI, reply_timeout)

    # -- StreamLaser ---------------------------------------------------------------------------------
    def _on_data(self, data: bytes, now: float) -> None:
        if self._pending:
            data = bytes(self._pending) + data
            self._pending.clear()
        turns = self._decoder.feed(data)
        if not turns:
            return
        # the newest turn ended when the next one began: the samples since then took their share of a turn
        dec = self._decoder
        after = dec.open_samples / max(dec.turn_samples, 1) * self.scan_period
        self._publish_read([self.geometry.scan(ranges) for ranges in turns], now, after)
        g = self.geometry          # the turn period as measured on this host, for `beam_offsets`
        self.geometry = geometry(g.beams, g.range_min, g.range_max, self.scan_period)

    def _stop_device(self) -> None:
        self._link.write(request(C.CMD_STOP))
        self._link.set_dtr(True)                        # stop the motor

    def beam_offsets(self) -> npt.NDArray[np.float64]:
        """When each beam of a turn was measured [s], relative to the turn's stamp (<= 0): the turn
        sweeps clockwise from the front and ends when the next one begins (`robotexp.run.laser_mount`
        places each echo from the robot pose at its beam's time)."""
        g = self.geometry
        cw = (-g.angles()) % (2 * np.pi)
        return -(1.0 - cw / (2 * np.pi)) * g.period

    def describe(self) -> str:
        g = self.geometry
        return (f"rplidar at {self.address}: {self.info.describe()}, health {self.health.status}; "
                f"{g.beams} beams over 360 deg, {g.range_max:g} m, {1 / g.period:.1f} Hz")

