"""A Hokuyo URG/UTM emulator: SCIP 2.0 served from a `ScanSource`, on a pseudo-terminal or TCP.

It answers VV, PP, II, BM, QT, RS, TM0/1/2, SCIP2.0, MD/MS and GD/GS as docs/protocols/hokuyo.md
describes, and streams MD/MS scans at the model's real rate (URG-04LX 600 rpm: one scan every
100 ms; UTM-30LX 2400 rpm: 25 ms), each measured by the source when it is sent, with the echo's
remaining-scans counter counting down (00 throughout for an unlimited stream) and the scan
interval honoured. Time stamps count milliseconds since start-up (or RS), modulo 2**24.

Emulation choices (not the firmware's, documented): beams are measured at the middle of their
cluster (the sensor keeps the nearest of the cluster's steps); echoes are measured out to the DMAX
its PP reply states (URG-04LX 5.6 m, beyond its rated 4 m, as a real one returns them; UTM-30LX 60 m),
no echo within DMAX is sent as error code 1; "SCIP2.0" is acknowledged with 00; a start step
outside AMIN..AMAX is refused with 04 like an end step; GD/GS with the laser off are refused with
10. Serving, transports and fault injection are `robotexp_drivers.emulation.StreamEmulator`'s.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from robotexp import ConfigError, ScanSource
from robotexp_drivers.lasers.base import LaserEmulatorBase
from robotexp_drivers.lasers.hokuyo import constants as C
from robotexp_drivers.lasers.hokuyo.codec import (
    ScanParams,
    encode_reply,
    encode_scan,
    encode_values,
    geometry,
    param_line,
    scip_sum,
)

__all__ = ["HokuyoEmulator", "HokuyoModel", "MODELS"]


@dataclass(frozen=True)
class HokuyoModel:
    """What an emulated model says about itself, and how far it sees."""

    params: ScanParams
    prod: str           # VV PROD
    firm: str           # VV FIRM
    rated: float        # [m] the range the maker guarantees (the driver's range_max)

    @property
    def reach(self) -> float:
        """[m] how far the emulated sensor measures: PP's DMAX (echoes beyond are reported as none)."""
        return self.params.dmax_mm / 1000.0


MODELS: dict[str, HokuyoModel] = {
    "URG-04LX": HokuyoModel(
        ScanParams(C.URG04_MODL, C.URG04_DMIN_MM, C.URG04_DMAX_MM, C.URG04_ARES, C.URG04_AMIN, C.URG04_AMAX,
                   C.URG04_AFRT, C.URG04_SCAN_RPM),
        "SOKUIKI Sensor URG-04LX", "3.4.03(robotexp emulator)", C.URG04_RATED_MM / 1000.0),
    "UTM-30LX": HokuyoModel(
        ScanParams(C.UTM30_MODL, C.UTM30_DMIN_MM, C.UTM30_DMAX_MM, C.UTM30_ARES, C.UTM30_AMIN, C.UTM30_AMAX,
                   C.UTM30_AFRT, C.UTM30_SCAN_RPM),
        "SOKUIKI Sensor TOP-URG UTM-30LX", "1.19.01(robotexp emulator)", C.UTM30_RATED_MM / 1000.0),
}


@dataclass
class _Stream:
    """An MD/MS stream in progress."""

    encoding: bytes
    start: int
    end: int
    cluster: int
    interval: int
    left: int | None        # scans still to send; None: until QT
    string: str | None
    angles: np.ndarray
    skipped: int = 0


class HokuyoEmulator(LaserEmulatorBase):
    """Serve a Hokuyo laser measuring with `source` (call `start()`, or use `with`).

    Args:
        source: what the laser sees.
        pty: serve on a pseudo-terminal (as a USB-ACM port) instead of TCP.
        port: TCP port on `host` (None or 0: any free one; read `address`). Ignored with `pty`.
        host: interface to listen on.
        model: "URG-04LX" (240 deg, 0.35 deg, rated 4 m, echoes to 5.6 m, 10 Hz) or "UTM-30LX" (270 deg,
            0.25 deg, rated 30 m, echoes to 60 m, 40 Hz).
        speedup: sensor seconds per wall second.
        serial: the serial number VV reports.

    Raises:
        ConfigError: an unknown model or a bad speedup.
        OSError: the port cannot be bound.
    """

    label = "hokuyo emulator"

    def __init__(self, source: ScanSource, *, pty: bool = False, port: int | None = None, host: str = "127.0.0.1",
                 model: str = "URG-04LX", speedup: float = 1.0, serial: str = "H0000001") -> None:
        if model not in MODELS:
            raise ConfigError(f"hokuyo emulator: model must be one of {', '.join(MODELS)}, got {model!r}")
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"hokuyo emulator: speedup must be > 0, got {speedup}")
        self._init_laser(source, speedup)
        self.model = MODELS[model]
        self.serial = serial
        self.commands: list[bytes] = []         # every command line received, in order
        self.scans_sent = 0
        self._line = bytearray()
        self._reset()
        self._open_transport(pty, port, host)

    @property
    def _period(self) -> float:
        return 60.0 / self.model.params.scan_rpm / self.speedup

    def _reset(self) -> None:
        self.laser_on = False
        self.time_adjust = False
        self._stream: _Stream | None = None
        self._t0 = time.monotonic()

    def _now_ms(self) -> int:
        return int((time.monotonic() - self._t0) * 1000.0 * self.speedup) % C.TIMESTAMP_MODULO

    @property
    def streaming(self) -> bool:
        """An MD/MS stream is running."""
        return self._stream is not None

    # -- serving -------------------------------------------------------------------------------------
    def _on_connect(self) -> None:
        self._reset()
        self._line.clear()

    def _halt(self) -> None:
        self._stream = None

    def _step(self) -> bytes:
        s = self._stream
        if s is None:
            return b""
        s.skipped += 1
        if (s.skipped - 1) % (s.interval + 1):
            return b""
        if s.left is not None:
            s.left -= 1
            if s.left <= 0:
                self._stream = None
        ranges = self.source(s.angles, self.model.reach)
        self.scans_sent += 1
        return encode_scan(ranges, start=s.start, end=s.end, cluster=s.cluster, encoding=s.encoding,
                           interval=s.interval, remaining=0 if s.left is None else s.left,
                           timestamp_ms=self._now_ms(), string=s.string)

    def _on_bytes(self, data: bytes) -> None:
        for byte in data:
            if byte in (C.LF, C.CR):
                if self._line:
                    line = bytes(self._line)
                    self._line.clear()
                    self.commands.append(line)
                    self._transmit(self._answer(line))
            elif len(self._line) < 64:
                self._line.append(byte)

    # -- commands --------------------------------------------------------------------------------------
    def _answer(self, line: bytes) -> bytes:
        name, rest = line[:2], line[2:]
        p = self.model.params
        if line == C.CMD_SCIP2:
            return encode_reply(line, C.STATUS_OK)
        if line == C.CMD_VV:
            return encode_reply(line, C.STATUS_OK, [
                param_line("VEND", "Hokuyo Automatic Co.,Ltd."), param_line("PROD", self.model.prod),
                param_line("FIRM", self.model.firm), param_line("PROT", "SCIP 2.0"),
                param_line("SERI", self.serial)])
        if line == C.CMD_PP:
            return encode_reply(line, C.STATUS_OK, p.pp_lines())
        if line == C.CMD_II:
            # the 24-bit millisecond counter as 6 hex digits, as a URG's II reply gives it ("TIME:081615;N");
            # in the 4-character encoding of scans it may hold ':' or ';', which parsers split lines on
            stamp = f"{self._now_ms():06X}"
            return encode_reply(line, C.STATUS_OK, [
                param_line("MODL", p.model), param_line("LASR", "ON" if self.laser_on else "OFF"),
                param_line("SCSP", f"Initial({p.scan_rpm}[rpm])"),
                param_line("MESM", "Measuring by Normal Mode"), param_line("SBPS", "USB only"),
                param_line("TIME", stamp), param_line("STAT", "Sensor works well.")])
        if line == C.CMD_BM:
            was_on, self.laser_on = self.laser_on, True
            return encode_reply(line, C.STATUS_BM_ALREADY_ON if was_on else C.STATUS_OK)
        if line in (C.CMD_QT, C.CMD_RS):
            self._stream = None
            self.laser_on = False
            if line == C.CMD_RS:
                self._reset()
            return encode_reply(line, C.STATUS_OK)
        if name == C.CMD_TM and len(rest) == 1:
            return self._time_adjust(line, rest)
        if name in (C.CMD_MD, C.CMD_MS):
            return self._multi(line, name, rest)
        if name in (C.CMD_GD, C.CMD_GS):
            return self._single(line, name, rest)
        return encode_reply(line, C.STATUS_UNDEFINED)

    def _time_adjust(self, line: bytes, code: bytes) -> bytes:
        if code == b"0":
            was, self.time_adjust = self.time_adjust, True
            return encode_reply(line, C.STATUS_TM_ALREADY_IN if was else C.STATUS_OK)
        if code == b"1":
            if not self.time_adjust:
                return encode_reply(line, C.STATUS_TM_NOT_IN)
            stamp = encode_values([self._now_ms()], C.TIMESTAMP_CHARS)
            return encode_reply(line, C.STATUS_OK, [stamp + bytes((scip_sum(stamp),))])
        if code == b"2":
            was, self.time_adjust = self.time_adjust, False
            return encode_reply(line, C.STATUS_OK if was else C.STATUS_TM_ALREADY_OUT)
        return encode_reply(line, C.STATUS_TM_BAD_CODE)

    def _steps(self, params: bytes) -> tuple[int, int, int] | bytes:
        """(start, end, cluster) from the first 10 digits, or the error status."""
        for field, (a, b) in ((C.STATUS_BAD_START, (0, 4)), (C.STATUS_BAD_END, (4, 8)),
                              (C.STATUS_BAD_CLUSTER, (8, 10))):
            if not params[a:b].isdigit():
                return field
        start, end, cluster = int(params[0:4]), int(params[4:8]), int(params[8:10])
        p = self.model.params
        if not (p.amin <= start <= p.amax and end <= p.amax):
            return C.STATUS_END_OUT_OF_RANGE
        if end < start:
            return C.STATUS_END_BEFORE_START
        return start, end, cluster

    def _scan_request(self, rest: bytes, digits: int) -> tuple[bytes, str | None, tuple[int, int, int]] | bytes:
        """(parameters, ";string", steps) of an MD/MS/GD/GS request, or the status refusing it."""
        params, sep, string = rest.partition(b";")
        if len(params) != digits or len(string) > C.STRING_MAX:
            return b"0H" if len(params) < digits else b"0D"      # command too short / too long
        steps = self._steps(params)
        if isinstance(steps, bytes):
            return steps
        return params, string.decode("ascii", "replace") if sep else None, steps

    def _angles(self, start: int, end: int, cluster: int) -> np.ndarray:
        return geometry(self.model.params, start, end, cluster, self.model.rated).angles()

    def _multi(self, line: bytes, name: bytes, rest: bytes) -> bytes:
        req = self._scan_request(rest, C.MD_PARAM_DIGITS)
        if isinstance(req, bytes):
            return encode_reply(line, req)
        params, string, (start, end, cluster) = req
        if not params[10:11].isdigit():
            return encode_reply(line, C.STATUS_BAD_INTERVAL)
        if not params[11:13].isdigit():
            return encode_reply(line, C.STATUS_BAD_SCANS)
        scans = int(params[11:13])
        self.laser_on = True
        self._stream = _Stream(name, start, end, cluster, int(params[10:11]),
                               None if scans == C.SCANS_UNLIMITED else scans, string,
                               self._angles(start, end, cluster))
        return encode_reply(line, C.STATUS_OK)

    def _single(self, line: bytes, name: bytes, rest: bytes) -> bytes:
        req = self._scan_request(rest, C.GD_PARAM_DIGITS)
        if isinstance(req, bytes):
            return encode_reply(line, req)
        if not self.laser_on:
            return encode_reply(line, C.STATUS_DENIED)
        _, string, (start, end, cluster) = req
        ranges = self.source(self._angles(start, end, cluster), self.model.reach)
        return encode_scan(ranges, start=start, end=end, cluster=cluster, encoding=name,
                           timestamp_ms=self._now_ms(), string=string)
