"""Every protocol constant of the SICK LMS2xx (LMS200/211/221/291) RS-232/422 interface, in one place.

Names follow SICK's "Telegram Listing LMS2xx" (8007954, 2006; "TL" below, with its sections) and the
"Quick Manual for LMS communication setup" (2001; "QM"). Where the listing was read through other public
sources, they are named: ROS sicktoolbox (SickLMS2xx.hh/.cc, "STB") and AriaCoda (ArLMS2xx*.cpp, "ARIA").
See docs/protocols/lms2xx.md for the telegram layouts.
"""

from __future__ import annotations

import math
from enum import IntEnum

# -- framing (TL 4.2, Table 4-4) ------------------------------------------------------------
STX = 0x02                  # start of every telegram
ACK = 0x06                  # a standalone byte: the LMS received a telegram with a good CRC (TL 4.3)
NAK = 0x15                  # a standalone byte: bad CRC / malformed telegram (TL 4.3)
ADDR_BROADCAST = 0x00       # host -> LMS: every LMS on the line (the address host drivers use)
ADDR_REPLY_BIT = 0x80       # LMS -> host: the replying LMS's address | 0x80 (TL 4.2; TL examples reply at 0x80)
HEADER_LEN = 4              # STX, address, 16-bit length (little endian)
CRC_LEN = 2                 # CRC-16, low byte first
# The length field counts the command byte and the data (and, in replies, the status byte). The largest
# ordinary telegram is 812 bytes (TL p22); two optional index bytes (TL Table 7-25) make 814.
MAX_TELEGRAM = 814
MAX_LENGTH = MAX_TELEGRAM - HEADER_LEN - CRC_LEN   # 808

# -- CRC (TL 9, p107: "CreateCRC"; the same routine in STB SickLMS2xxMessage.cc and ARIA ArLMS2xxPacket.cpp) ----
CRC16_GEN_POL = 0x8005      # shifted in once per byte, then XOR with (previous byte << 8 | byte); start 0


# -- command codes, host -> LMS (TL 7) ------------------------------------------------------
class Cmd(IntEnum):
    """Request codes (first byte after the length)."""

    RESET = 0x10                    # initialisation and reset (TL 7.2.1); replies 0x91, later 0x90
    SWITCH_MODE = 0x20              # select or change operating mode, incl. the baud rate (TL 7.4.1)
    REQUEST_VALUES = 0x30           # request measured values (TL 7.5.1); sub-command 0x01: all values
    REQUEST_STATUS = 0x31           # request LMS status (TL 7.6)
    REQUEST_TYPE = 0x3A             # request LMS type (TL 7.15)
    SWITCH_VARIANT = 0x3B           # switch variant: scan angle and angular resolution (TL 7.16)
    REQUEST_CONFIG = 0x74           # request LMS configuration (TL 7.43)
    CONFIGURE = 0x77                # configure LMS (TL 7.46; installation mode only)


REPLY_BIT = 0x80                    # a reply's code is the request's | 0x80 (TL 7)


class Reply(IntEnum):
    """Reply codes, LMS -> host."""

    POWER_ON = 0x90                 # power-on / ready message with the type and firmware (TL 7.3.1; QM p9)
    RESET_ACK = 0x91                # reset acknowledged (TL 7.3.2)
    NOT_ACKNOWLEDGED = 0x92         # command not acknowledged: not allowed in this mode / unknown (TL 7.3.4)
    MODE = 0xA0                     # response to 0x20 (TL 7.4.2)
    VALUES = 0xB0                   # measured values (TL 7.5.2)
    STATUS = 0xB1                   # status (TL 7.6)
    TYPE = 0xBA                     # LMS type string (TL 7.15)
    VARIANT = 0xBB                  # variant switched (TL 7.16)
    CONFIG = 0xF4                   # configuration (TL 7.43)
    CONFIGURED = 0xF7               # configuration written (TL 7.46)


SUB_ALL_VALUES = 0x01               # 0x30 sub-command: all measured values of one scan (TL 7.5.1)


# -- operating modes, the data byte of 0x20 (TL Table 7-11..7-18; STB sick_lms_2xx_operating_mode_t) --------
class Mode(IntEnum):
    """Operating modes selected with SWITCH_MODE."""

    INSTALLATION = 0x00             # followed by the 8-byte password; needed to CONFIGURE
    DIAGNOSTIC = 0x10
    MONITOR_MIN_PER_SEGMENT = 0x20
    CONTINUOUS_ALL = 0x24           # continuous output of all measured values (0xB0 telegrams)
    MONITOR_REQUEST = 0x25          # measured values on request only (the power-on mode; "stop output")
    BAUD_38400 = 0x40
    BAUD_19200 = 0x41
    BAUD_9600 = 0x42
    BAUD_500K = 0x48                # RS-422 only on a real LMS (TL Table 7-18; QM D.2)


INSTALLATION_PASSWORD = b"SICK_LMS"     # the factory password (TL 7.4.1; QM C.6; ARIA sends it)

# the 0xA0 response's result byte (TL 7.4.2; ARIA ArLMS2xx.cpp STATE_WAIT_FOR_INSTALL_MODE_ACK)
MODE_OK = 0x00
MODE_BAD_PASSWORD = 0x01
MODE_FAULT = 0x02

BAUD_CODES: dict[int, Mode] = {9600: Mode.BAUD_9600, 19200: Mode.BAUD_19200, 38400: Mode.BAUD_38400,
                               500000: Mode.BAUD_500K}
BAUD_OF_CODE: dict[int, int] = {int(code): baud for baud, code in BAUD_CODES.items()}
POWER_ON_BAUD = 9600            # the LMS's rate after power-on or reset (TL 7.4.1; QM C.4)
# the active baud rate as the status telegram (0xB1) reports it (TL Table 7-33 block B2, p56)
STATUS_BAUD_WORD: dict[int, int] = {9600: 0x8067, 19200: 0x8033, 38400: 0x8019, 500000: 0x8001}

# -- variants, 0x3B data: scan angle [deg] and resolution [1/100 deg], both 16-bit LE (TL 7.16) ---------------
VARIANT_OK = 0x01               # 0xBB result byte: switched
VARIANT_REFUSED = 0x00          # 0xBB result byte: aborted (the previous variant stays)
SCAN_ANGLES = (100, 180)
RESOLUTIONS = (25, 50, 100)     # [1/100 deg]
VALID_VARIANTS = frozenset({(180, 100), (180, 50), (100, 100), (100, 50), (100, 25)})   # 0.25 deg: 100 only

# -- configuration block (0x74 reply / 0x77 data), TL Table 7-122; STB _parseSickConfigProfile -------------
CONFIG_LEN = 34                 # TL p102 (blocks A..A4)
CONFIG_LEN_OLD = 32             # QM's earlier 32-byte block (A..A3); ARIA sends 32 bytes
CFG_BLANKING = 0                # u16 [cm]
CFG_STOP_THRESHOLD = 2
CFG_PEAK_THRESHOLD = 3
CFG_AVAILABILITY = 4
CFG_MEASURING_MODE = 5
CFG_UNITS = 6
CONFIG_OK = 0x01                # 0xF7 result byte
CONFIG_REFUSED = 0x00


class MeasuringMode(IntEnum):
    """Measuring modes (TL 7.46 block D, p98; STB sick_lms_2xx_measuring_mode_t): range bits and flags."""

    M8_80_FA_FB_DAZZLE = 0x00       # 13-bit range (8 m in mm, 80 m in cm), fields A, B, dazzle (default)
    M8_80_REFLECTOR = 0x01          # 13-bit range, reflector 8 levels
    M8_80_FA_FB_FC = 0x02           # 13-bit range, fields A, B, C
    M16_REFLECTOR = 0x03            # 14-bit range (16 m), reflector 4 levels
    M16_FA_FB = 0x04                # 14-bit range, fields A, B
    M32_REFLECTOR = 0x05            # 15-bit range (32 m), reflector 2 levels (ARIA's default, "1ref")
    M32_FA = 0x06                   # 15-bit range, field A
    M32_IMMEDIATE = 0x0F            # 15-bit range, immediate transmission, no flags


RANGE_BITS: dict[int, int] = {0x00: 13, 0x01: 13, 0x02: 13, 0x03: 14, 0x04: 14, 0x05: 15, 0x06: 15, 0x0F: 15}
MODE_RANGE_MM: dict[int, float] = {13: 8.0, 14: 16.0, 15: 32.0}    # [m] nominal reach in mm units per range bits
LMS200_MAX_RANGE = 80.0         # [m] the LMS200's longest range (data sheet), the cap in cm units


class Units(IntEnum):
    """Measured-value units (config block E; B0 header bits 14-15)."""

    CM = 0x00
    MM = 0x01


UNIT_METRES: dict[int, float] = {Units.CM: 0.01, Units.MM: 0.001}

# -- measured values, 0xB0 (TL 7.5.2, p47-51; STB _parseSickScanProfileB0) --------------------------------
VALUES_COUNT_MASK = 0x03FF          # header bits 0-9: number of values
VALUES_RASTER_SHIFT = 11            # header bits 11-12: partial-scan raster (0.25 deg offsets)
VALUES_PARTIAL_BIT = 0x2000         # header bit 13: partial scan
VALUES_UNIT_SHIFT = 14              # header bits 14-15: 00 cm, 01 mm (1x reserved)
# special values of the 13-bit range (TL 10.8, p124): a value >= 0x1FF7 is no distance
SPECIAL_NO_ECHO = 0x1FFF            # measured value not valid / no stop
SPECIAL_DAZZLE = 0x1FFE
SPECIAL_OVERFLOW = 0x1FFD
SPECIAL_SNR = 0x1FFB
SPECIAL_CHANNEL1 = 0x1FFA
SPECIAL_OVER_MAX = 0x1FF7           # measured value > maximum value
SPECIAL_SPAN = 9                    # 0x1FFF - 0x1FF7 + 1: the top codes of the 13-bit range


def special_floor(bits: int) -> int:
    """The smallest special (no-distance) value of a `bits`-bit range field. TL gives 0x1FF7 for 13 bits;
    for the 14/15-bit modes the same top span is assumed (an extrapolation; ARIA reads them past its maximum)."""
    return (1 << bits) - SPECIAL_SPAN


# -- status byte ending every reply (TL 8, p106) ---------------------------------------------------------
STATUS_OK = 0x10                    # as in TL Table 7-20's example reply: no error, bits 3-4 = 2
STATUS_SEVERITY_MASK = 0x07         # 0 ok, 1 info, 2 warning, 3 error, 4 fatal

# -- identity ------------------------------------------------------------------------------------------
TYPE_STRING = b"LMS200;30106"                       # 0xBA reply (STB _getSickType matches on it)
POWER_ON_TEXT = b"LMS200;301063;V02.10 "             # 0x90 data of a real LMS200 (a published capture)
SOFTWARE_VERSION = b"V02.10 "                       # 7 bytes, status block A
PROM_VERSION = b"V02.10 "                           # 7 bytes, status block B9
STATUS_DATA_LEN = 152                               # 0xB1 data bytes on the wire (TL Table 7-34)
# offsets in the 0xB1 data (after the code; STB _getSickStatus offsets minus one)
ST_SOFTWARE = 0
ST_MODE = 7
ST_ERROR = 8
ST_VARIANT_TYPE = 17
ST_MEASURING_MODE = 101
ST_SCAN_ANGLE = 106
ST_RESOLUTION = 108
ST_BAUD = 115
ST_PERMANENT_BAUD = 118
ST_ADDRESS = 119
ST_UNITS = 121
ST_PROM = 123

# -- timing (TL 2 p19, TL 4.3 p24) ----------------------------------------------------------------------
MIRROR_HZ = 75.0                    # mirror revolutions per second
ROTATIONS_PER_SCAN: dict[int, int] = {100: 1, 50: 2, 25: 4}    # per complete scan, by resolution [1/100 deg]
ACK_WITHIN = 0.060                  # [s] the LMS answers ACK/NAK within 60 ms
MODE_CHANGE_WITHIN = 3.0            # [s] a mode change may take up to 3 s
CONFIG_WITHIN = 7.0                 # [s] writing the configuration may take up to 7 s (QM C.6)
BITS_PER_BYTE = 10                  # 8-N-1


def scan_period(resolution_cdeg: int) -> float:
    """[s] one complete scan at `resolution_cdeg` (mirror-limited; the line may be slower)."""
    return ROTATIONS_PER_SCAN[resolution_cdeg] / MIRROR_HZ


def line_time(nbytes: int, baud: int) -> float:
    """[s] to send `nbytes` at `baud` (8-N-1)."""
    return nbytes * BITS_PER_BYTE / baud


def beams(angle_deg: int, resolution_cdeg: int) -> int:
    """Values per complete scan of a variant: 181 (180/1), 361 (180/0.5), 101, 201, 401 (100/0.25)."""
    return angle_deg * 100 // resolution_cdeg + 1


def first_angle(angle_deg: int) -> float:
    """[rad] the first beam in the sensor frame (0 forward, CCW): the LMS's 0..180 deg is -90..+90 deg,
    and the 100 deg variant covers LMS 40..140 deg (TL 7.5.2, Figures 7-1/7-2)."""
    return -math.radians(angle_deg) / 2
