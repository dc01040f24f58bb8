"""SICK LMS2xx (LMS200/211/221/291) laser driver: RS-232/422 telegrams with CRC-16 (entry point `lms2xx`).

`LMS2xxLaser` connects at the LMS's power-on rate (9600 baud; it also finds an LMS left at another rate),
switches the line to a faster rate (38400 by default; 500 k only where an RS-422 link allows; TCP has
no rate), sets the variant (scan angle, resolution) and the measuring mode/units as asked, starts the
continuous output (mode 0x24) and publishes each complete scan stamped on arrival, in the sensor frame
(0 forward, counter-clockwise: the LMS's 0..180 deg is -90..+90 deg). Closing stops the output and
puts the LMS back at 9600 baud. Protocol: `codec`, `constants`, docs/protocols/lms2xx.md.
"""

from __future__ import annotations

import math
import time

from robotexp import ConfigError, ConnectionLost, LaserGeometry, ProtocolError
from robotexp_drivers.backend import reads_until
from robotexp_drivers.lasers.base import LaserLink, StreamLaser
from robotexp_drivers.lasers.lms2xx import codec as k
from robotexp_drivers.lasers.lms2xx import constants as c

__all__ = ["LMS2xxLaser"]

RANGE_MODES = {8: c.MeasuringMode.M8_80_FA_FB_DAZZLE, 16: c.MeasuringMode.M16_FA_FB, 32: c.MeasuringMode.M32_FA}
DETECT_ORDER = (9600, 38400, 19200, 500000)     # rates tried when the LMS does not answer at `start_baud`


class LMS2xxLaser(StreamLaser):
    """A SICK LMS2xx on a serial port (or a serial-to-TCP bridge / the emulator on "host:port").

    Args:
        address: a serial device (/dev/ttyUSB0), "host:port" or a pyserial URL.
        baud: line rate for the scans: 9600, 19200, 38400 or 500000 (RS-422 only on a real LMS);
            ignored on TCP.
        fov: scan angle [deg]: 180 or 100.
        resolution: [deg] 1, 0.5 or 0.25 (0.25 with fov 100 only).
        units: "mm" or "cm" (the 8 m mode reaches 80 m in cm).
        range_mode: the measuring mode's range in mm units [m]: 8 (13-bit values, the default mode),
            16 or 32.
        start_baud: the rate the LMS is expected at (9600 after power-on).
        detect_baud: when the LMS does not answer at `start_baud`, try the other rates.
        password: the installation-mode password (needed only when the measuring mode or units change).
        timeout: [s] no valid scan for this long fails the laser (default: 1 s or three scan periods).
        reply_timeout: [s] how long a request waits for its reply.

    Raises:
        ConfigError: a bad option (before the port is opened).
        ConnectionLost: the port cannot be opened or the LMS does not answer.
        ProtocolError: the LMS refuses a setting or answers out of protocol.
    """

    name = "lms2xx"

    def __init__(self, address: str, *, baud: int = 38400, fov: int = 180, resolution: float = 1.0,  # noqa: PLR0913
                 units: str = "mm", range_mode: int = 8, start_baud: int = c.POWER_ON_BAUD,
                 detect_baud: bool = True, password: str = c.INSTALLATION_PASSWORD.decode(),
                 timeout: float | None = None, reply_timeout: float = 1.0) -> None:
        self.address = address
        who = self.name
        for what, rate in (("baud", baud), ("start_baud", start_baud)):
            if rate not in c.BAUD_CODES:
                raise ConfigError(f"{who}: {what} must be one of {sorted(c.BAUD_CODES)}, got {rate}")
        res_cdeg = round(resolution * 100)
        if (fov, res_cdeg) not in c.VALID_VARIANTS or abs(resolution * 100 - res_cdeg) > 1e-6:
            raise ConfigError(f"{who}: no variant {fov} deg at {resolution:g} deg; use fov 180 with resolution "
                              "1 or 0.5, or fov 100 with 1, 0.5 or 0.25")
        self.units = k.units_of(units)
        if range_mode not in RANGE_MODES:
            raise ConfigError(f"{who}: range_mode must be 8, 16 or 32 [m], got {range_mode}")
        pw = password.encode("ascii", "replace")
        if len(pw) != 8:
            raise ConfigError(f"{who}: the installation password has 8 characters, got {len(pw)}")
        if timeout is not None and not timeout > 0:
            raise ConfigError(f"{who}: timeout must be > 0 s, got {timeout}")
        if not reply_timeout > 0:
            raise ConfigError(f"{who}: reply_timeout must be > 0 s, got {reply_timeout}")
        self.measuring_mode = int(RANGE_MODES[range_mode])
        self.variant = (fov, res_cdeg)
        self.reply_timeout = reply_timeout
        self.identity = ""
        self._dec = k.ScanDecoder(self.measuring_mode)
        self._link = LaserLink(who, address, baudrate=start_baud)
        try:
            self.baud = self._find_baud(start_baud, detect_baud)
            self._handshake(baud, pw)
        except BaseException:
            self._link.close()
            raise
        beams = c.beams(fov, res_cdeg)
        period = c.scan_period(res_cdeg)
        if self._link.is_serial:
            period = max(period, c.line_time(2 * beams + 10, self.baud))
        self.geometry = LaserGeometry(angle_min=c.first_angle(fov), increment=math.radians(res_cdeg / 100),
                                      beams=beams, range_min=0.0,
                                      range_max=k.reach_of(self.measuring_mode, self.units), period=period)
        self._dec.beams = beams
        self._start_reader(timeout if timeout is not None else max(1.0, 3 * period))

    # -- handshake (before the reader thread) ----------------------------------------------------------------
    def _request(self, frame: bytes, expect: int, timeout: float | None = None) -> k.Telegram:
        """Send `frame`; return the first reply with code `expect` (0xB0 scans and other replies skipped).

        Raises:
            ConnectionLost: no such reply within `timeout` (one resend after a NAK).
            ProtocolError: the LMS did not acknowledge the command (0x92).
        """
        wait = self.reply_timeout if timeout is None else timeout
        self._dec.others.clear()
        naks = self._dec.telegrams.naks
        self._link.write(frame)
        resent = False
        for _ in reads_until(time.monotonic() + wait):
            self._dec.feed(self._link.read_some())
            for t in self._dec.others:
                if t.command == expect:
                    return t
                if t.command == c.Reply.NOT_ACKNOWLEDGED:
                    raise ProtocolError(f"{self.name}: the LMS at {self.address!r} did not acknowledge "
                                        f"command 0x{frame[4]:02X} (0x92: not allowed in its current mode)")
            self._dec.others.clear()
            if self._dec.telegrams.naks > naks and not resent:
                resent = True
                time.sleep(0.03)            # TL 4.3: at least 30 ms after a NAK before resending
                self._link.write(frame)
        raise ConnectionLost(f"{self.name}: no 0x{expect:02X} reply to command 0x{frame[4]:02X} from "
                             f"{self.address!r} within {wait:g} s; check the cable, power and baud rate")

    def _mode_ok(self, frame: bytes, what: str, timeout: float | None = None) -> None:
        result = k.parse_mode_reply(self._request(frame, c.Reply.MODE, timeout))
        if result != c.MODE_OK:
            why = {c.MODE_BAD_PASSWORD: "wrong installation password", c.MODE_FAULT: "LMS fault"}.get(
                result, f"result {result}")
            raise ProtocolError(f"{self.name}: the LMS at {self.address!r} refused {what}: {why}")

    def _find_baud(self, start_baud: int, detect: bool) -> int:
        """Stop any output (0x20 0x25) at `start_baud`, then at the other rates; the rate that answered."""
        if not self._link.is_serial:
            self._mode_ok(k.req_stop(), "monitoring mode 0x25")
            return start_baud
        rates = [start_baud] + ([b for b in DETECT_ORDER if b != start_baud] if detect else [])
        for rate in rates:
            self._link.set_baudrate(rate)
            self._link.reset_input()
            try:
                self._mode_ok(k.req_stop(), "monitoring mode 0x25")
                return rate
            except ConnectionLost:
                if self._link.closed:
                    raise
        raise ConnectionLost(f"{self.name}: no LMS2xx answer at {', '.join(map(str, rates))} baud on "
                             f"{self.address!r}; check the cable, power and port")

    def _handshake(self, baud: int, password: bytes) -> None:
        status = k.parse_status_reply(self._request(k.req_status(), c.Reply.STATUS))
        if status.error:
            raise ProtocolError(f"{self.name}: the LMS at {self.address!r} reports device error {status.error}")
        self.identity = self._request(k.req_type(), c.Reply.TYPE).data.decode("ascii", "replace").strip()
        if self._link.is_serial and baud != self.baud:
            self._mode_ok(k.req_baud(baud), f"{baud} baud")
            time.sleep(0.02)
            self._link.set_baudrate(baud)
            self._link.reset_input()
            self._dec = k.ScanDecoder(self.measuring_mode)
            self.baud = baud
            self._mode_ok(k.req_stop(), f"monitoring mode at {baud} baud", c.MODE_CHANGE_WITHIN)
        if (status.scan_angle, status.resolution) != self.variant:
            ok, angle, res = k.parse_variant_reply(self._request(k.req_variant(*self.variant), c.Reply.VARIANT))
            if not ok or (angle, res) != self.variant:
                raise ProtocolError(f"{self.name}: the LMS at {self.address!r} refused variant {self.variant[0]} "
                                    f"deg at {self.variant[1] / 100:g} deg (it stays at {angle} deg, {res / 100:g})")
        _, config = k.parse_config_reply(self._request(k.req_config(), c.Reply.CONFIG))
        if (config.measuring_mode, config.units) != (self.measuring_mode, self.units):
            self._mode_ok(k.req_installation(password), "installation mode", c.MODE_CHANGE_WITHIN)
            wanted = config.with_(measuring_mode=self.measuring_mode, units=self.units)
            reply = self._request(k.req_configure(wanted), c.Reply.CONFIGURED, c.CONFIG_WITHIN + 1)
            ok, now = k.parse_config_reply(reply)
            if not ok or (now.measuring_mode, now.units) != (self.measuring_mode, self.units):
                raise ProtocolError(f"{self.name}: the LMS at {self.address!r} refused measuring mode "
                                    f"0x{self.measuring_mode:02X} in {self.units.name.lower()}")
        self._mode_ok(k.req_continuous(), "continuous output (mode 0x24)", c.MODE_CHANGE_WITHIN)

    # -- StreamLaser hooks ----------------------------------------------------------------------------------
    def _on_data(self, data: bytes, now: float) -> None:
        self._publish_read([self.geometry.scan(ranges) for ranges in self._dec.feed(data)], now)

    def _stop_device(self) -> None:
        """Stop the output (0x20 0x25) and, on a serial line, go back to 9600 baud (0x20 0x42)."""
        self._link.write(k.req_stop())
        if self._link.is_serial and self.baud != c.POWER_ON_BAUD:
            time.sleep(0.05)
            self._link.write(k.req_baud(c.POWER_ON_BAUD))
            time.sleep(0.02)
            self._link.set_baudrate(c.POWER_ON_BAUD)
            self.baud = c.POWER_ON_BAUD

    def describe(self) -> str:
        """One line: the device, its type string and its scan mode."""
        return super().describe() + f" ({self.identity or 'LMS2xx'}, {self.baud} baud, " \
            f"{self.units.name.lower()})"
