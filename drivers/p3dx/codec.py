"""Pure codec of the ARIA / Pioneer robot protocol: bytes in, frozen dataclasses out, and back.

No I/O and no clock. Framing, checksum and layouts follow `shared/protocols/aria-sip.md` (section
numbers "§n" below). Values stay in wire units (mm, degrees, raw SIP units); `robot.py` converts.

Both directions are covered: a client (our driver) encodes commands with `encode_command` and the
`cmd_*` helpers and decodes the robot's packets with `PacketDecoder`; a robot-side emulator encodes
packets with `encode_packet` / `encode_laser_scan` and decodes commands with `CommandDecoder`.
Encoders raise `ConfigError` for values the protocol cannot carry; decoders of one payload raise
`ProtocolError`; the stream decoders never raise and count what they drop.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, fields
from operator import index

from robotexp import ConfigError, ProtocolError

from . import constants as c

__all__ = [
    "Command", "CommandDecoder", "ConfigPacket", "EncoderPacket", "Packet", "PacketDecoder",
    "SimDevice", "SimInfo", "SimLaserPacket", "SimMapChanged", "SimStat", "StandardSip", "SyncReply",
    "UnknownPacket", "checksum", "cmd_battery_info", "cmd_close", "cmd_config", "cmd_dhead",
    "cmd_enable", "cmd_estop", "cmd_head", "cmd_move", "cmd_open", "cmd_pulse", "cmd_rvel", "cmd_seta",
    "cmd_setra", "cmd_setrv", "cmd_setv", "cmd_sim_laser", "cmd_sim_lrf", "cmd_sim_reset",
    "cmd_sim_set_pose", "cmd_sim_stat", "cmd_sonar", "cmd_stop", "cmd_sync0", "cmd_sync1", "cmd_sync2",
    "cmd_vel", "cmd_vel2", "decode_command", "decode_packet", "encode_command", "encode_laser_scan",
    "encode_packet", "frame", "heading_to_raw", "mobilesim_config", "pack_2bytes", "position_to_raw",
    "unpack_2bytes", "unwrap_position_delta",
]

_WHERE = "p3dx codec"


# --- §2 framing ------------------------------------------------------------------------------------
def checksum(body: bytes | bytearray | memoryview) -> int:
    """Checksum of §2.1 over ID and DATA: sum of big-endian byte pairs mod 2**16, odd byte XORed.

    Args:
        body: the bytes from ID through the last DATA byte (header and COUNT excluded).

    Returns:
        The 16-bit checksum, sent high byte first.
    """
    n = len(body)
    total: int = sum(struct.unpack_from(f">{n >> 1}H", body)) & 0xFFFF
    return total ^ body[n - 1] if n & 1 else total


def frame(packet_id: int, data: bytes = b"") -> bytes:
    """Frame one packet: header, COUNT, ID, DATA and the big-endian checksum.

    Args:
        packet_id: command number (client to robot) or packet type (robot to client), 0..255.
        data: the DATA bytes.

    Returns:
        The packet bytes.

    Raises:
        ConfigError: the ID is not a byte or COUNT would exceed `MAX_COUNT` (200).
    """
    if not 0 <= packet_id <= 255:
        raise ConfigError(f"{_WHERE}: packet ID must be 0..255, got {packet_id}")
    count = len(data) + c.COUNT_OVERHEAD
    if count > c.MAX_COUNT:
        raise ConfigError(f"{_WHERE}: packet 0x{packet_id:02X} needs COUNT {count} > {c.MAX_COUNT} "
                          f"(DATA at most {c.MAX_DATA} bytes); send less per packet")
    body = bytes((packet_id,)) + bytes(data)
    return c.HEADER + bytes((count,)) + body + checksum(body).to_bytes(2, "big")


def _pack(st: struct.Struct | str, *values: int, what: str) -> bytes:
    try:
        return struct.pack(st, *values) if isinstance(st, str) else st.pack(*values)
    except struct.error as exc:
        raise ConfigError(f"{_WHERE}: {what} {values} do not fit the wire format: {exc}") from exc


def _cstr(text: str, what: str) -> bytes:
    try:
        raw = text.encode("latin-1")
    except UnicodeEncodeError as exc:
        raise ConfigError(f"{_WHERE}: {what} {text!r} is not latin-1 text") from exc
    if b"\0" in raw:
        raise ConfigError(f"{_WHERE}: {what} {text!r} contains a NUL byte")
    return raw + b"\0"


class _Reader:
    """Cursor over one payload; every read raises `ProtocolError` when bytes are missing."""

    def __init__(self, data: bytes, what: str) -> None:
        self.data, self.pos, self.what = data, 0, what

    def left(self) -> int:
        return len(self.data) - self.pos

    def unpack(self, st: struct.Struct) -> tuple[int, ...]:
        if self.left() < st.size:
            raise ProtocolError(f"{_WHERE}: {self.what} payload of {len(self.data)} bytes ends at byte "
                                f"{self.pos}, needs {st.size} more; the peer sent a truncated packet")
        out = st.unpack_from(self.data, self.pos)
        self.pos += st.size
        return out

    def cstr(self) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise ProtocolError(f"{_WHERE}: {self.what} string at byte {self.pos} has no NUL terminator")
        text = self.data[self.pos:end].decode("latin-1")
        self.pos = end + 1
        return text

    def rest(self) -> bytes:
        out = self.data[self.pos:]
        self.pos = len(self.data)
        return out


_U8, _U16, _I16, _U32 = (struct.Struct(f) for f in ("<B", "<H", "<h", "<I"))


# --- §2.2 / §4 commands (client to robot) ---------------------------------------------------------------
def _int_arg(value: int, what: str) -> bytes:
    v = index(value)
    if not c.INT_ARG_MIN <= v <= c.INT_ARG_MAX:
        raise ConfigError(f"{_WHERE}: {what} argument must be {c.INT_ARG_MIN}..{c.INT_ARG_MAX}, got {v}")
    # §2.2: NINTARG carries the absolute value; ARIA sends -32768 as NINT 0x8000.
    return bytes((c.ARG_INT if v >= 0 else c.ARG_NINT,)) + abs(v).to_bytes(2, "little")


def encode_command(cmd: int, arg: int | str | bytes | tuple[int, int, int] | None = None,
                   extra: bytes = b"") -> bytes:
    """Encode one client command (§2.2).

    Args:
        cmd: command number 0..255 (`constants.CMD_*`).
        arg: None (no argument); an int (INTARG/NINTARG, -32768..32767); a str (STRARG: length byte,
            latin-1 characters and a NUL as ARIA's comStr sends); bytes (raw DATA, as comDataN);
            or a tuple (x, y, th): int32 mm, mm, deg for SIM_SET_POSE after its ignored 0 byte,
            or int16 x, y, th for SETO after an INTARG type byte (MobileSim's extended SETO).
        extra: bytes appended after the argument (the laser index of commands 230..233, ...).

    Returns:
        The packet bytes.

    Raises:
        ConfigError: an argument out of range, a string longer than 199 characters, or a packet
            longer than the protocol allows.
    """
    what = f"command {cmd}"
    if arg is None:
        data = b""
    elif isinstance(arg, str):
        raw = _cstr(arg, f"{what} string")
        if len(raw) - 1 > c.MAX_STR_ARG:
            raise ConfigError(f"{_WHERE}: {what} string has {len(raw) - 1} characters, at most "
                              f"{c.MAX_STR_ARG}; split it")
        data = bytes((c.ARG_STR, len(raw) - 1)) + raw
    elif isinstance(arg, (bytes, bytearray, memoryview)):
        data = bytes(arg)
    elif isinstance(arg, tuple):
        if cmd == c.CMD_SIM_SET_POSE:
            data = b"\0" + _pack("<iii", *arg, what="SIM_SET_POSE x, y, th")
        elif cmd == c.CMD_SETO:
            data = bytes((c.ARG_INT,)) + _pack("<hhh", *arg, what="SETO x, y, th")
        else:
            raise ConfigError(f"{_WHERE}: a (x, y, th) argument is only for SIM_SET_POSE (224) or "
                              f"SETO (7), got command {cmd}")
    else:
        data = _int_arg(arg, what)
    return frame(cmd, data + bytes(extra))


@dataclass(frozen=True, slots=True)
class Command:
    """One decoded client command.

    Attributes:
        cmd: command number (`constants.CMD_*`).
        arg: None, a signed int (INTARG/NINTARG), a str (STRARG, latin-1), the (x, y, th) of
            SIM_SET_POSE (int32 mm, mm, deg) or extended SETO (int16), or the raw DATA bytes when
            they are none of these (SIM_CTRL map names, malformed arguments, ...).
        extra: bytes after the argument (laser index of 230..233, SIM_CTRL op data, ...).
    """

    cmd: int
    arg: int | str | bytes | tuple[int, int, int] | None = None
    extra: bytes = b""


def decode_command(cmd: int, data: bytes) -> Command:
    """Decode the DATA of a client command; never raises (unparseable DATA stays bytes in `arg`).

    Args:
        cmd: command number.
        data: DATA bytes after the command number.

    Returns:
        The command with its argument decoded as in §2.2 (MobileSim reads ints the same way).
    """
    data = bytes(data)
    if not data:
        return Command(cmd)
    if cmd == c.CMD_SIM_SET_POSE and len(data) == 13:
        x, y, th = struct.unpack_from("<iii", data, 1)
        return Command(cmd, (x, y, th))
    kind = data[0]
    if cmd == c.CMD_SETO and len(data) == 7 and kind in (c.ARG_INT, c.ARG_NINT):
        x, y, th = struct.unpack_from("<hhh", data, 1)
        return Command(cmd, (x, y, th))
    if kind in (c.ARG_INT, c.ARG_NINT) and len(data) >= 3:
        value = data[1] | data[2] << 8
        return Command(cmd, -value if kind == c.ARG_NINT else value, data[3:])
    if kind == c.ARG_STR and len(data) >= 2 and len(data) >= 2 + data[1]:
        end = 2 + data[1]
        rest = data[end:]
        if rest[:1] == b"\0":            # comStr's NUL (comStrN sends none)
            rest = rest[1:]
        return Command(cmd, data[2:end].decode("latin-1"), rest)
    return Command(cmd, data)


def pack_2bytes(high: int, low: int) -> int:
    """The int argument of a "2bytes" command (§2.2): `(high << 8) | low` as a signed 16-bit value.

    Args:
        high: signed byte -128..127 (the left wheel of VEL2).
        low: signed byte -128..127 (the right wheel of VEL2).

    Raises:
        ConfigError: a byte out of range.
    """
    if not (-128 <= high <= 127 and -128 <= low <= 127):
        raise ConfigError(f"{_WHERE}: 2bytes argument needs two signed bytes, got ({high}, {low})")
    value = (high & 0xFF) << 8 | (low & 0xFF)
    return value - 0x10000 if value >= 0x8000 else value


def unpack_2bytes(value: int) -> tuple[int, int]:
    """The (high, low) signed bytes of a decoded "2bytes" int argument (§2.2)."""
    high, low = (value >> 8) & 0xFF, value & 0xFF
    return (high - 256 if high > 127 else high), (low - 256 if low > 127 else low)


def cmd_sync0() -> bytes:
    """SYNC0 (0), first handshake packet: `FA FB 03 00 00 00`."""
    return frame(c.CMD_SYNC0)


def cmd_sync1() -> bytes:
    """SYNC1 (1), second handshake packet."""
    return frame(c.CMD_SYNC1)


def cmd_sync2() -> bytes:
    """SYNC2 (2), third handshake packet; the robot answers with name, class and subclass."""
    return frame(c.CMD_SYNC2)


def cmd_pulse() -> bytes:
    """PULSE (0), the keep-alive that resets the watchdog (§7)."""
    return frame(c.CMD_PULSE)


def cmd_open() -> bytes:
    """OPEN with int 1, as ARIA sends it: the robot starts sending SIPs."""
    return encode_command(c.CMD_OPEN, 1)


def cmd_close() -> bytes:
    """CLOSE with int 1, as ARIA sends it: the robot stops and ends the session."""
    return encode_command(c.CMD_CLOSE, 1)


def cmd_enable(on: bool) -> bytes:
    """ENABLE 1 / 0: enable or disable the motors."""
    return encode_command(c.CMD_ENABLE, int(on))


def cmd_vel(speed_mm_s: int) -> bytes:
    """VEL: translational velocity [mm/s], signed."""
    return encode_command(c.CMD_VEL, speed_mm_s)


def cmd_rvel(rate_deg_s: int) -> bytes:
    """RVEL: rotational velocity [deg/s], positive counter-clockwise."""
    return encode_command(c.CMD_RVEL, rate_deg_s)


def cmd_vel2(left_mm_s: float, right_mm_s: float, divisor: int = c.VEL2_DIVISOR) -> bytes:
    """VEL2: wheel velocities [mm/s], each rounded to units of `divisor` and clamped to -128..127.

    ARIA clamps to +128, which the robot reads as -128 (full reverse, aria-sip.md Notes §3); this
    helper clamps to +127.
    """
    left, right = (max(-128, min(127, round(v / divisor))) for v in (left_mm_s, right_mm_s))
    return encode_command(c.CMD_VEL2, pack_2bytes(left, right))


def cmd_head(heading_deg: int) -> bytes:
    """HEAD: turn to an absolute heading of the robot's odometry frame [deg]."""
    return encode_command(c.CMD_HEAD, heading_deg)


def cmd_dhead(delta_deg: int) -> bytes:
    """DHEAD: turn relative to the current heading [deg]."""
    return encode_command(c.CMD_DHEAD, delta_deg)


def cmd_move(distance_mm: int) -> bytes:
    """MOVE: translate a distance [mm]."""
    return encode_command(c.CMD_MOVE, distance_mm)


def cmd_setv(speed_mm_s: int) -> bytes:
    """SETV: maximum translational velocity [mm/s]."""
    return encode_command(c.CMD_SETV, speed_mm_s)


def cmd_setrv(rate_deg_s: int) -> bytes:
    """SETRV: maximum rotational velocity [deg/s]."""
    return encode_command(c.CMD_SETRV, rate_deg_s)


def cmd_seta(accel_mm_s2: int) -> bytes:
    """SETA: translational acceleration (positive) or deceleration (negative) [mm/s^2]."""
    return encode_command(c.CMD_SETA, accel_mm_s2)


def cmd_setra(accel_deg_s2: int) -> bytes:
    """SETRA: rotational acceleration (positive) or deceleration (negative) [deg/s^2]."""
    return encode_command(c.CMD_SETRA, accel_deg_s2)


def cmd_stop() -> bytes:
    """STOP without argument."""
    return frame(c.CMD_STOP)


def cmd_estop() -> bytes:
    """ESTOP: emergency stop, overrides the deceleration."""
    return frame(c.CMD_ESTOP)


def cmd_sonar(on: bool) -> bytes:
    """SONAR 1 / 0: enable or disable the sonar."""
    return encode_command(c.CMD_SONAR, int(on))


def cmd_config() -> bytes:
    """CONFIG 1: request one CONFIG packet (0x20)."""
    return encode_command(c.CMD_CONFIG, 1)


def cmd_battery_info(mode: int) -> bytes:
    """BATTERYINFO: 0 stop, 1 one packet, 2 continuous (ARIA sends 1 after CONFIG)."""
    return encode_command(c.CMD_BATTERYINFO, mode)


def cmd_sim_set_pose(x_mm: int, y_mm: int, th_deg: int) -> bytes:
    """SIM_SET_POSE (224): move the simulated robot to a true pose; odometry is unchanged."""
    return encode_command(c.CMD_SIM_SET_POSE, (x_mm, y_mm, th_deg))


def cmd_sim_reset() -> bytes:
    """SIM_RESET (225): back to the start pose, odometry reset to 0, 0, 0."""
    return frame(c.CMD_SIM_RESET)


def cmd_sim_stat(mode: int) -> bytes:
    """SIM_STAT (237): 0 stop, 1 one SIMSTAT packet, 2 one before every SIP."""
    return encode_command(c.CMD_SIM_STAT, mode)


def cmd_sim_laser(start_deg: int = c.LASER_DEFAULT_START_DEG, end_deg: int = c.LASER_DEFAULT_END_DEG,
                  res_cdeg: int = c.LASER_DEFAULT_RES_CDEG, mode: int = c.LRF_EXTENDED) -> bytes:
    """The old-numbered laser setup ARIA's ArSimulatedLaser sends (§8.1): 36, 37, 38, then 35.

    Args:
        start_deg: first reading angle [deg] from the centre.
        end_deg: last reading angle [deg]; must be -start_deg for MobileSim.
        res_cdeg: angle between readings [1/100 deg].
        mode: 0 off, 1 packets 0x60, 2 extended packets 0x61.

    Returns:
        The four packets, concatenated.
    """
    return (encode_command(c.CMD_OLD_SIM_LRF_SET_FOV_START, start_deg)
            + encode_command(c.CMD_OLD_SIM_LRF_SET_FOV_END, end_deg)
            + encode_command(c.CMD_OLD_SIM_LRF_SET_RES, res_cdeg)
            + encode_command(c.CMD_OLD_SIM_LRF_ENABLE, mode))


def cmd_sim_lrf(cmd: int, value: int, laser_index: int = 0) -> bytes:
    """One of the new laser commands 230..233 (§4.1): an int, then the laser index byte."""
    if not c.CMD_SIM_LRF_ENABLE <= cmd <= c.CMD_SIM_LRF_SET_RES:
        raise ConfigError(f"{_WHERE}: cmd_sim_lrf takes commands 230..233, got {cmd}")
    return encode_command(cmd, value, _pack(_U8, laser_index, what="laser index"))


# --- robot-to-client packets (§3, §5, §6, §8) -------------------------------------------------------
@dataclass(frozen=True, slots=True)
class SyncReply:
    """Reply to SYNC0/1/2 (§3); only the SYNC2 reply (seq 2) carries the three strings.

    Attributes:
        seq: 0, 1 or 2.
        name: robot name ("MobileSim" for the simulator).
        robot_type: robot class ("Pioneer").
        robot_subtype: robot subclass ("p3dx"); ARIA lowercases it to pick `<subtype>.p`.
    """

    seq: int
    name: str = ""
    robot_type: str = ""
    robot_subtype: str = ""


@dataclass(frozen=True, slots=True)
class StandardSip:
    """Standard server information packet, type 0x32 (stopped) / 0x33 (moving), §5.

    Fields 1..12 are always present; the optional ones (13 onward) are None when the packet ends
    before them. All values are raw wire units.

    Attributes:
        moving: True for type 0x33.
        xpos: XPOS as sent (uint16); ARIA uses `xpos & 0x7FFF` [DistConvFactor mm].
        ypos: YPOS as sent (uint16).
        thpos: heading [AngleConvFactor rad], int16.
        left_vel: left wheel velocity [VelConvFactor mm/s], int16.
        right_vel: right wheel velocity, int16.
        battery_dv: battery voltage [0.1 V], uint8.
        stall_bumpers: stall and bumper bits, uint16 (see the properties).
        control: server heading setpoint [angle units], int16.
        flags: FLAGS word, uint16 (bit0 motors, bits 1..4 sonar arrays, bit5 E-stop).
        compass: compass heading [2 deg], uint8.
        sonar: (sonar number, range [RangeConvFactor mm]) pairs in this SIP.
        grip_state, analog_port, analog, digin, digout: the uint8 group of fields 13..17.
        battery_x10: battery voltage [0.1 V], uint16.
        charge_state: `constants.CHARGE_STATE_*`, uint8.
        rot_vel_x10: rotational velocity [0.1 deg/s], int16.
        fault_flags: uint16.
        lat_vel: lateral velocity [mm/s], int16.
        temperature: [deg C], int8 (-127 = none in MobileSim).
        state_of_charge: [%], uint8.
        uc_time_us: microcontroller time [us], uint32.
        flags3: uint32.
        extra: bytes after the last field read (a truncated field, or data after FLAGS3).
    """

    moving: bool = False
    xpos: int = 0
    ypos: int = 0
    thpos: int = 0
    left_vel: int = 0
    right_vel: int = 0
    battery_dv: int = 0
    stall_bumpers: int = 0
    control: int = 0
    flags: int = 0
    compass: int = 0
    sonar: tuple[tuple[int, int], ...] = ()
    grip_state: int | None = None
    analog_port: int | None = None
    analog: int | None = None
    digin: int | None = None
    digout: int | None = None
    battery_x10: int | None = None
    charge_state: int | None = None
    rot_vel_x10: int | None = None
    fault_flags: int | None = None
    lat_vel: int | None = None
    temperature: int | None = None
    state_of_charge: int | None = None
    uc_time_us: int | None = None
    flags3: int | None = None
    extra: bytes = b""

    @property
    def left_stalled(self) -> bool:
        """Left motor stalled (bit 0)."""
        return bool(self.stall_bumpers & c.STALL_LEFT)

    @property
    def right_stalled(self) -> bool:
        """Right motor stalled (bit 8)."""
        return bool(self.stall_bumpers & c.STALL_RIGHT)

    @property
    def rear_bumpers(self) -> int:
        """Rear bumper segments, bit i = segment i (bits 1..7 of the word)."""
        return (self.stall_bumpers & c.REAR_BUMPERS_MASK) >> c.REAR_BUMPERS_SHIFT

    @property
    def front_bumpers(self) -> int:
        """Front bumper segments, bit i = segment i (bits 9..15 of the word)."""
        return (self.stall_bumpers & c.FRONT_BUMPERS_MASK) >> c.FRONT_BUMPERS_SHIFT

    @property
    def motors_enabled(self) -> bool:
        """FLAGS bit 0."""
        return bool(self.flags & c.FLAG_MOTORS_ENABLED)

    @property
    def sonar_arrays(self) -> int:
        """FLAGS bits 1..4 as a 4-bit mask of enabled sonar arrays."""
        return (self.flags & c.FLAG_SONARS_MASK) >> 1

    @property
    def estop(self) -> bool:
        """FLAGS bit 5: E-stop pressed (or not relieved)."""
        return bool(self.flags & c.FLAG_ESTOP)

    @property
    def compass_deg(self) -> int:
        """Compass heading [deg]."""
        return self.compass * c.COMPASS_SCALE_DEG


_SIP_FIXED = struct.Struct("<HHhhhBHhHBB")      # fields 1..11 (§5)
_SIP_FIXED_NAMES = ("xpos", "ypos", "thpos", "left_vel", "right_vel", "battery_dv", "stall_bumpers",
                    "control", "flags", "compass")
# §5: ARIA reads each group only if bytes remain: 13..17 together, then one field at a time.
_SIP_OPTIONAL: tuple[tuple[tuple[str, ...], struct.Struct], ...] = (
    (("grip_state", "analog_port", "analog", "digin", "digout"), struct.Struct("<BBBBB")),
    (("battery_x10",), _U16), (("charge_state",), _U8), (("rot_vel_x10",), _I16),
    (("fault_flags",), _U16), (("lat_vel",), _I16), (("temperature",), struct.Struct("<b")),
    (("state_of_charge",), _U8), (("uc_time_us",), _U32), (("flags3",), _U32),
)


def _decode_sip(ptype: int, data: bytes) -> StandardSip:
    if len(data) < _SIP_FIXED.size:
        raise ProtocolError(f"{_WHERE}: SIP (0x{ptype:02X}) of {len(data)} data bytes is shorter than "
                            f"its {_SIP_FIXED.size} fixed bytes; the robot sent a truncated SIP")
    values = _SIP_FIXED.unpack_from(data)
    kw: dict[str, object] = dict(zip(_SIP_FIXED_NAMES, values[:-1], strict=True))
    n, pos = values[-1], _SIP_FIXED.size
    if pos + 3 * n > len(data):
        raise ProtocolError(f"{_WHERE}: SIP announces {n} sonar readings ({3 * n} bytes) but only "
                            f"{len(data) - pos} bytes follow; the robot sent a truncated SIP")
    kw["sonar"] = tuple((data[o], data[o + 1] | data[o + 2] << 8) for o in range(pos, pos + 3 * n, 3))
    pos += 3 * n
    for names, st in _SIP_OPTIONAL:
        if len(data) - pos < st.size:
            break
        kw.update(zip(names, st.unpack_from(data, pos), strict=True))
        pos += st.size
    return StandardSip(moving=ptype == c.PTYPE_SIP_MOVING, extra=data[pos:], **kw)  # type: ignore[arg-type]


def _encode_sip(sip: StandardSip) -> tuple[int, bytes]:
    if len(sip.sonar) > 255:
        raise ConfigError(f"{_WHERE}: a SIP carries at most 255 sonar readings, got {len(sip.sonar)}")
    out = [_pack(_SIP_FIXED, *(getattr(sip, k) for k in _SIP_FIXED_NAMES), len(sip.sonar),
                 what="SIP fields 1..11")]
    out += [_pack("<BH", num, rng, what="sonar reading") for num, rng in sip.sonar]
    missing: int | None = None           # size of the first absent optional group
    for names, st in _SIP_OPTIONAL:
        vals = [getattr(sip, k) for k in names]
        if missing is None and all(v is not None for v in vals):
            out.append(_pack(st, *vals, what=f"SIP {'/'.join(names)}"))
        elif missing is None:
            missing = st.size
        if missing is not None and any(v is not None for v in vals):
            raise ConfigError(f"{_WHERE}: SIP optional fields must be a prefix of §5's order; "
                              f"{'/'.join(names)} is set after a field left as None")
    if missing is not None and len(sip.extra) >= missing:
        raise ConfigError(f"{_WHERE}: SIP extra of {len(sip.extra)} bytes would read back as the next "
                          "optional field; set that field instead")
    return (c.PTYPE_SIP_MOVING if sip.moving else c.PTYPE_SIP_STOPPED), b"".join(out) + sip.extra


@dataclass(frozen=True, slots=True)
class ConfigPacket:
    """CONFIG packet, type 0x20 (§6), in ARIA's reading order. Missing trailing fields read as 0/"".

    Units: velocities [mm/s] and [deg/s], accelerations [mm/s^2] and [deg/s^2], voltages [0.1 V],
    `watchdog_ms` and `sip_cycle_ms` [ms]. `present` is how many fields the packet carried (in
    order); `extra` holds bytes after them.
    """

    robot_type: str = ""
    robot_subtype: str = ""
    serial_number: str = ""
    reserved1: int = 0
    rot_vel_top: int = 0
    trans_vel_top: int = 0
    rot_acc_top: int = 0
    trans_acc_top: int = 0
    pwm_max: int = 0
    name: str = ""
    sip_cycle_ms: int = 0
    host_baud: int = 0
    aux1_baud: int = 0
    has_gripper: int = 0
    front_sonar: int = 0
    rear_sonar: int = 0
    low_battery_dv: int = 0
    rev_count: int = 0
    watchdog_ms: int = 0
    reserved2: int = 0
    stall_pwm: int = 0
    stall_count: int = 0
    joy_vel: int = 0
    joy_rot_vel: int = 0
    rot_vel_max: int = 0
    trans_vel_max: int = 0
    rot_accel: int = 0
    rot_decel: int = 0
    rot_kp: int = 0
    rot_kv: int = 0
    rot_ki: int = 0
    trans_accel: int = 0
    trans_decel: int = 0
    trans_kp: int = 0
    trans_kv: int = 0
    trans_ki: int = 0
    front_bumpers: int = 0
    rear_bumpers: int = 0
    charger_type: int = 0
    sonar_cycle: int = 0
    autobaud: int = 0
    gyro_type: int = 0
    drift_factor: int = 0
    aux2_baud: int = 0
    aux3_baud: int = 0
    ticks_mm: int = 0
    shutdown_volts: int = 0
    firmware_version: str = ""
    gyro_cw: int = 0
    gyro_ccw: int = 0
    kinematics_delay: int = 0
    lat_vel_top: int = 0
    lat_acc_top: int = 0
    lat_vel_max: int = 0
    lat_accel: int = 0
    lat_decel: int = 0
    charge_threshold: int = 0
    pdb_port: int = 0
    gyro_rate_limit: int = 0
    high_temp_shutdown: int = 0
    power_bits: int = 0
    battery_type: int = 0
    soc_low: int = 0
    soc_shutdown: int = 0
    bootloader_version: str = ""
    config_flags: int = 0
    gyro_fw_version: int = 0
    present: int = 67
    extra: bytes = b""


# Wire format of each ConfigPacket field, in order ("s" = NUL-terminated string).
_CONFIG_FORMATS = "sssBHHHHHsBBBHHBHHHBHHHHHHHHHHHHHHHHBBBBBBhBBHHsHHBHHHHHHBHbHBHHsIh"
_CONFIG_FIELDS = tuple((f.name, None if fmt == "s" else struct.Struct("<" + fmt))
                       for f, fmt in zip(fields(ConfigPacket)[:-2], _CONFIG_FORMATS, strict=True))


def _decode_config(data: bytes) -> ConfigPacket:
    r, kw = _Reader(data, "CONFIG"), {}
    for name, st in _CONFIG_FIELDS:
        if st is None and data.find(b"\0", r.pos) < 0 or st is not None and r.left() < st.size:
            break                         # §6: missing trailing fields read as 0
        kw[name] = r.cstr() if st is None else r.unpack(st)[0]
    return ConfigPacket(present=len(kw), extra=r.rest(), **kw)  # type: ignore[arg-type]


def _encode_config(cfg: ConfigPacket) -> tuple[int, bytes]:
    if not 0 <= cfg.present <= len(_CONFIG_FIELDS):
        raise ConfigError(f"{_WHERE}: CONFIG present must be 0..{len(_CONFIG_FIELDS)}, got {cfg.present}")
    out = [_cstr(getattr(cfg, name), f"CONFIG {name}") if st is None
           else _pack(st, getattr(cfg, name), what=f"CONFIG {name}")
           for name, st in _CONFIG_FIELDS[:cfg.present]]
    if cfg.present < len(_CONFIG_FIELDS) and cfg.extra:
        st = _CONFIG_FIELDS[cfg.present][1]
        if b"\0" in cfg.extra if st is None else len(cfg.extra) >= st.size:
            raise ConfigError(f"{_WHERE}: CONFIG extra would read back as field "
                              f"{_CONFIG_FIELDS[cfg.present][0]}; raise `present` instead")
    return c.PTYPE_CONFIG, b"".join(out) + cfg.extra


def mobilesim_config(robot_type: str = c.DEFAULT_CLASS,
                     robot_subtype: str = c.DEFAULT_SUBCLASS) -> ConfigPacket:
    """The CONFIG packet MobileSim sends (§6 bracketed values, §9 session defaults)."""
    top = c.SIM_CONFIG_TOP
    return ConfigPacket(
        robot_type=robot_type, robot_subtype=robot_subtype, serial_number=c.SIM_SERIAL,
        rot_vel_top=top, trans_vel_top=top, rot_acc_top=top, trans_acc_top=top, pwm_max=c.SIM_PWM_MAX,
        name=c.SIM_NAME, sip_cycle_ms=round(c.SIP_PERIOD_S * 1000), watchdog_ms=round(c.WATCHDOG_S * 1000),
        rot_vel_max=c.SIM_ROT_VEL_MAX_DEG_S, trans_vel_max=c.SIM_TRANS_VEL_MAX_MM_S,
        rot_accel=c.SIM_ROT_ACCEL_DEG_S2, rot_decel=c.SIM_ROT_ACCEL_DEG_S2,
        trans_accel=c.SIM_TRANS_ACCEL_MM_S2, trans_decel=c.SIM_TRANS_ACCEL_MM_S2,
        autobaud=c.AUTOBAUD_ENABLED, firmware_version=c.SIM_FIRMWARE)


@dataclass(frozen=True, slots=True)
class SimLaserPacket:
    """One simulated-laser packet of MobileSim (§8.2): 0x60 basic or 0x61 extended.

    Attributes:
        extended: True for 0x61.
        total: readings in the full scan.
        first: index of the first reading in this packet (index 0 is the rightmost beam).
        ranges: ranges [mm], uint16 each.
        reflectance: 0x61 only, one uint8 per reading (the 2 reserved bytes per reading are
            not kept; they are written as 0).
        pose: 0x60 only, odometry (x [mm], y [mm], th [deg]) as int16; ARIA ignores it.
        laser_index: 0x61 only, uint8.
        flags: 0x61 only, uint8 (bit 0 = robot moved).
        extra: bytes after the packet's fields.
    """

    extended: bool
    total: int
    first: int
    ranges: tuple[int, ...]
    reflectance: tuple[int, ...] = ()
    pose: tuple[int, int, int] | None = None
    laser_index: int = 0
    flags: int = 0
    extra: bytes = b""

    @property
    def complete(self) -> bool:
        """True when this packet ends the scan (`first + n >= total`)."""
        return self.first + len(self.ranges) >= self.total


_LASER_HEAD = struct.Struct("<HHB")
_POSE16 = struct.Struct("<hhh")


def _decode_laser(data: bytes, extended: bool) -> SimLaserPacket:
    r = _Reader(data, "laser 0x61" if extended else "laser 0x60")
    pose = None if extended else r.unpack(_POSE16)
    total, first, n = r.unpack(_LASER_HEAD)
    if not extended:
        ranges = r.unpack(struct.Struct(f"<{n}H"))
        return SimLaserPacket(False, total, first, ranges, pose=pose, extra=r.rest())  # type: ignore[arg-type]
    vals = r.unpack(struct.Struct("<" + "HBxx" * n))
    index_, flags = r.unpack(struct.Struct("<BB"))
    return SimLaserPacket(True, total, first, vals[0::2], vals[1::2], None, index_, flags, r.rest())


def _encode_laser(p: SimLaserPacket) -> tuple[int, bytes]:
    n = len(p.ranges)
    head = _pack(_LASER_HEAD, p.total, p.first, n, what="laser total, first, n")
    if not p.extended:
        if p.pose is None or p.reflectance or p.laser_index or p.flags:
            raise ConfigError(f"{_WHERE}: a basic 0x60 laser packet needs `pose` and has no reflectance, "
                              "laser_index or flags")
        return c.PTYPE_SIM_LASER, (_pack(_POSE16, *p.pose, what="laser pose") + head
                                   + _pack(f"<{n}H", *p.ranges, what="laser ranges") + p.extra)
    if p.pose is not None or len(p.reflectance) != n:
        raise ConfigError(f"{_WHERE}: an extended 0x61 laser packet has no pose and one reflectance "
                          f"per range; got {len(p.reflectance)} for {n} ranges")
    body = [v for pair in zip(p.ranges, p.reflectance, strict=True) for v in pair]
    return c.PTYPE_SIM_LASER_EXT, (head + _pack("<" + "HBxx" * n, *body, what="laser readings")
                                   + _pack("<BB", p.laser_index, p.flags, what="laser index, flags")
                                   + p.extra)


def encode_laser_scan(ranges_mm: Sequence[int], *, extended: bool = True,
                      reflectance: Sequence[int] | None = None, pose: tuple[int, int, int] = (0, 0, 0),
                      laser_index: int = 0, flags: int = 0) -> list[bytes]:
    """Split a full scan into laser packets of at most 32 readings (§8.2), as MobileSim sends them.

    Args:
        ranges_mm: the whole scan [mm], index 0 = rightmost beam.
        extended: 0x61 packets (ARIA's choice) or 0x60.
        reflectance: per-reading uint8 for 0x61 (zeros when None).
        pose: odometry (x [mm], y [mm], th [deg]) written into 0x60 packets.
        laser_index: 0x61 laser index.
        flags: 0x61 flags, written into every packet of the scan.

    Returns:
        The packets' bytes, in order.

    Raises:
        ConfigError: a value out of range for its field.
    """
    total, refl = len(ranges_mm), list(reflectance) if reflectance is not None else [0] * len(ranges_mm)
    if len(refl) != total:
        raise ConfigError(f"{_WHERE}: {len(refl)} reflectance values for {total} ranges")
    out = []
    for first in range(0, total, c.LASER_MAX_PER_PACKET):
        sl = slice(first, first + c.LASER_MAX_PER_PACKET)
        pkt = (SimLaserPacket(True, total, first, tuple(ranges_mm[sl]), tuple(refl[sl]), None,
                              laser_index, flags) if extended
               else SimLaserPacket(False, total, first, tuple(ranges_mm[sl]), pose=pose))
        out.append(encode_packet(pkt))
    return out


@dataclass(frozen=True, slots=True)
class SimStat:
    """SIMSTAT, type 0x62 (§8.3): the simulator's ground truth.

    Attributes:
        flags: bit0 have map, bit1 georeferenced, bit2 odometry-error data present.
        sim_interval_ms, real_interval_ms, last_interval_ms: simulation timing [ms].
        true_x_mm, true_y_mm, true_z_mm: true position [mm].
        true_th_deg: true heading [deg].
        latitude_e7, longitude_e7: [deg x 1e7]; altitude_cm: [cm]; dop_x100: GPS DOP x 100
            (0 in a bad-GPS sector, -1 without georeference).
        odom_error_x_e7, odom_error_y_e7, odom_error_th_e7: odometry error x 1e7.
        extra: bytes after these fields.
    """

    flags: int = 0
    sim_interval_ms: int = 0
    real_interval_ms: int = 0
    last_interval_ms: int = 0
    true_x_mm: int = 0
    true_y_mm: int = 0
    true_z_mm: int = 0
    true_th_deg: int = 0
    latitude_e7: int = 0
    longitude_e7: int = 0
    altitude_cm: int = 0
    dop_x100: int = 0
    odom_error_x_e7: int = 0
    odom_error_y_e7: int = 0
    odom_error_th_e7: int = 0
    extra: bytes = b""


_SIMSTAT = struct.Struct("<xxIHHH11i")           # two reserved bytes (MobileSim: two empty strings)


@dataclass(frozen=True, slots=True)
class SimDevice:
    """One device of a SIMINFO packet: name, type, number and status."""

    name: str
    type: str
    number: int
    status: int


@dataclass(frozen=True, slots=True)
class SimInfo:
    """SIMINFO, type 0x63 (§5.2): application name and version, feature flags, devices."""

    app_name: str
    app_version: str
    flags: int = 0
    devices: tuple[SimDevice, ...] = ()
    extra: bytes = b""


def _decode_siminfo(data: bytes) -> SimInfo:
    r = _Reader(data, "SIMINFO")
    name, version = r.cstr(), r.cstr()
    flags, count = r.unpack(_U32)[0], r.unpack(_U32)[0]
    if count * 7 > r.left():               # every device takes at least 7 bytes
        raise ProtocolError(f"{_WHERE}: SIMINFO announces {count} devices in {r.left()} bytes")
    devices = tuple(SimDevice(r.cstr(), r.cstr(), r.unpack(_U8)[0], r.unpack(_U32)[0]) for _ in range(count))
    return SimInfo(name, version, flags, devices, r.rest())


@dataclass(frozen=True, slots=True)
class SimMapChanged:
    """SIM_MAP_CHANGED, type 0x66 (§5.2): user (1) or client (0) change, load status, file name."""

    user: int
    loaded: int
    filename: str
    extra: bytes = b""


@dataclass(frozen=True, slots=True)
class EncoderPacket:
    """ENCODER, type 0x90 (§5.2): raw encoder counts of the left and right wheels (int32)."""

    left: int
    right: int
    extra: bytes = b""


@dataclass(frozen=True, slots=True)
class UnknownPacket:
    """A packet of a type this codec does not decode (or whose payload was malformed)."""

    ptype: int
    payload: bytes


Packet = (SyncReply | StandardSip | ConfigPacket | SimLaserPacket | SimStat | SimInfo | SimMapChanged
          | EncoderPacket | UnknownPacket)


def decode_packet(ptype: int, data: bytes) -> Packet:
    """Decode the DATA of one robot-to-client packet by its type.

    Args:
        ptype: packet type byte.
        data: DATA bytes after the type.

    Returns:
        The decoded packet; `UnknownPacket` for types without a documented layout.

    Raises:
        ProtocolError: the payload is too short or inconsistent for its type.
    """
    data = bytes(data)
    if ptype in (c.PTYPE_SIP_STOPPED, c.PTYPE_SIP_MOVING):
        return _decode_sip(ptype, data)
    if ptype in (c.PTYPE_SYNC0, c.PTYPE_SYNC1):
        if data:
            raise ProtocolError(f"{_WHERE}: SYNC{ptype} reply must be empty, got {len(data)} data bytes")
        return SyncReply(ptype)
    if ptype == c.PTYPE_SYNC2:
        r = _Reader(data, "SYNC2 reply")
        reply = SyncReply(2, r.cstr(), r.cstr(), r.cstr())
        if r.left():
            raise ProtocolError(f"{_WHERE}: SYNC2 reply has {r.left()} bytes after its three strings")
        return reply
    if ptype == c.PTYPE_CONFIG:
        return _decode_config(data)
    if ptype in (c.PTYPE_SIM_LASER, c.PTYPE_SIM_LASER_EXT):
        return _decode_laser(data, ptype == c.PTYPE_SIM_LASER_EXT)
    if ptype == c.PTYPE_SIMSTAT:
        r = _Reader(data, "SIMSTAT")
        names = [f.name for f in fields(SimStat)[:-1]]
        return SimStat(**dict(zip(names, r.unpack(_SIMSTAT), strict=True)), extra=r.rest())
    if ptype == c.PTYPE_SIMINFO:
        return _decode_siminfo(data)
    if ptype == c.PTYPE_SIM_MAP_CHANGED:
        r = _Reader(data, "SIM_MAP_CHANGED")
        user, loaded = r.unpack(_U8)[0], r.unpack(_U8)[0]
        return SimMapChanged(user, loaded, r.cstr(), r.rest())
    if ptype == c.PTYPE_ENCODER:
        r = _Reader(data, "ENCODER")
        left, right = r.unpack(struct.Struct("<ii"))
        return EncoderPacket(left, right, r.rest())
    return UnknownPacket(ptype, data)


def encode_packet(packet: Packet) -> bytes:
    """Frame one robot-to-client packet (the emulator's side); inverse of `PacketDecoder`.

    Raises:
        ConfigError: a field out of range for its wire type, or an inconsistent packet.
    """
    if isinstance(packet, StandardSip):
        ptype, data = _encode_sip(packet)
    elif isinstance(packet, SyncReply):
        if packet.seq not in (0, 1, 2) or packet.seq < 2 and (packet.name or packet.robot_type
                                                               or packet.robot_subtype):
            raise ConfigError(f"{_WHERE}: sync reply seq must be 0..2 and only seq 2 has strings, "
                              f"got {packet}")
        ptype = packet.seq
        data = b"" if ptype < 2 else b"".join(_cstr(s, "SYNC2 string") for s in
                                              (packet.name, packet.robot_type, packet.robot_subtype))
    elif isinstance(packet, ConfigPacket):
        ptype, data = _encode_config(packet)
    elif isinstance(packet, SimLaserPacket):
        ptype, data = _encode_laser(packet)
    elif isinstance(packet, SimStat):
        ptype = c.PTYPE_SIMSTAT
        data = _pack(_SIMSTAT, *(getattr(packet, f.name) for f in fields(SimStat)[:-1]),
                     what="SIMSTAT fields") + packet.extra
    elif isinstance(packet, SimInfo):
        ptype = c.PTYPE_SIMINFO
        data = (_cstr(packet.app_name, "SIMINFO name") + _cstr(packet.app_version, "SIMINFO version")
                + _pack("<II", packet.flags, len(packet.devices), what="SIMINFO flags, count")
                + b"".join(_cstr(d.name, "device name") + _cstr(d.type, "device type")
                           + _pack("<BI", d.number, d.status, what="device number, status")
                           for d in packet.devices) + packet.extra)
    elif isinstance(packet, SimMapChanged):
        ptype = c.PTYPE_SIM_MAP_CHANGED
        data = (_pack("<BB", packet.user, packet.loaded, what="SIM_MAP_CHANGED user, loaded")
                + _cstr(packet.filename, "map file name") + packet.extra)
    elif isinstance(packet, EncoderPacket):
        ptype, data = c.PTYPE_ENCODER, _pack("<ii", packet.left, packet.right, what="encoder") + packet.extra
    else:
        ptype, data = packet.ptype, packet.payload
    return frame(ptype, data)


# --- stream decoders -----------------------------------------------------------------------------------
class _FrameStream:
    """Splits a byte stream into (id, data) frames; resynchronises on 0xFA 0xFB, never raises."""

    def __init__(self, max_count: int = c.MAX_COUNT) -> None:
        if not c.MIN_COUNT <= max_count <= 255:
            raise ConfigError(f"{_WHERE}: max_count must be {c.MIN_COUNT}..255, got {max_count}")
        self.max_count = max_count
        self._buf = bytearray()
        self.packets = 0          # frames with a valid checksum
        self.dropped_bytes = 0    # bytes not part of any valid frame
        self.bad_checksums = 0
        self.bad_lengths = 0      # COUNT < 3 or > max_count
        self.truncated = 0        # incomplete frames discarded by flush()

    @property
    def buffered(self) -> int:
        """Bytes held back, waiting for the rest of a frame."""
        return len(self._buf)

    def _frames(self, data: bytes | bytearray | memoryview, final: bool) -> list[tuple[int, bytes]]:
        buf = self._buf
        buf += data
        out: list[tuple[int, bytes]] = []
        pos, n = 0, len(buf)
        while True:
            i = buf.find(c.HEADER, pos)
            if i < 0:                     # keep a trailing 0xFA: it may start the next header
                keep = n - 1 if n > pos and buf[-1] == c.HEADER_0 and not final else n
                self.dropped_bytes += keep - pos
                pos = keep
                break
            self.dropped_bytes += i - pos
            pos = i
            end = pos + 3 + buf[pos + 2] if pos + 2 < n else n + 1
            if pos + 2 < n and not c.MIN_COUNT <= buf[pos + 2] <= self.max_count:
                self.bad_lengths += 1
            elif end > n:                 # incomplete: wait, unless the stream ended or went silent
                if not final:
                    break
                self.truncated += 1
            elif checksum(buf[pos + 3:end - 2]) != (buf[end - 2] << 8 | buf[end - 1]):
                self.bad_checksums += 1
            else:
                out.append((buf[pos + 3], bytes(buf[pos + 4:end - 2])))
                self.packets += 1
                pos = end
                continue
            # Skip only the 0xFA: a real header may start inside the rejected bytes.
            self.dropped_bytes += 1
            pos += 1
        del buf[:pos]
        return out


class PacketDecoder(_FrameStream):
    """Robot-to-client stream decoder (the driver's side).

    `feed` returns every complete packet; `flush` discards a partial frame (call it when the link
    was silent for more than 100 ms, ARIA's rule in §2.1, or at the end of a stream) and returns
    packets found in the bytes after it. Malformed payloads of known types come out as
    `UnknownPacket` and are counted in `bad_payloads`. Never raises.

    Args:
        max_count: largest COUNT accepted (200 by §2; ARIA itself accepts up to 255).
    """

    def __init__(self, max_count: int = c.MAX_COUNT) -> None:
        """Start with an empty buffer and zero counters."""
        super().__init__(max_count)
        self.bad_payloads = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[Packet]:
        """Add received bytes; return the packets they complete, in order."""
        return [self._decode(pid, body) for pid, body in self._frames(data, final=False)]

    def flush(self) -> list[Packet]:
        """Drop any incomplete frame and return packets that were waiting behind it."""
        return [self._decode(pid, body) for pid, body in self._frames(b"", final=True)]

    def _decode(self, ptype: int, data: bytes) -> Packet:
        try:
            return decode_packet(ptype, data)
        except ProtocolError:
            self.bad_payloads += 1
            return UnknownPacket(ptype, data)


class CommandDecoder(_FrameStream):
    """Client-to-robot stream decoder (the emulator's side): yields `Command`s. Never raises.

    Args:
        max_count: largest COUNT accepted (200 by §2).
    """

    def feed(self, data: bytes | bytearray | memoryview) -> list[Command]:
        """Add received bytes; return the commands they complete, in order."""
        return [decode_command(cmd, body) for cmd, body in self._frames(data, final=False)]

    def flush(self) -> list[Command]:
        """Drop any incomplete frame and return commands that were waiting behind it."""
        return [decode_command(cmd, body) for cmd, body in self._frames(b"", final=True)]


# --- §5.1 positions ------------------------------------------------------------------------------------
def unwrap_position_delta(prev_raw: int, new_raw: int) -> int:
    """Odometry delta between two XPOS (or YPOS) values, as ARIA computes it (§5.1).

    Only the low 15 bits count; a jump beyond +-0x1000 units is taken as a wrap-around.

    Args:
        prev_raw: previous XPOS as received.
        new_raw: new XPOS as received.

    Returns:
        The delta [DistConvFactor mm], in -0x1000..0x1000 (the robot must not move more than
        0x1000 units, 1987 mm at 0.485 mm/unit, between two SIPs).
    """
    d = (new_raw & c.POS_MASK) - (prev_raw & c.POS_MASK)
    if d > c.POS_WRAP_THRESHOLD:
        d -= c.POS_MODULUS
    elif d < -c.POS_WRAP_THRESHOLD:
        d += c.POS_MODULUS
    return d


def position_to_raw(pos_mm: float, dist_conv: float = c.DIST_CONV_FACTOR) -> int:
    """XPOS/YPOS for a position [mm]: `pos_mm / dist_conv` truncated, as uint16 (wraps like MobileSim)."""
    return int(pos_mm / dist_conv) & 0xFFFF


def heading_to_raw(theta_deg: float, angle_conv: float = c.ANGLE_CONV_FACTOR) -> int:
    """THPOS for a heading [deg] (normalised to -180..180 first): `rad / angle_conv` truncated."""
    wrapped = (theta_deg + 180.0) % 360.0 - 180.0
    return int(math.radians(wrapped) / angle_conv)

