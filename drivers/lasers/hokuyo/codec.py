"""Pure codec of Hokuyo's SCIP 2.0: commands, replies, the character encoding and the scan stream.

No I/O and no clocks here. A command is ASCII ending with LF; a reply is the command's echo, a
status line (2 characters and their sum), data lines (at most 64 characters and their sum) and an
empty line, so every reply ends with LF LF (docs/protocols/hokuyo.md). Distances are 2 or 3
characters (MS/GS, MD/GD) of 6 bits each plus 0x30, most significant first; a data block is cut
into lines of 64 characters regardless of value boundaries. Units stay the protocol's (mm, steps,
ms) except in `encode_scan` and `ScanDecoder`, which speak metres.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, LaserGeometry, ProtocolError
from robotexp_drivers.lasers.hokuyo import constants as C

__all__ = [
    "Reply", "ScanDecoder", "ScanParams", "beam_count", "command", "decode_values", "encode_reply",
    "encode_scan", "encode_values", "gd_command", "geometry", "md_command", "param_line",
    "parse_params", "parse_reply", "scip_sum", "split_blocks", "sum_ok",
]

MAX_BLOCK = 16384     # [bytes] a reply longer than this without its empty line is noise (UTM-30LX: ~3.5 k)

_MD_ECHO = re.compile(rb"(MD|MS)(\d{4})(\d{4})(\d{2})(\d)(\d{2})(?:;[\x20-\x7e]{0,16})?\Z")
_GD_ECHO = re.compile(rb"(GD|GS)(\d{4})(\d{4})(\d{2})(?:;[\x20-\x7e]{0,16})?\Z")


# --- sums and the character encoding ------------------------------------------------------------
def scip_sum(data: bytes) -> int:
    """The sum character of `data`: the low 6 bits of its byte sum, plus 0x30."""
    return (sum(data) & C.SUM_MASK) + C.ENCODE_OFFSET


def sum_ok(line: bytes) -> bool:
    """True when `line` (data then its sum character, no LF) has a good sum."""
    return len(line) >= 2 and scip_sum(line[:-1]) == line[-1]


def encode_values(values: npt.ArrayLike, chars: int) -> bytes:
    """Encode non-negative integers in `chars` (2, 3 or 4) characters each.

    Raises:
        ConfigError: `chars` out of 1..4 or a value that does not fit.
    """
    if not 1 <= chars <= 4:
        raise ConfigError(f"SCIP encoding: chars must be 1..4, got {chars}")
    v = np.asarray(values, dtype=np.int64).ravel()
    if v.size and (v.min() < 0 or v.max() >= 1 << (C.ENCODE_BITS * chars)):
        raise ConfigError(f"SCIP encoding: values must be 0..{(1 << (C.ENCODE_BITS * chars)) - 1} in "
                          f"{chars} characters, got {int(v.min())}..{int(v.max())}")
    out = np.empty((v.size, chars), np.uint8)
    for k in range(chars):
        out[:, k] = ((v >> (C.ENCODE_BITS * (chars - 1 - k))) & C.SUM_MASK) + C.ENCODE_OFFSET
    return out.tobytes()


def decode_values(data: bytes, chars: int) -> npt.NDArray[np.int64]:
    """Decode a run of `chars`-character values.

    Raises:
        ProtocolError: a length not a multiple of `chars` or a character outside 0x30..0x6F.
    """
    if len(data) % chars:
        raise ProtocolError(f"SCIP data: {len(data)} characters is not a whole number of {chars}-character values")
    a = np.frombuffer(data, np.uint8).astype(np.int64) - C.ENCODE_OFFSET
    if a.size and (a.min() < 0 or a.max() > C.SUM_MASK):
        raise ProtocolError("SCIP data: a character outside 0x30..0x6F")
    a = a.reshape(-1, chars)
    out = np.zeros(a.shape[0], np.int64)
    for k in range(chars):
        out = (out << C.ENCODE_BITS) | a[:, k]
    return out


def data_lines(payload: bytes) -> bytes:
    """`payload` cut into lines of 64 characters, each followed by its sum and LF."""
    out = bytearray()
    for i in range(0, len(payload), C.LINE_DATA_MAX):
        chunk = payload[i:i + C.LINE_DATA_MAX]
        out += chunk
        out.append(scip_sum(chunk))
        out.append(C.LF)
    return bytes(out)


# --- commands -------------------------------------------------------------------------------------
def command(name: bytes, params: bytes = b"", string: str | None = None) -> bytes:
    """A command line: name, parameters, optional ";string" (echoed back), LF.

    Raises:
        ConfigError: a string longer than 16 characters or not printable ASCII.
    """
    line = name + params
    if string is not None:
        if len(string) > C.STRING_MAX or not all(0x20 <= ord(c) < 0x7F for c in string):
            raise ConfigError(f"SCIP command string must be <= {C.STRING_MAX} printable ASCII characters, "
                              f"got {string!r}")
        line += b";" + string.encode("ascii")
    return line + C.TERMINATOR


def md_command(start: int, end: int, cluster: int = 1, interval: int = 0, scans: int = 0, *,
               encoding: bytes = C.CMD_MD, string: str | None = None) -> bytes:
    """MD (3 characters) or MS (2 characters): stream `scans` scans (0: until QT) of steps
    `start`..`end` grouped by `cluster`, sending one scan in `interval` + 1.

    Raises:
        ConfigError: a field that does not fit its digits, or an encoding other than MD/MS.
    """
    if encoding not in (C.CMD_MD, C.CMD_MS):
        raise ConfigError(f"SCIP multi-scan command must be MD or MS, got {encoding!r}")
    _check_fields(start=(start, 9999), end=(end, 9999), cluster=(cluster, 99), interval=(interval, 9),
                  scans=(scans, 99))
    return command(encoding, f"{start:04d}{end:04d}{cluster:02d}{interval:1d}{scans:02d}".encode(), string)


def gd_command(start: int, end: int, cluster: int = 1, *, encoding: bytes = C.CMD_GD,
               string: str | None = None) -> bytes:
    """GD (3 characters) or GS (2 characters): one scan of steps `start`..`end` by `cluster`.

    Raises:
        ConfigError: a field that does not fit its digits, or an encoding other than GD/GS.
    """
    if encoding not in (C.CMD_GD, C.CMD_GS):
        raise ConfigError(f"SCIP single-scan command must be GD or GS, got {encoding!r}")
    _check_fields(start=(start, 9999), end=(end, 9999), cluster=(cluster, 99))
    return command(encoding, f"{start:04d}{end:04d}{cluster:02d}".encode(), string)


def _check_fields(**fields: tuple[int, int]) -> None:
    for name, (value, top) in fields.items():
        if not 0 <= value <= top:
            raise ConfigError(f"SCIP command: {name} must be 0..{top}, got {value}")


# --- replies ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reply:
    """A reply: the echo of its command, the 2-character status, and its lines (sums verified and
    removed; parameter lines keep their ';')."""

    echo: bytes
    status: bytes
    lines: tuple[bytes, ...]


def param_line(key: str, value: str) -> bytes:
    """A parameter line of VV/PP/II without LF: ``KEY:value;`` then the sum of ``KEY:value``."""
    text = f"{key}:{value}".encode("ascii")
    return text + b";" + bytes((scip_sum(text),))


def encode_reply(echo: bytes, status: bytes, lines: list[bytes] | tuple[bytes, ...] = ()) -> bytes:
    """A whole reply: `echo` (the command line without LF), the status and its sum, `lines` (each
    already ending with its sum, see `param_line` / `data_lines`), the empty line."""
    out = bytearray(echo + C.TERMINATOR + status + bytes((scip_sum(status),)) + C.TERMINATOR)
    for line in lines:
        out += line + C.TERMINATOR
    return bytes(out + C.TERMINATOR)


def split_blocks(buf: bytearray) -> tuple[list[bytes], int]:
    """Take every complete reply (up to its empty line) out of `buf`, in place; each comes back
    without its final LF LF. Empty lines between replies are dropped; a tail longer than
    `MAX_BLOCK` without an empty line is cut back to what follows its last LF.

    Returns:
        The replies, and the bytes of noise cut off the over-long tail (0 mostly).
    """
    out: list[bytes] = []
    pos = 0
    while True:
        while pos < len(buf) and buf[pos] == C.LF:
            pos += 1
        end = buf.find(C.BLOCK_END, pos)
        if end < 0:
            break
        out.append(bytes(buf[pos:end]))
        pos = end + 2
    del buf[:pos]
    cut = 0
    if len(buf) > MAX_BLOCK:
        last = buf.rfind(C.LF)
        cut = last + 1 if last >= 0 else len(buf)
        del buf[:cut]
    return out, cut


def parse_reply(block: bytes) -> Reply:
    """Check and split one reply as `split_blocks` gives it.

    Raises:
        ProtocolError: no status line, or a bad sum on the status or a data line.
    """
    lines = block.split(C.TERMINATOR)
    if len(lines) < 2 or len(lines[1]) != 3 or not sum_ok(lines[1]):
        raise ProtocolError(f"SCIP reply to {lines[0][:20]!r}: bad status line {lines[1:2]!r}")
    body = []
    for line in lines[2:]:
        if not sum_ok(line) and not _param_sum_ok(line):
            raise ProtocolError(f"SCIP reply to {lines[0][:20]!r}: bad sum on line {line[:70]!r}")
        body.append(line[:-1])
    return Reply(lines[0], lines[1][:2], tuple(body))


def _param_sum_ok(line: bytes) -> bool:
    # "KEY:value;S" with S the sum of "KEY:value" [cap, lx]
    return len(line) >= 3 and line[-2] == 0x3B and scip_sum(line[:-2]) == line[-1]


def parse_params(reply: Reply) -> dict[str, str]:
    """The ``KEY:value`` lines of a VV/PP/II reply.

    Raises:
        ProtocolError: a line that is not ``KEY:value;``.
    """
    out: dict[str, str] = {}
    for line in reply.lines:
        text = line.decode("ascii", "replace")
        if not text.endswith(";") or ":" not in text:
            raise ProtocolError(f"SCIP {reply.echo[:2]!r} reply: line {text!r} is not KEY:value;")
        key, value = text[:-1].split(":", 1)
        out[key] = value
    return out


# --- scan geometry ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ScanParams:
    """What PP says about the scanner (steps, distances in mm, speed in rpm)."""

    model: str
    dmin_mm: int
    dmax_mm: int
    ares: int
    amin: int
    amax: int
    afrt: int
    scan_rpm: int

    @classmethod
    def from_pp(cls, params: dict[str, str]) -> ScanParams:
        """From a PP reply's parameters.

        Raises:
            ProtocolError: a key missing or not a number.
        """
        try:
            return cls(params.get("MODL", "?"), int(params["DMIN"]), int(params["DMAX"]), int(params["ARES"]),
                       int(params["AMIN"]), int(params["AMAX"]), int(params["AFRT"]), int(params["SCAN"]))
        except (KeyError, ValueError) as exc:
            raise ProtocolError(f"SCIP PP reply: missing or bad parameter ({exc}) in {params}") from exc

    def pp_lines(self) -> list[bytes]:
        """The PP reply's lines (for an emulator)."""
        return [param_line(k, str(v)) for k, v in (
            ("MODL", self.model), ("DMIN", self.dmin_mm), ("DMAX", self.dmax_mm), ("ARES", self.ares),
            ("AMIN", self.amin), ("AMAX", self.amax), ("AFRT", self.afrt), ("SCAN", self.scan_rpm))]


def beam_count(start: int, end: int, cluster: int) -> int:
    """Values in a scan of steps `start`..`end` grouped by `cluster` (0 counts as 1)."""
    return -(-(end - start + 1) // max(cluster, 1))


def geometry(p: ScanParams, start: int, end: int, cluster: int, range_max: float) -> LaserGeometry:
    """The beams of a scan of steps `start`..`end` by `cluster`: step s points at
    (s - AFRT) * 2 pi / ARES, counter-clockwise; a cluster's beam at the middle of its steps."""
    c = max(cluster, 1)
    step = 2 * math.pi / p.ares
    return LaserGeometry(angle_min=(start + (c - 1) / 2 - p.afrt) * step, increment=c * step,
                         beams=beam_count(start, end, c), range_min=p.dmin_mm / 1000.0, range_max=range_max,
                         period=60.0 / p.scan_rpm)


# --- the scan stream --------------------------------------------------------------------------------
def encode_scan(ranges: npt.ArrayLike, *, start: int = C.URG04_AMIN, end: int | None = None, cluster: int = 1,
                encoding: bytes = C.CMD_MD, interval: int = 0, remaining: int = 0, timestamp_ms: int = 0,
                string: str | None = None) -> bytes:
    """One scan as the sensor streams it after MD/MS (status 99) or answers GD/GS (status 00).

    Args:
        ranges: [m] one per beam; inf or NaN (no echo) is sent as an error code below DMIN.
        start, end, cluster: the steps of the scan, as in the command (end None: fits `ranges`).
        encoding: MD, MS, GD or GS.
        interval, remaining: MD/MS echo fields (remaining: the scans still to come, 00 unlimited).
        timestamp_ms: the sensor's time [ms], modulo 2**24.
        string: the command's ";string", echoed.

    Raises:
        ConfigError: `ranges` does not fill the steps, or a field out of range.
    """
    r = np.asarray(ranges, dtype=np.float64).ravel()
    if end is None:
        end = start + r.size * max(cluster, 1) - 1
    if beam_count(start, end, cluster) != r.size:
        raise ConfigError(f"SCIP scan: steps {start}..{end} by {cluster} make {beam_count(start, end, cluster)} "
                          f"values, got {r.size} ranges")
    chars = C.ENCODING_CHARS.get(encoding)
    if chars is None:
        raise ConfigError(f"SCIP scan: encoding must be MD, MS, GD or GS, got {encoding!r}")
    top = C.ENC3_MAX if chars == 3 else C.ENC2_MAX
    ok = np.isfinite(r)
    mm = np.full(r.size, C.NO_ECHO_CODE, np.int64)
    mm[ok] = np.clip(np.rint(r[ok] * 1000.0), 0, top).astype(np.int64)
    if encoding in (C.CMD_MD, C.CMD_MS):
        echo = md_command(start, end, cluster, interval, remaining, encoding=encoding, string=string)[:-1]
        status = C.STATUS_SCAN
    else:
        echo = gd_command(start, end, cluster, encoding=encoding, string=string)[:-1]
        status = C.STATUS_OK
    stamp = encode_values([timestamp_ms % C.TIMESTAMP_MODULO], C.TIMESTAMP_CHARS)
    out = bytearray(echo + C.TERMINATOR + status + bytes((scip_sum(status),)) + C.TERMINATOR)
    out += stamp + bytes((scip_sum(stamp), C.LF))
    out += data_lines(encode_values(mm, chars))
    out.append(C.LF)
    return bytes(out)


class ScanDecoder:
    """Incremental decoder of a SCIP 2.0 stream: feed it any bytes, get the ranges of every scan
    (MD/MS status 99, GD/GS status 00) completed by them.

    A reply is taken whole up to its empty line; a scan counts only when its echo is a well-formed
    MD/MS/GD/GS line (noise before it on the same line is cut off), every sum is right and the data
    hold exactly the values its steps call for. Anything else is dropped up to the next empty line
    (the next reply). Values outside DMIN..DMAX (the error codes below DMIN) read `inf`.
    `feed` never raises on any bytes.

    Attributes:
        scans: scans decoded.
        replies: other well-formed replies seen (command acknowledgements, MD's "00" start).
        dropped_bytes: bytes of rejected replies and noise.
        bad_sums: replies rejected for a sum.
        bad_lengths: scans rejected for the number or the characters of their values.
        timestamp_ms: the last scan's sensor time [ms] (None before the first).
        remaining: the last MD/MS scan's remaining-scans field.
        echo: the last scan's echo line.
    """

    def __init__(self, dmin_mm: int = C.URG04_DMIN_MM, dmax_mm: int = C.ENC3_MAX) -> None:
        self.dmin_mm = dmin_mm
        self.dmax_mm = dmax_mm
        self._buffer = bytearray()
        self.scans = 0
        self.replies = 0
        self.dropped_bytes = 0
        self.bad_sums = 0
        self.bad_lengths = 0
        self.timestamp_ms: int | None = None
        self.remaining = 0
        self.echo = b""

    def feed(self, data: bytes | bytearray | memoryview) -> list[npt.NDArray[np.float64]]:
        """Append `data` to the stream; return the ranges [m] of the scans it completed, in order."""
        self._buffer += data
        blocks, cut = split_blocks(self._buffer)
        self.dropped_bytes += cut
        out: list[npt.NDArray[np.float64]] = []
        for block in blocks:
            ranges = self._block(block)
            if ranges is not None:
                out.append(ranges)
        return out

    def _block(self, block: bytes) -> npt.NDArray[np.float64] | None:
        lines = block.split(C.TERMINATOR)
        for i in range(len(lines) - 1):
            status = lines[i + 1]
            if len(status) != 3 or not sum_ok(status):
                continue
            m = _MD_ECHO.search(lines[i]) or _GD_ECHO.search(lines[i])
            if m is None:
                if i == 0:                      # a well-formed reply to another command
                    self.replies += 1
                    return None
                continue
            self.dropped_bytes += sum(len(x) + 1 for x in lines[:i]) + m.start()
            want = C.STATUS_SCAN if m.group(1) in (C.CMD_MD, C.CMD_MS) else C.STATUS_OK
            if status[:2] != want:
                self.replies += 1               # MD's "00" acknowledgement, or an error status
                return None
            return self._scan(m, lines[i + 2:], block)
        self.dropped_bytes += len(block) + 2
        return None

    def _scan(self, m: re.Match[bytes], lines: list[bytes], block: bytes) -> npt.NDArray[np.float64] | None:
        if not lines or len(lines[0]) != C.TIMESTAMP_CHARS + 1:
            self.bad_lengths += 1
            self.dropped_bytes += len(block) + 2
            return None
        for line in lines:
            if len(line) > C.LINE_DATA_MAX + 1 or not sum_ok(line):
                self.bad_sums += 1
                self.dropped_bytes += len(block) + 2
                return None
        chars = C.ENCODING_CHARS[m.group(1)]
        start, end, cluster = int(m.group(2)), int(m.group(3)), int(m.group(4))
        payload = b"".join(line[:-1] for line in lines[1:])
        try:
            stamp = decode_values(lines[0][:-1], C.TIMESTAMP_CHARS)
            values = decode_values(payload, chars)
        except ProtocolError:
            values = np.zeros(0, np.int64)
            stamp = np.zeros(1, np.int64)
            payload = b"?"
        if end < start or values.size != beam_count(start, end, cluster) or payload == b"?":
            self.bad_lengths += 1
            self.dropped_bytes += len(block) + 2
            return None
        self.scans += 1
        self.timestamp_ms = int(stamp[0])
        self.remaining = int(m.group(6)) if m.group(1) in (C.CMD_MD, C.CMD_MS) else 0
        self.echo = m.group(0)
        ranges = values.astype(np.float64) / 1000.0
        ranges[(values < self.dmin_mm) | (values > self.dmax_mm)] = math.inf
        return ranges
