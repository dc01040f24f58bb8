"""Messages of the Kobuki serial protocol: one frozen dataclass per sub-payload, with its layout.

Each message encodes itself as a whole sub-payload (``ID | LEN | DATA``) and decodes from its data
bytes (None when the length is not the documented one). Units stay those of the protocol (mm, mm/s,
ticks, 0.01 deg, 0.1 V); `codec` does the framing and holds the few SI helpers.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, fields
from typing import ClassVar, Self, TypeAlias

from robotexp import ConfigError
from robotexp_drivers.kobuki import constants as K

__all__ = [
    "BaseControl",
    "BasicSensorData",
    "CliffSensors",
    "ControllerInfo",
    "DockingIR",
    "FirmwareVersion",
    "GeneralPurposeInput",
    "GeneralPurposeOutput",
    "GetControllerGain",
    "HardwareVersion",
    "InertialSensor",
    "Message",
    "MotorCurrent",
    "RawGyro",
    "RequestExtra",
    "SetControllerGain",
    "Sound",
    "SoundSequence",
    "UniqueDeviceID",
    "UnknownSubpayload",
]


def _pack(name: str, fmt: str, *values: int) -> bytes:
    """Pack `values` with struct format `fmt`; out-of-range values raise ConfigError naming `name`."""
    try:
        return struct.pack(fmt, *values)
    except struct.error as exc:
        raise ConfigError(f"kobuki codec: {name}{values} does not fit the protocol fields "
                          f"({fmt!r}: {exc}); pass integers within the documented ranges") from exc


def _subpayload(sub_id: int, data: bytes) -> bytes:
    """Prefix `data` with its sub-payload ID and LEN bytes."""
    if not K.MIN_SUBPAYLOAD_DATA_LEN <= len(data) <= K.MAX_PAYLOAD_LEN - K.SUBPAYLOAD_HEADER_LEN:
        raise ConfigError(f"kobuki codec: sub-payload {sub_id} has {len(data)} data bytes, expected "
                          f"{K.MIN_SUBPAYLOAD_DATA_LEN}..{K.MAX_PAYLOAD_LEN - K.SUBPAYLOAD_HEADER_LEN}")
    return _pack("sub-payload header", "<BB", sub_id, len(data)) + data


@dataclass(frozen=True, slots=True)
class _Fixed:
    """Base of the messages whose data is one fixed struct layout (`FMT`) of their fields in order."""

    ID: ClassVar[int]
    FMT: ClassVar[str]

    def encode(self) -> bytes:
        """Return the whole sub-payload (ID, LEN, data) [bytes]. Raises ConfigError when out of range."""
        values = [getattr(self, f.name) for f in fields(self)]
        return _subpayload(self.ID, _pack(type(self).__name__, self.FMT, *values))

    @classmethod
    def decode(cls, data: bytes) -> Self | None:
        """Decode the data bytes of a sub-payload; None when the length is not the documented one."""
        if len(data) != struct.calcsize(cls.FMT):
            return None
        return cls(*struct.unpack(cls.FMT, data))


@dataclass(frozen=True, slots=True)
class UnknownSubpayload:
    """A sub-payload with an unknown ID, or a known ID with a data length we cannot decode."""

    id: int
    data: bytes

    def encode(self) -> bytes:
        """Return the whole sub-payload (ID, LEN, data) [bytes]."""
        return _subpayload(self.id, bytes(self.data))


# ---------------------------------------------------------------------------------------- feedback
@dataclass(frozen=True, slots=True)
class BasicSensorData(_Fixed):
    """Feedback ID 1, streamed at 50 Hz (kobuki.md 4.1). Bit masks are `constants.BUMPER_*` etc."""

    ID = K.FB_BASIC_SENSOR_DATA
    FMT = "<HBBBHHbbBBBB"
    timestamp_ms: int   # [ms] wraps 65535 -> 0
    bumper: int         # 0x01 right, 0x02 centre, 0x04 left
    wheel_drop: int     # 0x01 right, 0x02 left
    cliff: int          # 0x01 right, 0x02 centre, 0x04 left
    left_encoder: int   # [ticks] uint16, wraps
    right_encoder: int  # [ticks] uint16, wraps
    left_pwm: int       # int8, negative = backward
    right_pwm: int      # int8
    buttons: int        # 0x01 B0, 0x02 B1, 0x04 B2
    charger: int        # 0 discharging, 2/6 dock charged/charging, 18/22 adapter charged/charging
    battery_dv: int     # [0.1 V]
    overcurrent: int    # 0x01 left wheel, 0x02 right wheel

    @property
    def battery_voltage(self) -> float:
        """Battery voltage [V]."""
        return self.battery_dv * K.BATTERY_SCALE


@dataclass(frozen=True, slots=True)
class DockingIR(_Fixed):
    """Feedback ID 3: the dock's IR regions seen by each receiver (`constants.DOCK_*` bits)."""

    ID = K.FB_DOCKING_IR
    FMT = "<BBB"
    right: int
    central: int
    left: int


@dataclass(frozen=True, slots=True)
class InertialSensor(_Fixed):
    """Feedback ID 4: factory-calibrated z heading and rate (counter-clockwise positive)."""

    ID = K.FB_INERTIAL_SENSOR
    FMT = "<hhBBB"
    angle_cdeg: int           # [0.01 deg] int16
    angle_rate_cdeg_s: int    # [0.01 deg/s] int16
    acc0: int = 0             # three unused bytes, kept for exact re-encoding
    acc1: int = 0
    acc2: int = 0

    @property
    def angle(self) -> float:
        """Heading [rad] (not offset; the backend subtracts the first reading)."""
        return math.radians(self.angle_cdeg * K.INERTIA_SCALE)

    @property
    def angle_rate(self) -> float:
        """Turn rate [rad/s]."""
        return math.radians(self.angle_rate_cdeg_s * K.INERTIA_SCALE)


@dataclass(frozen=True, slots=True)
class CliffSensors(_Fixed):
    """Feedback ID 5: 12-bit ADC readings of the floor-facing PSD sensors (0..4095 = 0..3.3 V)."""

    ID = K.FB_CLIFF
    FMT = "<HHH"
    right: int
    centre: int
    left: int


@dataclass(frozen=True, slots=True)
class MotorCurrent(_Fixed):
    """Feedback ID 6: wheel motor currents, one byte each as the driver reads them."""

    ID = K.FB_CURRENT
    FMT = "<BB"
    left_10ma: int   # [10 mA]
    right_10ma: int  # [10 mA]


@dataclass(frozen=True, slots=True)
class _Version:
    """Hardware or firmware version: uint32 `major << 16 | minor << 8 | patch`, or an old uint16."""

    ID: ClassVar[int]
    version: int
    legacy: bool = False  # True: the old LEN-2 form carrying a uint16 code

    @property
    def major(self) -> int:
        """Major version number (0 for a legacy code)."""
        return (self.version >> 16) & 0xFF

    @property
    def minor(self) -> int:
        """Minor version number."""
        return (self.version >> 8) & 0xFF

    @property
    def patch(self) -> int:
        """Patch version number."""
        return self.version & 0xFF

    def encode(self) -> bytes:
        """Return the whole sub-payload (ID, LEN, data) [bytes]. Raises ConfigError when out of range."""
        fmt = "<H" if self.legacy else "<I"
        return _subpayload(self.ID, _pack(type(self).__name__, fmt, self.version))

    @classmethod
    def decode(cls, data: bytes) -> Self | None:
        """Decode 4 (or legacy 2) data bytes; None for any other length."""
        if len(data) == K.FB_VERSION_LEN:
            return cls(struct.unpack("<I", data)[0])
        if len(data) == K.FB_VERSION_LEGACY_LEN:
            return cls(struct.unpack("<H", data)[0], legacy=True)
        return None


@dataclass(frozen=True, slots=True)
class HardwareVersion(_Version):
    """Feedback ID 10, sent on Request Extra (flag 0x01)."""

    ID = K.FB_HARDWARE_VERSION


@dataclass(frozen=True, slots=True)
class FirmwareVersion(_Version):
    """Feedback ID 11, sent on Request Extra (flag 0x02). Legacy codes: `constants.FIRMWARE_LEGACY_CODES`."""

    ID = K.FB_FIRMWARE_VERSION


@dataclass(frozen=True, slots=True)
class RawGyro:
    """Feedback ID 13: raw L3G4200D samples (x, y, z) as int16 [0.00875 deg/s], gyro axes."""

    ID: ClassVar[int] = K.FB_RAW_GYRO
    frame_id: int                               # id of sample 0, wraps 0..255
    samples: tuple[tuple[int, int, int], ...]

    def encode(self) -> bytes:
        """Return the whole sub-payload (ID, LEN, data) [bytes]. Raises ConfigError when out of range."""
        words = [w for s in self.samples for w in s]
        if any(len(s) != 3 for s in self.samples):
            raise ConfigError(f"kobuki codec: RawGyro samples must be (x, y, z) triples, got {self.samples}")
        data = _pack("RawGyro", f"<BB{len(words)}h", self.frame_id, len(words), *words)
        return _subpayload(self.ID, data)

    @classmethod
    def decode(cls, data: bytes) -> Self | None:
        """Decode frame id, word count 3N and N samples; None when the lengths disagree."""
        if len(data) < K.FB_RAW_GYRO_HEADER_LEN:
            return None
        frame_id, n_words = data[0], data[1]
        if n_words % 3 or len(data) != K.FB_RAW_GYRO_HEADER_LEN + 2 * n_words:
            return None
        words = struct.unpack_from(f"<{n_words}h", data, K.FB_RAW_GYRO_HEADER_LEN)
        return cls(frame_id, tuple((words[i], words[i + 1], words[i + 2]) for i in range(0, n_words, 3)))


@dataclass(frozen=True, slots=True)
class GeneralPurposeInput(_Fixed):
    """Feedback ID 16: digital inputs (0x01..0x08) and four 12-bit analog inputs (0..4095 = 0..3.3 V)."""

    ID = K.FB_GENERAL_PURPOSE_INPUT
    FMT = "<8H"
    digital: int
    analog0: int
    analog1: int
    analog2: int
    analog3: int
    unused0: int = 0   # three unused words, kept for exact re-encoding
    unused1: int = 0
    unused2: int = 0


@dataclass(frozen=True, slots=True)
class UniqueDeviceID(_Fixed):
    """Feedback ID 19, sent on Request Extra (flag 0x08); printed as ``UDID0-UDID1-UDID2``."""

    ID = K.FB_UDID
    FMT = "<III"
    udid0: int
    udid1: int
    udid2: int

    def __str__(self) -> str:
        """The driver's printed form ``UDID0-UDID1-UDID2`` (decimal)."""
        return f"{self.udid0}-{self.udid1}-{self.udid2}"


@dataclass(frozen=True, slots=True)
class ControllerInfo(_Fixed):
    """Feedback ID 21, the answer to Get Controller Gain: gain type and P, I, D (each gain x 1000)."""

    ID = K.FB_CONTROLLER_INFO
    FMT = "<BIII"
    gain_type: int  # 0 factory, 1 user
    p_x1000: int
    i_x1000: int
    d_x1000: int


# ---------------------------------------------------------------------------------------- commands
@dataclass(frozen=True, slots=True)
class BaseControl(_Fixed):
    """Command ID 1: arc of `radius_mm` at `speed_mm_s` (radius 0 straight, 1 turn in place)."""

    ID = K.CMD_BASE_CONTROL
    FMT = "<hh"
    speed_mm_s: int  # [mm/s] int16; outer-wheel speed on arcs, wheel speed when turning in place
    radius_mm: int   # [mm] int16, > 0 = centre on the left


@dataclass(frozen=True, slots=True)
class Sound(_Fixed):
    """Command ID 3: a tone; `note` = 1 / (f * 2.75e-6) (see `sound_note`)."""

    ID = K.CMD_SOUND
    FMT = "<HB"
    note: int
    duration_ms: int  # [ms]


@dataclass(frozen=True, slots=True)
class SoundSequence(_Fixed):
    """Command ID 4: play a built-in sequence (`constants.SOUND_ON` .. `SOUND_CLEANING_END`)."""

    ID = K.CMD_SOUND_SEQUENCE
    FMT = "<B"
    sequence: int


@dataclass(frozen=True, slots=True)
class RequestExtra(_Fixed):
    """Command ID 9: ask for hardware/firmware version and UDID (`constants.REQUEST_*` flags)."""

    ID = K.CMD_REQUEST_EXTRA
    FMT = "<H"
    flags: int


@dataclass(frozen=True, slots=True)
class GeneralPurposeOutput(_Fixed):
    """Command ID 12: the whole 16-bit output word (`constants.GPO_*` flags)."""

    ID = K.CMD_GENERAL_PURPOSE_OUTPUT
    FMT = "<H"
    flags: int


@dataclass(frozen=True, slots=True)
class SetControllerGain(_Fixed):
    """Command ID 13 (LEN 13, driver code; the docs' header 1 is an erratum)."""

    ID = K.CMD_SET_CONTROLLER_GAIN
    FMT = "<BIII"
    gain_type: int  # 0 factory default, 1 user
    p_x1000: int
    i_x1000: int
    d_x1000: int


@dataclass(frozen=True, slots=True)
class GetControllerGain(_Fixed):
    """Command ID 14 (LEN 1, one unused byte); the robot answers with `ControllerInfo`."""

    ID = K.CMD_GET_CONTROLLER_GAIN
    FMT = "<B"
    unused: int = 0


Message: TypeAlias = (
    BasicSensorData | DockingIR | InertialSensor | CliffSensors | MotorCurrent | HardwareVersion
    | FirmwareVersion | RawGyro | GeneralPurposeInput | UniqueDeviceID | ControllerInfo
    | BaseControl | Sound | SoundSequence | RequestExtra | GeneralPurposeOutput | SetControllerGain
    | GetControllerGain | UnknownSubpayload
)
