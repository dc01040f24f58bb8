"""Pure codec of the Kobuki serial protocol: bytes in, frozen dataclasses out, and back.

No I/O and no clocks here. A frame is ``AA 55 | LENGTH | PAYLOAD | CHECKSUM`` with the checksum the
XOR of the length byte and the payload; the payload is a run of sub-payloads ``ID | LEN | DATA``
(kobuki.md section 2). Feedback and command IDs overlap (1, 3, 4, ...), so decoding needs a
`Direction`. Every sub-payload a decoder does not know, or whose data length is not the documented
one, is kept as `UnknownSubpayload` (the driver skips those by their LEN byte too).

The message dataclasses live in `messages` and are re-exported here, so ``codec.BaseControl``
and friends keep working. Units stay those of the protocol (mm, mm/s, ticks, 0.01 deg); the SI
helpers at the end (`base_control_from_twist`, odometry) are the only conversions, for the backend
and the emulator.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal, TypeAlias

from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.kobuki.messages import (
    BaseControl,
    BasicSensorData,
    CliffSensors,
    ControllerInfo,
    DockingIR,
    FirmwareVersion,
    GeneralPurposeInput,
    GeneralPurposeOutput,
    GetControllerGain,
    HardwareVersion,
    InertialSensor,
    Message,
    MotorCurrent,
    RawGyro,
    RequestExtra,
    SetControllerGain,
    Sound,
    SoundSequence,
    UniqueDeviceID,
    UnknownSubpayload,
)

from robotexp import ConfigError

__all__ = [
    "BaseControl", "BasicSensorData", "CliffSensors", "ControllerInfo", "Direction", "DockingIR",
    "FirmwareVersion", "Frame", "FrameDecoder", "GeneralPurposeInput", "GeneralPurposeOutput",
    "GetControllerGain", "HardwareVersion", "InertialSensor", "Message", "MotorCurrent", "RawGyro",
    "RequestExtra", "SetControllerGain", "Sound", "SoundSequence", "UniqueDeviceID",
    "UnknownSubpayload", "base_control", "base_control_from_twist", "decode_payload",
    "decode_subpayload", "diff_drive_update", "encode_frame", "encode_messages", "encoder_delta",
    "general_purpose_output", "get_controller_gain", "metres_to_ticks", "request_extra",
    "set_controller_gain", "sound", "sound_note", "sound_sequence", "ticks_to_metres",
    "timestamp_delta", "twist_from_base_control", "xor_checksum",
]

Direction: TypeAlias = Literal["feedback", "command"]


Frame: TypeAlias = list[Message]
"""One decoded frame: its sub-payload messages in order."""

_FEEDBACK_TYPES = (BasicSensorData, DockingIR, InertialSensor, CliffSensors, MotorCurrent, HardwareVersion,
                   FirmwareVersion, RawGyro, GeneralPurposeInput, UniqueDeviceID, ControllerInfo)
_COMMAND_TYPES = (BaseControl, Sound, SoundSequence, RequestExtra, GeneralPurposeOutput, SetControllerGain,
                  GetControllerGain)
_DECODERS: dict[str, dict[int, Callable[[bytes], Message | None]]] = {
    "feedback": {c.ID: c.decode for c in _FEEDBACK_TYPES},
    "command": {c.ID: c.decode for c in _COMMAND_TYPES},
}


# ---------------------------------------------------------------------------------------- framing
def xor_checksum(data: bytes | bytearray | memoryview) -> int:
    """XOR of all bytes of `data` (0 for empty data)."""
    acc = 0
    for byte in data:
        acc ^= byte
    return acc


def encode_frame(subpayloads: bytes) -> bytes:
    """Wrap concatenated sub-payloads into ``AA 55 | LENGTH | PAYLOAD | XOR(LENGTH, PAYLOAD)``.

    Raises:
        ConfigError: the payload is shorter than 3 or longer than 255 bytes.
    """
    n = len(subpayloads)
    if not K.MIN_PAYLOAD_LEN <= n <= K.MAX_PAYLOAD_LEN:
        raise ConfigError(f"kobuki codec: frame payload of {n} bytes, expected "
                          f"{K.MIN_PAYLOAD_LEN}..{K.MAX_PAYLOAD_LEN}; split it over several frames")
    return K.HEADER + bytes((n,)) + bytes(subpayloads) + bytes((n ^ xor_checksum(subpayloads),))


def encode_messages(*messages: Message) -> bytes:
    """Encode `messages` as the sub-payloads of one frame. Raises ConfigError as `encode_frame`."""
    return encode_frame(b"".join(m.encode() for m in messages))


def decode_subpayload(sub_id: int, data: bytes, direction: Direction = "feedback") -> Message:
    """Decode one sub-payload's data; unknown IDs and wrong lengths give `UnknownSubpayload`."""
    decoder = _DECODERS[direction].get(sub_id)
    message = decoder(data) if decoder is not None else None
    return message if message is not None else UnknownSubpayload(sub_id, bytes(data))


def decode_payload(payload: bytes, direction: Direction = "feedback") -> Frame | None:
    """Split a frame payload into decoded sub-payloads.

    Returns:
        The messages in order, or None when the sub-payload lengths do not tile the payload exactly
        (a LEN byte that overruns it, a LEN of 0, or one or two stray bytes at the end).
    """
    messages: Frame = []
    pos, n = 0, len(payload)
    while pos < n:
        if n - pos < K.SUBPAYLOAD_HEADER_LEN + K.MIN_SUBPAYLOAD_DATA_LEN:
            return None
        sub_id, sub_len = payload[pos], payload[pos + 1]
        start = pos + K.SUBPAYLOAD_HEADER_LEN
        if sub_len < K.MIN_SUBPAYLOAD_DATA_LEN or start + sub_len > n:
            return None
        messages.append(decode_subpayload(sub_id, payload[start:start + sub_len], direction))
        pos = start + sub_len
    return messages


class FrameDecoder:
    """Incremental frame finder: feed it any bytes, get back the complete valid frames.

    It scans for ``AA 55``, waits for the whole frame, and accepts it only when the length is at
    least 3, the XOR checksum is 0 and the sub-payloads tile the payload. On any rejection it drops
    a single byte and scans again, so a false header never hides a real frame behind it unless the
    false frame itself passes both checks (the fuzz benchmark measures how rarely). A corrupted
    length byte holds the frames behind it back until its LENGTH + 4 bytes (at most 259) have
    arrived, as in the Yujin driver. `feed` never raises on any bytes.

    Attributes:
        frames: frames accepted.
        dropped_bytes: bytes discarded while resynchronising (noise and rejected headers).
        bad_checksums: candidate frames rejected for their checksum.
        bad_lengths: candidates rejected for a length under 3 or sub-payloads that do not tile.
        unknown_subpayloads: sub-payloads kept as `UnknownSubpayload` in accepted frames.
    """

    def __init__(self, direction: Direction = "feedback") -> None:
        """Decode feedback (robot to host, default) or commands (host to robot, for the emulator).

        Raises:
            ConfigError: `direction` is neither "feedback" nor "command".
        """
        if direction not in _DECODERS:
            raise ConfigError(f"kobuki FrameDecoder: direction must be 'feedback' or 'command', "
                              f"got {direction!r}")
        self.direction: Direction = direction
        self._buffer = bytearray()
        self.frames = 0
        self.dropped_bytes = 0
        self.bad_checksums = 0
        self.bad_lengths = 0
        self.unknown_subpayloads = 0

    @property
    def buffered(self) -> int:
        """Bytes held back waiting for the rest of a frame [bytes] (at most 258 + one feed)."""
        return len(self._buffer)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        """Append `data` to the stream and return the frames completed by it, in order."""
        buf = self._buffer
        buf += data
        n = len(buf)
        frames: list[Frame] = []
        pos = 0
        while True:
            start = buf.find(K.HEADER, pos)
            if start < 0:
                # Keep a trailing 0xAA: it may be the first half of a header split across feeds.
                keep = n - 1 if n > pos and buf[-1] == K.HEADER_0 else n
                self.dropped_bytes += keep - pos
                pos = keep
                break
            self.dropped_bytes += start - pos
            pos = start
            if n - pos < 3:
                break
            length = buf[pos + 2]
            end = pos + K.FRAME_OVERHEAD + length
            if length < K.MIN_PAYLOAD_LEN:
                self.bad_lengths += 1
            elif end > n:
                break  # wait for the rest of the frame
            elif xor_checksum(memoryview(buf)[pos + 2:end]) != 0:
                self.bad_checksums += 1
            else:
                messages = decode_payload(bytes(buf[pos + 3:end - 1]), self.direction)
                if messages is not None:
                    frames.append(messages)
                    self.frames += 1
                    self.unknown_subpayloads += sum(isinstance(m, UnknownSubpayload) for m in messages)
                    pos = end
                    continue
                self.bad_lengths += 1
            self.dropped_bytes += 1
            pos += 1
        del buf[:pos]
        return frames


# ---------------------------------------------------------------------------------------- builders
def base_control(speed_mm_s: int, radius_mm: int) -> bytes:
    """Base Control sub-payload (ID 1). Raises ConfigError outside int16."""
    return BaseControl(speed_mm_s, radius_mm).encode()


def sound(note: int, duration_ms: int) -> bytes:
    """Sound sub-payload (ID 3). Raises ConfigError outside uint16 / uint8."""
    return Sound(note, duration_ms).encode()


def sound_note(frequency: float) -> int:
    """Note value for a tone of `frequency` [Hz]: round(1 / (f * 2.75e-6)).

    Raises:
        ConfigError: the note does not fit uint16 (f below about 5.6 Hz) or f is not positive.
    """
    if not frequency > 0.0 or not math.isfinite(frequency):
        raise ConfigError(f"kobuki sound_note: frequency must be a positive number [Hz], got {frequency}")
    note = round(1.0 / (frequency * K.SOUND_NOTE_PERIOD))
    if not 1 <= note <= 0xFFFF:
        raise ConfigError(f"kobuki sound_note: {frequency} Hz gives note {note}, outside 1..65535")
    return note


def sound_sequence(sequence: int) -> bytes:
    """Sound Sequence sub-payload (ID 4); `sequence` is one of `constants.SOUND_*`."""
    return SoundSequence(sequence).encode()


def request_extra(flags: int) -> bytes:
    """Request Extra sub-payload (ID 9); `flags` from `constants.REQUEST_*`."""
    return RequestExtra(flags).encode()


def general_purpose_output(flags: int) -> bytes:
    """General Purpose Output sub-payload (ID 12); the whole word of `constants.GPO_*` flags."""
    return GeneralPurposeOutput(flags).encode()


def set_controller_gain(gain_type: int, p_x1000: int, i_x1000: int, d_x1000: int) -> bytes:
    """Set Controller Gain sub-payload (ID 13); gains x 1000 as uint32."""
    return SetControllerGain(gain_type, p_x1000, i_x1000, d_x1000).encode()


def get_controller_gain() -> bytes:
    """Get Controller Gain sub-payload (ID 14)."""
    return GetControllerGain().encode()


# ---------------------------------------------------------------------------------------- SI helpers
def _bound_int16(value: float) -> int:
    """Clamp to int16, then truncate toward zero (DiffDrive::bound)."""
    if value > K.INT16_MAX:
        return K.INT16_MAX
    if value < K.INT16_MIN:
        return K.INT16_MIN
    return int(value)


def base_control_from_twist(v: float, w: float) -> tuple[int, int]:
    """Convert a body command to Base Control values, as `DiffDrive::velocityCommands` does.

    |w| < 1e-4: straight (radius 0, speed = v). Else radius = v / w; if |v| < 1e-4 or |radius| <= 1 mm:
    turn in place (radius 1, speed = b w / 2, positive for counter-clockwise). Else an arc whose speed
    is the outer wheel's, (radius +- b/2) w, the sign following the radius. Both are clamped to int16
    and truncated toward zero; the operations keep the driver's order so the doubles round alike.

    Args:
        v: forward speed [m/s].
        w: turn rate [rad/s], counter-clockwise positive.

    Returns:
        (speed_mm_s, radius_mm).

    Raises:
        ConfigError: v or w is not finite.
    """
    if not (math.isfinite(v) and math.isfinite(w)):
        raise ConfigError(f"kobuki base_control_from_twist: v and w must be finite, got v={v}, w={w}")
    if abs(w) < K.TWIST_EPSILON:
        return _bound_int16(1000.0 * v), K.RADIUS_STRAIGHT_MM
    radius = v * 1000.0 / w
    if abs(v) < K.TWIST_EPSILON or abs(radius) <= 1.0:
        return _bound_int16(1000.0 * K.WHEEL_BASE * w / 2.0), K.RADIUS_ROTATE_MM
    half_base_mm = 1000.0 * K.WHEEL_BASE / 2.0
    speed = (radius + half_base_mm) * w if radius > 0.0 else (radius - half_base_mm) * w
    return _bound_int16(speed), _bound_int16(radius)


def twist_from_base_control(speed_mm_s: int, radius_mm: int) -> tuple[float, float]:
    """Body velocity (v [m/s], w [rad/s]) a robot follows for a Base Control command (for emulators).

    Radius 0: v = speed. Radius 1: w = 2 speed / b. Otherwise w = speed / (radius +- b/2) (the sign of
    the radius), v = w radius. Radius -1 is not special in any source (UNCONFIRMED; the driver never
    sends it): here it is an ordinary arc of -1 mm.
    """
    if radius_mm == K.RADIUS_STRAIGHT_MM:
        return speed_mm_s / 1000.0, 0.0
    if radius_mm == K.RADIUS_ROTATE_MM:
        return 0.0, 2.0 * speed_mm_s / K.WHEEL_BASE_MM
    half_base_mm = K.WHEEL_BASE_MM / 2.0
    w = speed_mm_s / (radius_mm + half_base_mm) if radius_mm > 0 else speed_mm_s / (radius_mm - half_base_mm)
    return w * radius_mm / 1000.0, w


def encoder_delta(current: int, last: int) -> int:
    """Signed tick change between two uint16 encoder readings, across the 65535 -> 0 wrap [ticks]."""
    d = (current - last) & 0xFFFF
    return d - K.ENCODER_MODULUS if d >= 0x8000 else d


def timestamp_delta(current_ms: int, last_ms: int) -> float:
    """Time between two uint16 basic-sensor timestamps, as the driver computes it (int16) [s]."""
    return encoder_delta(current_ms, last_ms) / 1000.0


def ticks_to_metres(ticks: float) -> float:
    """Wheel travel [m] for `ticks` encoder ticks."""
    return ticks * K.TICK_TO_METRE


def metres_to_ticks(distance: float) -> int:
    """Encoder ticks (rounded) for a wheel travel of `distance` [m] (emulator side)."""
    return round(distance * K.METRE_TO_TICK)


def diff_drive_update(dl: float, dr: float, wheel_base: float = K.WHEEL_BASE) -> tuple[float, float]:
    """Differential-drive step: (ds, dtheta) = ((dl + dr) / 2, (dr - dl) / b).

    Args:
        dl: left wheel travel [m].
        dr: right wheel travel [m].
        wheel_base: wheel-to-wheel distance b [m].

    Returns:
        (ds [m] along the heading, dtheta [rad] counter-clockwise).
    """
    return (dl + dr) / 2.0, (dr - dl) / wheel_base
