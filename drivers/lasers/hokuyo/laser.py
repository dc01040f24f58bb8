"""Hokuyo URG/UTM laser driver: SCIP 2.0 over USB-ACM (a serial port) or TCP (UTM-30LX-EW).

`HokuyoLaser(address)` stops whatever the sensor was doing (QT), reads its identity (VV), its
scan parameters (PP) and state (II), then starts an unlimited MD stream of the configured steps;
a reader thread decodes every scan (`codec.ScanDecoder`) and stamps it on arrival. Beam angles
follow the steps: step s at (s - AFRT) * 360 / ARES deg, counter-clockwise, 0 forward, as the
laser frame wants. `close()` sends QT (laser off) and releases the link. Protocol notes:
docs/protocols/hokuyo.md.
"""

from __future__ import annotations

import math
import time
from typing import ClassVar

from robotexp import ConfigError, ConnectionLost, ProtocolError
from robotexp_drivers.backend import reads_until
from robotexp_drivers.lasers.base import LaserLink, StreamLaser
from robotexp_drivers.lasers.hokuyo import constants as C
from robotexp_drivers.lasers.hokuyo.codec import (
    Reply,
    ScanDecoder,
    ScanParams,
    command,
    geometry,
    md_command,
    parse_params,
    parse_reply,
    split_blocks,
)

__all__ = ["HokuyoLaser"]


class HokuyoLaser(StreamLaser):
    """A Hokuyo URG/UTM laser speaking SCIP 2.0 (see the module docstring).

    Args:
        address: a serial device (/dev/ttyACM0), "host:port" or socket://host:port.
        timeout: no valid scan for this long [s] fails the laser (ConnectionLost).
        start, end: the steps to scan (default: AMIN..AMAX from PP).
        cluster: steps grouped into one value (the sensor keeps the nearest of them).
        encoding: "MD" (3 characters, up to 262 m) or "MS" (2 characters, up to 4.095 m).
        range_max: [m] where beams without echo end (default: the model's rated range, else DMAX).
        reply_timeout: how long to wait for each handshake reply [s].

    Raises:
        ConnectionLost: the port cannot be opened or the sensor does not answer.
        ProtocolError: the sensor refuses a command or answers something else.
        ConfigError: an option out of range.
    """

    name: ClassVar[str] = "hokuyo"

    def __init__(self, address: str, *, timeout: float = 1.0, start: int | None = None, end: int | None = None,
                 cluster: int = 1, encoding: str = "MD", range_max: float | None = None,
                 reply_timeout: float = 2.0) -> None:
        if encoding not in ("MD", "MS"):
            raise ConfigError(f"hokuyo: encoding must be 'MD' or 'MS', got {encoding!r}")
        if not 1 <= cluster <= 99:
            raise ConfigError(f"hokuyo: cluster must be 1..99 steps, got {cluster}")
        if range_max is not None and not range_max > 0:
            raise ConfigError(f"hokuyo: range_max must be > 0 m, got {range_max}")
        self.address = address
        self._buffer = bytearray()
        self._link = LaserLink(self.name, address, baudrate=C.BAUD_RATE)
        try:
            self._handshake(start, end, cluster, encoding.encode(), range_max, reply_timeout)
        except BaseException:
            self._link.close()
            raise
        self._start_reader(timeout)

    # -- handshake -------------------------------------------------------------------------------
    def _request(self, line: bytes, timeout: float) -> Reply:
        """Send a command line and return its reply (other replies and scans are skipped)."""
        self._link.write(line)
        echo = line.rstrip(b"\r\n")
        for _ in reads_until(time.monotonic() + timeout):
            self._buffer += self._link.read_some()
            blocks, _ = split_blocks(self._buffer)
            for i, block in enumerate(blocks):
                if block.split(C.TERMINATOR, 1)[0] == echo:
                    rest = b"".join(b + C.BLOCK_END for b in blocks[i + 1:])
                    self._buffer[:0] = rest
                    return parse_reply(block)
        raise ConnectionLost(f"hokuyo: no reply to {echo.decode('ascii', 'replace')} from {self.address!r} "
                             f"within {timeout:g} s; check the cable, power and that it speaks SCIP 2.0")

    def _handshake(self, start: int | None, end: int | None, cluster: int, encoding: bytes,
                   range_max: float | None, reply_timeout: float) -> None:
        # A URG-04LX that boots in SCIP 1.1 needs "SCIP2.0" first; one in SCIP 2.0 refuses it: either is fine.
        self._link.write(command(C.CMD_SCIP2))
        time.sleep(0.05)
        self._link.reset_input()
        self._buffer.clear()
        self._request(command(C.CMD_QT), reply_timeout)           # stop a stream left running
        self.version = parse_params(self._expect(command(C.CMD_VV), reply_timeout))
        pp = parse_params(self._expect(command(C.CMD_PP), reply_timeout))
        self.state = parse_params(self._expect(command(C.CMD_II), reply_timeout))
        self.params = p = ScanParams.from_pp(pp)
        start = p.amin if start is None else start
        end = p.amax if end is None else end
        if not p.amin <= start <= end <= p.amax:
            raise ConfigError(f"hokuyo: steps {start}..{end} must lie within the sensor's {p.amin}..{p.amax}")
        if range_max is None:
            ident = p.model + " " + self.version.get("PROD", "")
            rated = [mm for key, mm in C.RATED_RANGE_MM.items() if key in ident]
            range_max = (rated[0] if rated else p.dmax_mm) / 1000.0
        self.steps = (start, end, cluster)
        self.geometry = geometry(p, start, end, cluster, range_max)
        self._decoder = ScanDecoder(p.dmin_mm, p.dmax_mm)
        self._expect(md_command(start, end, cluster, 0, C.SCANS_UNLIMITED, encoding=encoding), reply_timeout)

    def _expect(self, line: bytes, timeout: float) -> Reply:
        reply = self._request(line, timeout)
        if reply.status != C.STATUS_OK:
            raise ProtocolError(f"hokuyo: {line.strip().decode('ascii', 'replace')} refused by {self.address!r} "
                                f"with status {reply.status.decode('ascii', 'replace')}")
        return reply

    # -- StreamLaser -----------------------------------------------------------------------------
    def _on_data(self, data: bytes, now: float) -> None:
        if self._buffer:
            data = bytes(self._buffer) + data
            self._buffer.clear()
        self._publish_read([self.geometry.scan(ranges) for ranges in self._decoder.feed(data)], now)

    def _stop_device(self) -> None:
        self._link.write(command(C.CMD_QT))

    def describe(self) -> str:
        g = self.geometry
        v = self.version
        return (f"hokuyo at {self.address}: {v.get('PROD', '?')} firmware {v.get('FIRM', '?')} serial "
                f"{v.get('SERI', '?')}, steps {self.steps[0]}..{self.steps[1]} by {self.steps[2]}: {g.beams} beams "
                f"over {math.degrees(g.fov):.1f} deg, {g.range_max:g} m, {1 / g.period:.1f} Hz")
