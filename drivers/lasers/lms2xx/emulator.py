"""An LMS200 emulator: the SICK LMS2xx telegram protocol served from a `ScanSource`.

It serves on a pseudo-terminal (the address is the slave device: a driver opens a real serial device)
or on TCP ("host:port"). Like the LMS200 it starts at 9600 baud in monitoring mode 0x25, answers each
request with a good CRC with ACK (0x06) and its reply, a bad CRC with NAK (0x15), and:

- 0x10 reset: 0x91 at once, then after `boot_time` s the 0x90 power-on telegram; the LMS is back at
  9600 baud, mode 0x25, power-on variant (the configuration block, in EEPROM on a real LMS, stays);
  requests during the boot are ignored;
- 0x20 modes: installation (with the password "SICK_LMS"; else result 1), 0x24 continuous output of all
  values, 0x25 values on request, baud rates 9600/19200/38400/500 k (the reply goes out at the old rate,
  then the rate changes; a pseudo-terminal has no real rate: the state is kept and paces the output);
  other modes are not acknowledged (0x92);
- 0x30 0x01 one scan, 0x31 status (0xB1, 152 bytes), 0x3A type, 0x74 configuration;
- 0x3B variant: 180 deg at 1/0.5 deg, 100 deg at 1/0.5/0.25 deg (others refused with the old variant
  echoed); a variant change stops the continuous output, as sicktoolbox observed of the real LMS;
- 0x77 configuration (installation mode only, else 0x92): 32- or 34-byte blocks with a range
  measuring mode (0x00-0x06, 0x0F) and cm/mm units; otherwise refused (F7 00).

In continuous mode each step measures one scan with the source and sends a 0xB0 telegram: one scan per
1/2/4 mirror turns at 75 Hz (1/0.5/0.25 deg), or slower when the serial line cannot carry it at the
current baud (on a pseudo-terminal; TCP has no line rate). Geometry: the LMS's 0..180 deg is -90..+90 deg
in the sensor frame; reach 8 m (mm) / 80 m (cm) in the 13-bit modes, 16/32 m in the 14/15-bit modes.
Emulation choices (not the firmware's): the boot takes `boot_time` (a real LMS takes tens of seconds),
a configuration write is answered at once (up to 7 s on a real LMS), a new TCP client finds the LMS
freshly powered on, and the power-on variant is 180 deg at 0.5 deg.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from robotexp import ConfigError, ScanSource
from robotexp_drivers.lasers.base import LaserEmulatorBase
from robotexp_drivers.lasers.lms2xx import codec as k
from robotexp_drivers.lasers.lms2xx import constants as c

__all__ = ["LMS2xxEmulator"]

log = logging.getLogger(__name__)

POWER_ON_VARIANT = (180, 50)        # (deg, 1/100 deg): the emulator's power-on variant
IDLE_PERIOD = 0.01                  # [s] serving-loop step when not streaming (boot timer, commands)


class LMS2xxEmulator(LaserEmulatorBase):
    """Serve an LMS200 measuring with `source` (call `start()`, or use `with`).

    Args:
        source: what the laser measures (`robotexp.laser.ScanSource`, e.g. `robotexp.sim.mounted_source`).
        pty: serve on a pseudo-terminal instead of TCP.
        port: TCP port on `host` (None or 0: any free one; read `address`). Ignored with `pty`.
        host: interface to listen on.
        boot_time: [s] from a reset to the power-on telegram.
        lms_address: the LMS's own address (requests to it or to 0x00 are answered).
        speedup: scans per wall second are multiplied by this.

    Raises:
        ConfigError: a parameter out of range.
        OSError: the port cannot be bound.
    """

    label = "lms2xx emulator"

    def __init__(self, source: ScanSource, *, pty: bool = False, port: int | None = None, host: str = "127.0.0.1",
                 boot_time: float = 0.5, lms_address: int = 0, speedup: float = 1.0) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"{self.label}: speedup must be > 0, got {speedup}")
        if not (boot_time >= 0 and math.isfinite(boot_time)):
            raise ConfigError(f"{self.label}: boot_time must be >= 0 s, got {boot_time}")
        if not 0 <= lms_address <= 0x7F:
            raise ConfigError(f"{self.label}: lms_address must be 0..127, got {lms_address}")
        self._init_laser(source, speedup)
        self.boot_time = boot_time
        self.lms_address = lms_address
        self.config = k.LMSConfig.default()
        self.baud_log: list[int] = []          # every baud rate switched to, in order
        self.requests: list[int] = []          # command codes of the requests answered, in order
        self.last_data: dict[int, bytes] = {}  # the data of the latest request of each command code
        self.scans_sent = 0
        self.naks_sent = 0
        self._nak_next = 0
        self._serial = pty
        self._power_on()
        self._open_transport(pty, port, host)

    # -- fault injection ----------------------------------------------------------------------------------
    def nak_requests(self, n: int) -> None:
        """Answer the next `n` good requests with NAK only (as if their CRC had been garbled on the line)."""
        self._nak_next += n

    # -- state -------------------------------------------------------------------------------------------
    def _power_on(self) -> None:
        self.baud = c.POWER_ON_BAUD
        self.mode = int(c.Mode.MONITOR_REQUEST)
        self.streaming = False
        self.variant = POWER_ON_VARIANT
        self._decoder = k.TelegramDecoder(replies=False)
        self._booting_until: float | None = None

    @property
    def beams(self) -> int:
        """Values per scan of the current variant."""
        return c.beams(*self.variant)

    @property
    def reach(self) -> float:
        """[m] the current measuring mode's range in the current units."""
        return k.reach_of(self.config.measuring_mode, self.config.units)

    def angles(self) -> np.ndarray:
        """[rad] the beams of the current variant in the sensor frame."""
        angle, res = self.variant
        return c.first_angle(angle) + math.radians(res / 100) * np.arange(self.beams, dtype=np.float64)

    def scan_frame(self) -> bytes:
        """Measure one scan now and encode it as a 0xB0 telegram."""
        ranges = self.source(self.angles(), self.reach)
        return k.encode_scan(ranges, units=self.config.units, measuring_mode=self.config.measuring_mode,
                             reach=self.reach, address=self.lms_address | c.ADDR_REPLY_BIT)

    # -- StreamEmulator hooks -----------------------------------------------------------------------------
    @property
    def _period(self) -> float:
        if not self.streaming:
            return IDLE_PERIOD / self.speedup
        period = c.scan_period(self.variant[1])
        if self._serial:
            period = max(period, c.line_time(2 * self.beams + 10, self.baud))
        return period / self.speedup

    def _on_connect(self) -> None:
        self._power_on()

    def _halt(self) -> None:
        self.streaming = False
        self.mode = int(c.Mode.MONITOR_REQUEST)

    def _step(self) -> bytes:
        if self._booting_until is not None:
            if time.monotonic() < self._booting_until:
                return b""
            self._power_on()
            return k.reply_power_on(address=self.lms_address)
        if not self.streaming:
            return b""
        self.scans_sent += 1
        return self._maybe_corrupt(self.scan_frame())

    def _on_bytes(self, data: bytes) -> None:
        if self._booting_until is not None:
            return
        bad = self._decoder.bad_crcs
        telegrams = self._decoder.feed(data)
        out = bytearray(bytes((c.NAK,)) * (self._decoder.bad_crcs - bad))
        self.naks_sent += self._decoder.bad_crcs - bad
        after: list[int] = []
        for t in telegrams:
            if t.address not in (c.ADDR_BROADCAST, self.lms_address):
                continue
            if self._nak_next > 0:
                self._nak_next -= 1
                self.naks_sent += 1
                out.append(c.NAK)
                continue
            self.requests.append(t.command)
            self.last_data[t.command] = t.data
            out.append(c.ACK)
            out += self._answer(t, after)
        self._transmit(bytes(out))
        for baud in after:                 # the reply went out at the old rate
            self.baud = baud
            self.baud_log.append(baud)

    # -- requests ------------------------------------------------------------------------------------------
    def _answer(self, t: k.Telegram, after: list[int]) -> bytes:
        a = self.lms_address
        cmd, data = t.command, t.data
        if cmd == c.Cmd.RESET:
            self.streaming = False
            self._booting_until = time.monotonic() + self.boot_time / self.speedup
            return k.reply_reset_ack(address=a)
        if cmd == c.Cmd.SWITCH_MODE and data:
            return self._switch_mode(data[0], data[1:], after)
        if cmd == c.Cmd.REQUEST_VALUES and data[:1] == bytes((c.SUB_ALL_VALUES,)):
            return self.scan_frame()
        if cmd == c.Cmd.REQUEST_STATUS:
            return k.reply_status(k.LMSStatus(
                software=c.SOFTWARE_VERSION.decode(), mode=self.mode, error=0,
                measuring_mode=self.config.measuring_mode, scan_angle=self.variant[0], resolution=self.variant[1],
                baud=self.baud, address=a, units=self.config.units))
        if cmd == c.Cmd.REQUEST_TYPE:
            return k.reply_type(address=a)
        if cmd == c.Cmd.SWITCH_VARIANT and len(data) == 4:
            wanted = (data[0] | data[1] << 8, data[2] | data[3] << 8)
            ok = wanted in c.VALID_VARIANTS
            if ok:
                self.variant = wanted
                self.streaming = False
                self.mode = int(c.Mode.MONITOR_REQUEST) if self.mode == c.Mode.CONTINUOUS_ALL else self.mode
            return k.reply_variant(ok, *self.variant, address=a)
        if cmd == c.Cmd.REQUEST_CONFIG:
            return k.reply_config(self.config, address=a)
        if cmd == c.Cmd.CONFIGURE:
            if self.mode != c.Mode.INSTALLATION:
                return k.reply_not_acknowledged(address=a)
            ok = (len(data) in (c.CONFIG_LEN, c.CONFIG_LEN_OLD) and data[c.CFG_MEASURING_MODE] in c.RANGE_BITS
                  and data[c.CFG_UNITS] in (c.Units.CM, c.Units.MM))
            if ok:
                self.config = k.LMSConfig(bytes(data) + self.config.raw[len(data):])
            return k.reply_configured(ok, self.config, address=a)
        return k.reply_not_acknowledged(address=a)

    def _switch_mode(self, mode: int, rest: bytes, after: list[int]) -> bytes:
        a = self.lms_address
        if mode == c.Mode.INSTALLATION:
            if rest != c.INSTALLATION_PASSWORD:
                return k.reply_mode(c.MODE_BAD_PASSWORD, address=a)
            self.streaming = False
            self.mode = mode
            return k.reply_mode(c.MODE_OK, address=a)
        if mode in (c.Mode.CONTINUOUS_ALL, c.Mode.MONITOR_REQUEST):
            self.mode = mode
            self.streaming = mode == c.Mode.CONTINUOUS_ALL
            return k.reply_mode(c.MODE_OK, address=a)
        if mode in c.BAUD_OF_CODE:
            after.append(c.BAUD_OF_CODE[mode])
            return k.reply_mode(c.MODE_OK, address=a)
        return k.reply_not_acknowledged(address=a)
