"""SICK LMS2xx telegrams: framing, CRC-16, the requests and replies robotexp uses, measured values.

No I/O and no clock. A telegram (TL 4.2) is

    STX(0x02) ADDRESS LEN_LO LEN_HI COMMAND DATA... [STATUS] CRC_LO CRC_HI

where LEN counts COMMAND + DATA (+ STATUS, present in replies only), host requests go to address 0x00
and replies come from 0x80 | the LMS's address, and the CRC covers STX .. the last byte before it.
The CRC (TL 9, "CreateCRC") is not a table CRC: per byte the 16-bit register is shifted left once
(XOR 0x8005 when its top bit fell out) and then XORed with (previous byte << 8 | this byte).

`ScanDecoder` turns the continuous output (0xB0 telegrams after mode 0x24) into ranges [m] with `inf`
for no-distance values; `encode_scan` makes such a telegram. Constants: `constants.py`; layouts and
sources: docs/protocols/lms2xx.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, ProtocolError
from robotexp_drivers.lasers.lms2xx import constants as c

__all__ = [
    "crc16", "crc16_reference", "encode_telegram", "Telegram", "TelegramDecoder", "ScanDecoder", "encode_scan",
    "MeasuredValues", "encode_values", "decode_values", "ranges_to_values", "values_to_ranges", "range_bits",
    "reach_of", "LMSConfig", "LMSStatus", "req_reset", "req_mode", "req_installation", "req_continuous",
    "req_stop", "req_baud", "req_status", "req_type", "req_variant", "req_config", "req_configure",
    "req_values", "reply_mode", "reply_variant", "reply_config", "reply_configured", "reply_status",
    "reply_type", "reply_power_on", "reply_reset_ack", "reply_not_acknowledged", "parse_mode_reply",
    "parse_variant_reply", "parse_config_reply", "parse_status_reply", "units_of",
]

_WHERE = "lms2xx codec"


# -- CRC ---------------------------------------------------------------------------------------------------
def crc16_reference(data: bytes | bytearray | memoryview) -> int:
    """The LMS2xx CRC-16 of `data`, byte by byte as TL 9 writes it (the slow reference of `crc16`)."""
    crc = 0
    prev = 0
    for byte in bytes(data):
        if crc & 0x8000:
            crc = ((crc & 0x7FFF) << 1) ^ c.CRC16_GEN_POL
        else:
            crc = crc << 1
        crc = (crc ^ ((prev << 8) | byte)) & 0xFFFF
        prev = byte
    return crc


@numba.njit(cache=True)
def _crc16_kernel(data: npt.NDArray[np.uint8]) -> int:    # pragma: no cover - compiled
    crc = 0
    prev = 0
    for i in range(data.shape[0]):
        byte = int(data[i])
        if crc & 0x8000:
            crc = ((crc & 0x7FFF) << 1) ^ 0x8005
        else:
            crc = crc << 1
        crc = (crc ^ ((prev << 8) | byte)) & 0xFFFF
        prev = byte
    return crc


def crc16(data: bytes | bytearray | memoryview) -> int:
    """The LMS2xx CRC-16 of `data` (numba kernel; equal to `crc16_reference`), sent low byte first."""
    if len(data) < 16:
        return crc16_reference(data)
    return int(_crc16_kernel(np.frombuffer(bytes(data), dtype=np.uint8)))


# -- framing -----------------------------------------------------------------------------------------------
def encode_telegram(command: int, data: bytes = b"", *, address: int = c.ADDR_BROADCAST,
                    status: int | None = None) -> bytes:
    """Frame one telegram.

    Args:
        command: the command (request) or reply code.
        data: the bytes after the code.
        address: 0x00 (broadcast) for requests; 0x80 | address for replies.
        status: the status byte ending a reply (None for a request).

    Returns:
        STX, address, length, command, data, [status], CRC (low byte first).

    Raises:
        ConfigError: a byte value out of range or a telegram longer than the LMS's largest.
    """
    if not (0 <= command <= 0xFF and 0 <= address <= 0xFF and (status is None or 0 <= status <= 0xFF)):
        raise ConfigError(f"{_WHERE}: command, address and status must be bytes")
    body = bytes((command,)) + bytes(data) + (b"" if status is None else bytes((status,)))
    if len(body) > c.MAX_LENGTH:
        raise ConfigError(f"{_WHERE}: telegram of {len(body)} bytes exceeds the LMS's {c.MAX_LENGTH}")
    frame = bytes((c.STX, address)) + len(body).to_bytes(2, "little") + body
    return frame + crc16(frame).to_bytes(2, "little")


@dataclass(frozen=True)
class Telegram:
    """One decoded telegram: `status` is the reply's final byte (None in a request)."""

    address: int
    command: int
    data: bytes
    status: int | None = None

    @property
    def is_reply(self) -> bool:
        """True for an LMS -> host telegram."""
        return bool(self.address & c.ADDR_REPLY_BIT)


class TelegramDecoder:
    """Splits a byte stream into telegrams; resynchronises on STX after garbage, never raises.

    A candidate starts at STX followed by an address of the expected direction (bit 7 set in replies,
    clear in requests) and a length within the LMS's limits; a candidate whose CRC fails is dropped one
    byte at a time (a real telegram may start inside it). Standalone ACK/NAK bytes between telegrams are
    counted (`acks`, `naks`) and otherwise dropped like garbage.

    Args:
        replies: decode LMS -> host replies (with a status byte) if True, host -> LMS requests if False.
    """

    def __init__(self, replies: bool = True) -> None:
        self.replies = replies
        self._buf = bytearray()
        self.telegrams = 0        # with a good CRC
        self.dropped_bytes = 0    # bytes not part of any good telegram (ACK/NAK included)
        self.bad_crcs = 0
        self.bad_headers = 0      # STX with a wrong-direction address or an impossible length
        self.truncated = 0        # incomplete candidates dropped by flush()
        self.acks = 0
        self.naks = 0

    @property
    def buffered(self) -> int:
        """Bytes held back, waiting for the rest of a telegram."""
        return len(self._buf)

    def _count_controls(self, segment: bytes | bytearray) -> None:
        self.acks += segment.count(c.ACK)
        self.naks += segment.count(c.NAK)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Telegram]:
        """Append `data`; return every telegram completed by it, in order."""
        return self._decode(data, final=False)

    def flush(self) -> list[Telegram]:
        """The stream ended (or went silent): drop an incomplete candidate, return telegrams behind it."""
        return self._decode(b"", final=True)

    def _decode(self, data: bytes | bytearray | memoryview, final: bool) -> list[Telegram]:
        buf = self._buf
        buf += data
        out: list[Telegram] = []
        pos, n = 0, len(buf)
        min_len = 2 if self.replies else 1
        while True:
            i = buf.find(c.STX, pos)
            if i < 0:
                self._count_controls(buf[pos:n])
                self.dropped_bytes += n - pos
                pos = n
                break
            if i > pos:
                self._count_controls(buf[pos:i])
                self.dropped_bytes += i - pos
            pos = i
            if pos + c.HEADER_LEN > n:          # the header is not complete yet
                if not final:
                    break
                self.truncated += 1
            elif bool(buf[pos + 1] & c.ADDR_REPLY_BIT) != self.replies or not (
                    min_len <= (length := buf[pos + 2] | buf[pos + 3] << 8) <= c.MAX_LENGTH):
                self.bad_headers += 1
            else:
                end = pos + c.HEADER_LEN + length + c.CRC_LEN
                if end > n:
                    if not final:
                        break
                    self.truncated += 1
                elif crc16(buf[pos:end - 2]) != (buf[end - 2] | buf[end - 1] << 8):
                    self.bad_crcs += 1
                else:
                    body = bytes(buf[pos + c.HEADER_LEN:end - 2])
                    if self.replies:
                        out.append(Telegram(buf[pos + 1], body[0], body[1:-1], body[-1]))
                    else:
                        out.append(Telegram(buf[pos + 1], body[0], body[1:]))
                    self.telegrams += 1
                    pos = end
                    continue
            # drop only the STX: a real telegram may start inside the rejected bytes
            self.dropped_bytes += 1
            pos += 1
        del buf[:pos]
        return out


# -- measured values ---------------------------------------------------------------------------------------
def range_bits(measuring_mode: int) -> int:
    """Bits of the range field in a measured value of `measuring_mode` (13, 14 or 15).

    Raises:
        ConfigError: a mode the LMS2xx does not define for ranges.
    """
    try:
        return c.RANGE_BITS[measuring_mode]
    except KeyError:
        raise ConfigError(f"{_WHERE}: measuring mode 0x{measuring_mode:02X} is not a range mode; use one of "
                          + ", ".join(f"0x{m:02X}" for m in c.RANGE_BITS)) from None


def units_of(name: str | int) -> c.Units:
    """`Units` from "mm"/"cm" or the code. Raises ConfigError on anything else."""
    if isinstance(name, str):
        try:
            return c.Units[name.upper()]
        except KeyError:
            raise ConfigError(f"{_WHERE}: units must be 'mm' or 'cm', got {name!r}") from None
    try:
        return c.Units(name)
    except ValueError:
        raise ConfigError(f"{_WHERE}: unit code must be 0 (cm) or 1 (mm), got {name}") from None


def reach_of(measuring_mode: int, units: int) -> float:
    """[m] the nominal range of a measuring mode in `units`: 8 m (mm) / 80 m (cm) for the 13-bit modes,
    16 m / 32 m for the 14/15-bit modes in mm, capped at the LMS200's 80 m."""
    nominal = c.MODE_RANGE_MM[range_bits(measuring_mode)]
    if units_of(units) == c.Units.CM:
        nominal *= 10
    return min(nominal, c.LMS200_MAX_RANGE)


def ranges_to_values(ranges: npt.ArrayLike, *, units: int = c.Units.MM, bits: int = 13,
                     reach: float | None = None) -> npt.NDArray[np.uint16]:
    """Measured values (range field only, flags 0) of `ranges` [m]: rounded to the unit; `inf`, NaN,
    negative or beyond `reach` (default: the largest value the field holds) become 'over maximum'."""
    unit = c.UNIT_METRES[units_of(units)]
    floor = c.special_floor(bits)
    r = np.asarray(ranges, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        raw = np.rint(r / unit)
        limit = floor - 1 if reach is None else min(floor - 1, int(round(reach / unit)))
        ok = np.isfinite(raw) & (raw >= 0) & (raw <= limit)
    return np.where(ok, raw, floor).astype(np.uint16)


def values_to_ranges(values: npt.NDArray[np.integer], *, units: int = c.Units.MM,
                     bits: int = 13) -> npt.NDArray[np.float64]:
    """Ranges [m] of measured values: the low `bits` bits in `units`; special values -> `inf`."""
    field = np.asarray(values).astype(np.int64) & ((1 << bits) - 1)
    out = field * c.UNIT_METRES[units_of(units)]
    return np.where(field >= c.special_floor(bits), np.inf, out)


@dataclass(frozen=True)
class MeasuredValues:
    """The data of a 0xB0 telegram (TL 7.5.2): header word fields and the raw 16-bit values."""

    values: npt.NDArray[np.uint16]     # raw words: range field + mode-dependent flag bits
    units: c.Units
    partial: bool = False
    raster: int = 0                    # partial-scan raster 0..3 (0.25 deg steps)
    extra: bytes = b""                 # real-time / telegram index bytes, when configured


def encode_values(mv: MeasuredValues) -> bytes:
    """The data bytes of a 0xB0 telegram (header word + little-endian values + extra bytes).

    Raises:
        ConfigError: more values than the 10-bit count holds, or a bad raster.
    """
    n = len(mv.values)
    if n > c.VALUES_COUNT_MASK or not 0 <= mv.raster <= 3:
        raise ConfigError(f"{_WHERE}: {n} values / raster {mv.raster} do not fit a 0xB0 header")
    header = (n | mv.raster << c.VALUES_RASTER_SHIFT | (c.VALUES_PARTIAL_BIT if mv.partial else 0)
              | int(mv.units) << c.VALUES_UNIT_SHIFT)
    return header.to_bytes(2, "little") + np.asarray(mv.values, dtype="<u2").tobytes() + mv.extra


def decode_values(data: bytes) -> MeasuredValues:
    """Parse a 0xB0 telegram's data (without code and status).

    Raises:
        ProtocolError: the length does not match the count (0..2 index bytes may follow the values) or
            the unit bits are reserved.
    """
    if len(data) < 2:
        raise ProtocolError(f"{_WHERE}: 0xB0 telegram of {len(data)} data bytes has no header")
    header = data[0] | data[1] << 8
    n = header & c.VALUES_COUNT_MASK
    extra = len(data) - 2 - 2 * n
    if not 0 <= extra <= 2:
        raise ProtocolError(f"{_WHERE}: 0xB0 telegram announces {n} values in {len(data)} data bytes")
    unit_bits = header >> c.VALUES_UNIT_SHIFT
    if unit_bits > 1:
        raise ProtocolError(f"{_WHERE}: 0xB0 telegram has reserved unit bits {unit_bits:02b}")
    values = np.frombuffer(data, dtype="<u2", count=n, offset=2).astype(np.uint16)
    return MeasuredValues(values, c.Units(unit_bits), bool(header & c.VALUES_PARTIAL_BIT),
                          (header >> c.VALUES_RASTER_SHIFT) & 3, bytes(data[2 + 2 * n:]))


def encode_scan(ranges: npt.ArrayLike, *, units: str | int = "mm",
                measuring_mode: int = c.MeasuringMode.M8_80_FA_FB_DAZZLE, reach: float | None = None,
                address: int = c.ADDR_REPLY_BIT, status: int = c.STATUS_OK) -> bytes:
    """One complete scan as the continuous output sends it: a 0xB0 telegram of `ranges` [m].

    Args:
        ranges: one per beam, in the LMS's order (right to left); `inf` = no echo.
        units: "mm" or "cm" (or the code).
        measuring_mode: sets the range field's width (13 bits by default: 8 m in mm, 80 m in cm).
        reach: [m] ranges beyond it are sent as 'over maximum' (default: what the field holds).
        address: the replying LMS's address (0x80 | its address).
        status: the status byte.

    Raises:
        ConfigError: bad units or mode, or more than 1023 values.
    """
    u = units_of(units)
    values = ranges_to_values(ranges, units=u, bits=range_bits(measuring_mode), reach=reach)
    return encode_telegram(c.Reply.VALUES, encode_values(MeasuredValues(values, u)), address=address,
                           status=status)


class ScanDecoder:
    """Incremental decoder of the continuous output: the ranges [m] of each complete scan.

    Only 0xB0 telegrams of complete scans come out (partial scans, other replies and malformed values are
    counted and skipped); `inf` is a special (no-distance) value. Never raises.

    Args:
        measuring_mode: the LMS's configured measuring mode (sets the range field's width).
        beams: when given, scans with another number of values are counted in `bad_scans` and skipped.
    """

    def __init__(self, measuring_mode: int = c.MeasuringMode.M8_80_FA_FB_DAZZLE, beams: int | None = None) -> None:
        self.bits = range_bits(measuring_mode)
        self.beams = beams
        self.telegrams = TelegramDecoder(replies=True)
        self.scans = 0
        self.bad_scans = 0        # 0xB0 telegrams with a good CRC but an impossible layout or count
        self.partial = 0
        self.others: list[Telegram] = []   # the latest non-0xB0 replies (the driver looks for its answers)

    @property
    def dropped_bytes(self) -> int:
        """Bytes that were not part of a good telegram."""
        return self.telegrams.dropped_bytes

    @property
    def bad_crcs(self) -> int:
        """Candidates that failed their CRC."""
        return self.telegrams.bad_crcs

    def feed(self, data: bytes | bytearray | memoryview) -> list[npt.NDArray[np.float64]]:
        """Append `data`; return the ranges [m] of each scan it completed, in order."""
        return self._scans(self.telegrams.feed(data))

    def flush(self) -> list[npt.NDArray[np.float64]]:
        """The stream ended: scans behind an incomplete candidate."""
        return self._scans(self.telegrams.flush())

    def _scans(self, telegrams: list[Telegram]) -> list[npt.NDArray[np.float64]]:
        out: list[npt.NDArray[np.float64]] = []
        for t in telegrams:
            if t.command != c.Reply.VALUES:
                self.others.append(t)
                del self.others[:-16]
                continue
            try:
                mv = decode_values(t.data)
            except ProtocolError:
                self.bad_scans += 1
                continue
            if mv.partial:
                self.partial += 1
                continue
            if self.beams is not None and len(mv.values) != self.beams:
                self.bad_scans += 1
                continue
            out.append(values_to_ranges(mv.values, units=mv.units, bits=self.bits))
            self.scans += 1
        return out


# -- configuration and status blocks -----------------------------------------------------------------------
@dataclass(frozen=True)
class LMSConfig:
    """The configuration block (0x74 reply, 0x77 data; TL Table 7-122), kept whole so that a driver
    changes only what it means to (32 bytes on older firmware, 34 on newer)."""

    raw: bytes

    @classmethod
    def default(cls) -> LMSConfig:
        """A delivery-like block: no blanking, thresholds 70/0, mode 0 (8/80 m), mm, no fields."""
        raw = bytearray(c.CONFIG_LEN)
        raw[c.CFG_STOP_THRESHOLD] = 70
        raw[c.CFG_MEASURING_MODE] = c.MeasuringMode.M8_80_FA_FB_DAZZLE
        raw[c.CFG_UNITS] = c.Units.MM
        return cls(bytes(raw))

    @classmethod
    def parse(cls, data: bytes) -> LMSConfig:
        """Raises ProtocolError unless `data` is 32 or 34 bytes."""
        if len(data) not in (c.CONFIG_LEN, c.CONFIG_LEN_OLD):
            raise ProtocolError(f"{_WHERE}: configuration block of {len(data)} bytes (expected "
                                f"{c.CONFIG_LEN_OLD} or {c.CONFIG_LEN})")
        return cls(bytes(data))

    @property
    def measuring_mode(self) -> int:
        """Block D."""
        return self.raw[c.CFG_MEASURING_MODE]

    @property
    def units(self) -> int:
        """Block E: 0 cm, 1 mm."""
        return self.raw[c.CFG_UNITS]

    def with_(self, *, measuring_mode: int, units: int) -> LMSConfig:
        """This block with blocks D and E replaced."""
        raw = bytearray(self.raw)
        raw[c.CFG_MEASURING_MODE] = measuring_mode
        raw[c.CFG_UNITS] = units
        return LMSConfig(bytes(raw))


@dataclass(frozen=True)
class LMSStatus:
    """What robotexp reads from the status telegram (0xB1; TL Table 7-33, offsets as sicktoolbox reads)."""

    software: str
    mode: int
    error: int
    measuring_mode: int
    scan_angle: int          # [deg]
    resolution: int          # [1/100 deg]
    baud: int | None         # [bit/s], None when the word is unknown
    address: int
    units: int


# -- requests (host -> LMS) --------------------------------------------------------------------------------
def req_reset() -> bytes:
    """0x10: reset; the LMS answers 0x91, then 0x90 when it is ready again (at 9600 baud)."""
    return encode_telegram(c.Cmd.RESET)


def req_mode(mode: int, data: bytes = b"") -> bytes:
    """0x20 `mode` [data]: switch the operating mode (or the baud rate)."""
    return encode_telegram(c.Cmd.SWITCH_MODE, bytes((mode,)) + data)


def req_installation(password: bytes = c.INSTALLATION_PASSWORD) -> bytes:
    """0x20 0x00 + 8-byte password: installation mode (needed for 0x77). Raises ConfigError on a bad length."""
    if len(password) != 8:
        raise ConfigError(f"{_WHERE}: the installation password has 8 bytes, got {len(password)}")
    return req_mode(c.Mode.INSTALLATION, password)


def req_continuous() -> bytes:
    """0x20 0x24: continuous output of all measured values."""
    return req_mode(c.Mode.CONTINUOUS_ALL)


def req_stop() -> bytes:
    """0x20 0x25: measured values on request only (stops the continuous output)."""
    return req_mode(c.Mode.MONITOR_REQUEST)


def req_baud(baud: int) -> bytes:
    """0x20 0x40/0x41/0x42/0x48: switch to 38400/19200/9600/500000 baud. Raises ConfigError otherwise."""
    try:
        return req_mode(c.BAUD_CODES[baud])
    except KeyError:
        raise ConfigError(f"{_WHERE}: baud must be one of {sorted(c.BAUD_CODES)}, got {baud}") from None


def req_status() -> bytes:
    """0x31: request the status."""
    return encode_telegram(c.Cmd.REQUEST_STATUS)


def req_type() -> bytes:
    """0x3A: request the type string."""
    return encode_telegram(c.Cmd.REQUEST_TYPE)


def req_variant(angle_deg: int, resolution_cdeg: int) -> bytes:
    """0x3B: switch the variant (scan angle [deg], resolution [1/100 deg]). Raises ConfigError when the
    LMS2xx has no such variant."""
    if (angle_deg, resolution_cdeg) not in c.VALID_VARIANTS:
        raise ConfigError(f"{_WHERE}: no LMS2xx variant {angle_deg} deg at {resolution_cdeg / 100:g} deg; use "
                          "180 at 1 or 0.5, or 100 at 1, 0.5 or 0.25")
    return encode_telegram(c.Cmd.SWITCH_VARIANT, angle_deg.to_bytes(2, "little")
                           + resolution_cdeg.to_bytes(2, "little"))


def req_config() -> bytes:
    """0x74: request the configuration block."""
    return encode_telegram(c.Cmd.REQUEST_CONFIG)


def req_configure(config: LMSConfig) -> bytes:
    """0x77 + block: write the configuration (installation mode only)."""
    return encode_telegram(c.Cmd.CONFIGURE, config.raw)


def req_values() -> bytes:
    """0x30 0x01: one scan of all measured values."""
    return encode_telegram(c.Cmd.REQUEST_VALUES, bytes((c.SUB_ALL_VALUES,)))


# -- replies (LMS -> host): built by the emulator, parsed by the driver -------------------------------------
def _reply(code: int, data: bytes, address: int, status: int) -> bytes:
    return encode_telegram(code, data, address=address | c.ADDR_REPLY_BIT, status=status)


def reply_mode(result: int, *, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0xA0 result (0 ok, 1 bad password, 2 fault)."""
    return _reply(c.Reply.MODE, bytes((result,)), address, status)


def reply_variant(ok: bool, angle_deg: int, resolution_cdeg: int, *, address: int = 0,
                  status: int = c.STATUS_OK) -> bytes:
    """0xBB result + the variant now in force."""
    data = bytes((c.VARIANT_OK if ok else c.VARIANT_REFUSED,)) + angle_deg.to_bytes(2, "little") \
        + resolution_cdeg.to_bytes(2, "little")
    return _reply(c.Reply.VARIANT, data, address, status)


def reply_config(config: LMSConfig, *, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0xF4 + the block."""
    return _reply(c.Reply.CONFIG, config.raw, address, status)


def reply_configured(ok: bool, config: LMSConfig, *, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0xF7 result (1 ok, 0 refused) + the block now in force."""
    return _reply(c.Reply.CONFIGURED, bytes((c.CONFIG_OK if ok else c.CONFIG_REFUSED,)) + config.raw,
                  address, status)


def reply_status(st: LMSStatus, *, status: int = c.STATUS_OK) -> bytes:
    """0xB1 + the 152-byte status block with the fields of `st` (the rest zero)."""
    d = bytearray(c.STATUS_DATA_LEN)
    d[c.ST_SOFTWARE:c.ST_SOFTWARE + 7] = st.software.encode("ascii")[:7].ljust(7)
    d[c.ST_MODE] = st.mode
    d[c.ST_ERROR] = st.error
    d[c.ST_MEASURING_MODE] = st.measuring_mode
    d[c.ST_SCAN_ANGLE:c.ST_SCAN_ANGLE + 2] = st.scan_angle.to_bytes(2, "little")
    d[c.ST_RESOLUTION:c.ST_RESOLUTION + 2] = st.resolution.to_bytes(2, "little")
    d[c.ST_BAUD:c.ST_BAUD + 2] = c.STATUS_BAUD_WORD.get(st.baud or 0, 0).to_bytes(2, "little")
    d[c.ST_ADDRESS] = st.address
    d[c.ST_UNITS] = st.units
    d[c.ST_PROM:c.ST_PROM + 7] = c.PROM_VERSION
    return _reply(c.Reply.STATUS, bytes(d), st.address, status)


def reply_type(*, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0xBA + the type string."""
    return _reply(c.Reply.TYPE, c.TYPE_STRING, address, status)


def reply_power_on(*, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0x90 + type and firmware text: the LMS is ready (after power-on or reset)."""
    return _reply(c.Reply.POWER_ON, c.POWER_ON_TEXT, address, status)


def reply_reset_ack(*, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0x91: reset acknowledged."""
    return _reply(c.Reply.RESET_ACK, b"", address, status)


def reply_not_acknowledged(*, address: int = 0, status: int = c.STATUS_OK) -> bytes:
    """0x92: the command is not allowed now (or unknown)."""
    return _reply(c.Reply.NOT_ACKNOWLEDGED, b"", address, status)


def _expect(t: Telegram, code: int, min_len: int) -> None:
    if t.command != code or len(t.data) < min_len:
        raise ProtocolError(f"{_WHERE}: expected a 0x{code:02X} reply of >= {min_len} data bytes, got "
                            f"0x{t.command:02X} with {len(t.data)}")


def parse_mode_reply(t: Telegram) -> int:
    """The result byte of an 0xA0 reply. Raises ProtocolError on another telegram."""
    _expect(t, c.Reply.MODE, 1)
    return t.data[0]


def parse_variant_reply(t: Telegram) -> tuple[bool, int, int]:
    """(switched, angle [deg], resolution [1/100 deg]) of an 0xBB reply. Raises ProtocolError otherwise."""
    _expect(t, c.Reply.VARIANT, 5)
    return (t.data[0] == c.VARIANT_OK, t.data[1] | t.data[2] << 8, t.data[3] | t.data[4] << 8)


def parse_config_reply(t: Telegram) -> tuple[bool, LMSConfig]:
    """(ok, block) of an 0xF7 reply, or (True, block) of an 0xF4. Raises ProtocolError otherwise."""
    if t.command == c.Reply.CONFIG:
        return True, LMSConfig.parse(t.data)
    _expect(t, c.Reply.CONFIGURED, 1)
    return t.data[0] == c.CONFIG_OK, LMSConfig.parse(t.data[1:])


def parse_status_reply(t: Telegram) -> LMSStatus:
    """The fields robotexp uses of an 0xB1 reply. Raises ProtocolError on another telegram or a short one."""
    _expect(t, c.Reply.STATUS, c.ST_PROM)
    d = t.data
    word = d[c.ST_BAUD] | d[c.ST_BAUD + 1] << 8
    baud = {v: k for k, v in c.STATUS_BAUD_WORD.items()}.get(word)
    return LMSStatus(software=d[c.ST_SOFTWARE:c.ST_SOFTWARE + 7].decode("ascii", "replace"), mode=d[c.ST_MODE],
                     error=d[c.ST_ERROR], measuring_mode=d[c.ST_MEASURING_MODE],
                     scan_angle=d[c.ST_SCAN_ANGLE] | d[c.ST_SCAN_ANGLE + 1] << 8,
                     resolution=d[c.ST_RESOLUTION] | d[c.ST_RESOLUTION + 1] << 8, baud=baud,
                     address=d[c.ST_ADDRESS], units=d[c.ST_UNITS])
