"""Every number of Slamtec's RPLidar serial protocol (A1/A2), once, with its source.

Sources (docs/protocols/rplidar.md has the details):

- [proto] Slamtec, "RPLIDAR Interface Protocol and Application Notes" (A1/A2 series): request and
  response-descriptor format, the command bytes, GET_INFO / GET_HEALTH / GET_SAMPLERATE replies,
  the 5-byte SCAN measurement node, the STOP/RESET waits, the angle convention (clockwise).
- [sdk] Slamtec rplidar_sdk `sl_lidar_cmd.h` / `rplidar_cmd.h`: the same constants by name
  (RPLIDAR_CMD_*, RPLIDAR_ANS_TYPE_*, RPLIDAR_RESP_MEASUREMENT_*), SET_MOTOR_PWM 0xF0, and the
  launch files' baud rates (A1, A2M8: 115200; A2M7/A2M12, A3: 256000).
- [cap] public outputs of a real A1M8 through rplidar-roboticia: GET_INFO model 24, firmware 1.29,
  hardware 7; GET_SAMPLERATE 508 us standard, 254 us express.
- [rr] rplidar-roboticia 0.9.5 (PyPI): what a common client sends (SET_MOTOR_PWM 660 before SCAN,
  DTR low to spin an A1's motor through its USB adapter board).

Values in the protocol's own units carry the unit in their name (`_Q6`, `_Q2`, `_US`, `_MM`).
"""

from __future__ import annotations

from typing import Final

# --- link [proto; sdk launch files]
BAUD_A1: Final = 115200
BAUD_A2M8: Final = 115200
BAUD_HIGH_SPEED: Final = 256000     # A2M7 / A2M12, A3
# The A1/A2 USB adapter board drives the motor from DTR: DTR low spins it [rr]
STOP_WAIT: Final = 0.001            # [s] after STOP before the next request [proto]
RESET_WAIT: Final = 0.002           # [s] after RESET [proto]; the device reboots

# --- requests [proto "Request packets' format"]: A5 CMD, or A5 CMD SIZE PAYLOAD CHECKSUM
SYNC_BYTE: Final = 0xA5             # RPLIDAR_CMD_SYNC_BYTE
CMDFLAG_HAS_PAYLOAD: Final = 0x80   # commands >= 0x80 carry a payload [sdk]
# checksum = XOR of every byte before it, 0xA5 included [proto]
CMD_STOP: Final = 0x25              # no response
CMD_RESET: Final = 0x40             # no response (the device reboots)
CMD_SCAN: Final = 0x20              # multiple response: measurement nodes
CMD_FORCE_SCAN: Final = 0x21        # the same without waiting for a stable motor speed
CMD_EXPRESS_SCAN: Final = 0x82      # payload: working mode + 4 reserved bytes
CMD_GET_INFO: Final = 0x50
CMD_GET_HEALTH: Final = 0x52
CMD_GET_SAMPLERATE: Final = 0x59
CMD_SET_MOTOR_PWM: Final = 0xF0     # payload: uint16 PWM 0..1023 (A2/A3 motor control) [sdk, rr]
MAX_PAYLOAD: Final = 255            # the size byte

# --- response descriptor [proto "Response packets' format"]: A5 5A, u32 LE (bits 0-29 length,
# bits 30-31 send mode), data type
SYNC_BYTE2: Final = 0x5A
DESCRIPTOR_LEN: Final = 7
SEND_MODE_SINGLE: Final = 0x0
SEND_MODE_MULTI: Final = 0x1
SEND_MODE_SHIFT: Final = 30
LENGTH_MASK: Final = (1 << 30) - 1
ANS_TYPE_DEVINFO: Final = 0x04
ANS_TYPE_DEVHEALTH: Final = 0x06
ANS_TYPE_MEASUREMENT: Final = 0x81
ANS_TYPE_MEASUREMENT_CAPSULED: Final = 0x82
ANS_TYPE_SAMPLE_RATE: Final = 0x15
DEVINFO_LEN: Final = 20             # model, firmware minor, firmware major, hardware, serial[16]
SERIAL_LEN: Final = 16
HEALTH_LEN: Final = 3               # status, error code (u16 LE)
SAMPLE_RATE_LEN: Final = 4          # Tstandard, Texpress [us] (u16 LE each)

# --- health [proto]
HEALTH_GOOD: Final = 0
HEALTH_WARNING: Final = 1
HEALTH_ERROR: Final = 2             # protection stop: RESET to recover

# --- measurement node [proto "SCAN ... response"]: 5 bytes
#   byte 0: quality (6 bits) << 2 | !S << 1 | S   (S: first node of a new turn)
#   byte 1: angle_q6 bits 0-6 << 1 | C            (C: check bit, always 1)
#   byte 2: angle_q6 bits 7-14
#   bytes 3-4: distance_q2 (u16 LE)
# angle = angle_q6 / 64 deg, clockwise seen from above, 0 at the front; distance = distance_q2 / 4 mm,
# 0 = no valid measurement.
NODE_LEN: Final = 5
NODE_SYNCBIT: Final = 0x01
NODE_SYNCBIT_INV: Final = 0x02
NODE_QUALITY_SHIFT: Final = 2
NODE_CHECKBIT: Final = 0x01
NODE_ANGLE_SHIFT: Final = 1
ANGLE_Q6_PER_DEG: Final = 64
DISTANCE_Q2_PER_MM: Final = 4
ANGLE_Q6_TURN: Final = 360 * 64     # angles at or past this are not valid
QUALITY_MAX: Final = 63

# --- express scan, legacy capsules [proto "EXPRESS_SCAN"; sdk _capsuleToNormal]: request payload
# working mode 0 + 4 reserved bytes; descriptor A5 5A 54 00 00 40 82; 84-byte capsules:
#   byte 0: 0xA << 4 | checksum bits 0-3; byte 1: 0x5 << 4 | checksum bits 4-7 (XOR of bytes 2..83)
#   bytes 2-3: start angle q6 (15 bits) | start flag << 15 (first capsule after the request)
#   16 cabins of 5 bytes: u16 distance1 [mm] << 2 | dθ1 bits 4-5, u16 distance2 << 2 | dθ2 bits 4-5,
#   dθ1 bits 0-3 | dθ2 bits 0-3 << 4; dθ [1/8 deg] is subtracted from the sample's angle [sdk].
EXPRESS_PAYLOAD: Final = bytes(5)
EXPRESS_CAPSULE_LEN: Final = 84
EXPRESS_SYNC_1: Final = 0xA
EXPRESS_SYNC_2: Final = 0x5
EXPRESS_SYNCBIT: Final = 1 << 15
EXPRESS_CABINS: Final = 16
EXPRESS_SAMPLES: Final = 32
EXPRESS_DISTANCE_MAX_MM: Final = (1 << 14) - 1

# --- models. A1M8 [cap]: model 24 (0x18; the SDK reads the series in the high nibble), firmware
# 1.29, hardware 7; 508 us per sample in SCAN mode (1968 samples/s), 5.5 Hz typical, 0.15-12 m.
A1M8_MODEL: Final = 0x18
A1M8_FIRMWARE: Final = (1, 29)
A1M8_HARDWARE: Final = 7
A1M8_SAMPLE_US: Final = 508
A1M8_EXPRESS_US: Final = 254
A1_RANGE_MIN_MM: Final = 150
A1_RANGE_MAX_MM: Final = 12000
# A2M8: series 2 in the high nibble [sdk]; 4000 samples/s in SCAN mode at about 10 Hz, 0.15-12 m.
# Firmware and hardware numbers below are an emulator's choice, not a capture.
A2M8_MODEL: Final = 0x28
A2M8_FIRMWARE: Final = (1, 27)
A2M8_HARDWARE: Final = 5
A2M8_SAMPLE_US: Final = 250
A2M8_EXPRESS_US: Final = 125
