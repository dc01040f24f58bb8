"""Every number of the Yujin Kobuki serial protocol, once, with its source.

Sources:

- [dox] kobuki_core 0.7.12 `kobuki_driver/doxygen/english/en_appendix_protocol.dox` and
  `en_appendix_parameters.dox` (framing, tables, geometry constants).
- [drv] kobuki_core `kobuki_driver` sources: `src/driver/kobuki.cpp` (115200 8N1, packet finder
  configured with a 1-byte length field and 256-byte max payload, XOR check from the length byte on,
  0.1 s stream timeout), `src/driver/command.cpp` (command IDs and lengths, gp_out 0x00F0),
  `src/driver/diff_drive.cpp` (bias 0.23 m, epsilon 1e-4, int16 bounds, tick_to_rad),
  `include/kobuki_driver/packets/*.hpp` (feedback sizes), `packets/firmware.hpp` (old 2-byte
  firmware codes).
- [rst] kobuki-base/kobuki_documentation `doc/protocol.rst` (20 ms stream, "XOR (length + payload)").

Where the documents and the driver disagree the driver is followed (kobuki.md, "Doc errata").
Values in the protocol's own units carry the unit in their name (`_MM`, `_MS`, `_CDEG`).
"""

from __future__ import annotations

from typing import Final

# --- physical link [drv kobuki.cpp: serial.open(..., BaudRate_115200, DataBits_8, StopBits_1, NoParity)]
BAUD_RATE: Final = 115200
DATA_BITS: Final = 8
STOP_BITS: Final = 1
# Flow control: none documented (UNCONFIRMED; the driver opens the port without any).
FTDI_VENDOR_ID: Final = 0x0403   # [drv kobuki_ftdi/57-kobuki.rules]
FTDI_PRODUCT_ID: Final = 0x6001
DEFAULT_PORT: Final = "/dev/kobuki"
FEEDBACK_PERIOD: Final = 0.020   # [s] feedback stream, 50 Hz from power-on [dox, rst]
STREAM_TIMEOUT: Final = 0.1      # [s] no frame for this long: driver marks the robot "not alive" [drv]
CMD_VEL_TIMEOUT: Final = 0.6     # [s] kobuki_node zeroes commands after this (host software only)

# --- framing [dox "Structure of Bytestream"; drv PacketFinder]
HEADER_0: Final = 0xAA
HEADER_1: Final = 0x55
HEADER: Final = bytes((HEADER_0, HEADER_1))
# Frame = HEADER | LENGTH (1 byte, payload bytes only) | PAYLOAD | CHECKSUM (1 byte).
# Checksum = XOR of the length byte and every payload byte (headers excluded) [rst]; the driver
# verifies by XOR-ing everything from the length byte through the checksum and expecting 0 [drv].
FRAME_OVERHEAD: Final = 4         # header 2 + length 1 + checksum 1 [bytes]
MIN_PAYLOAD_LEN: Final = 3        # one sub-payload: ID + LEN + at least one data byte [dox]
# The driver's finder accepts a 256-byte payload, but a 1-byte length field cannot say more than 255.
MAX_PAYLOAD_LEN: Final = 255
MAX_FRAME_LEN: Final = MAX_PAYLOAD_LEN + FRAME_OVERHEAD
# Sub-payload = ID (1) | LEN (1, data bytes that follow) | DATA (LEN). The driver calls anything under
# 3 bytes "too small sub-payload" (kobuki.cpp fixPayload), so LEN >= 1.
SUBPAYLOAD_HEADER_LEN: Final = 2
MIN_SUBPAYLOAD_DATA_LEN: Final = 1

# --- command sub-payload IDs and data lengths (host -> robot) [drv command.cpp; dox table]
CMD_BASE_CONTROL: Final = 1          # int16 speed [mm/s], int16 radius [mm]
CMD_SOUND: Final = 3                 # uint16 note, uint8 duration [ms]
CMD_SOUND_SEQUENCE: Final = 4        # uint8 sequence number
CMD_REQUEST_EXTRA: Final = 9         # uint16 flags
CMD_CHANGE_FRAME: Final = 10         # uint8 frame id; reserved in the docs, purpose UNCONFIRMED
CMD_REQUEST_EEPROM: Final = 11       # uint8 frame id; reserved in the docs, purpose UNCONFIRMED
CMD_GENERAL_PURPOSE_OUTPUT: Final = 12  # uint16 flags
# Doc erratum: the docs give header 1 for both gain commands; the driver sends 13 (LEN 13), 14 (LEN 1).
CMD_SET_CONTROLLER_GAIN: Final = 13  # uint8 type, uint32 P, I, D (gain x 1000)
CMD_GET_CONTROLLER_GAIN: Final = 14  # uint8 unused (0); answered by FB_CONTROLLER_INFO

CMD_BASE_CONTROL_LEN: Final = 4
CMD_SOUND_LEN: Final = 3
CMD_SOUND_SEQUENCE_LEN: Final = 1
CMD_REQUEST_EXTRA_LEN: Final = 2
CMD_CHANGE_FRAME_LEN: Final = 1
CMD_REQUEST_EEPROM_LEN: Final = 1
CMD_GENERAL_PURPOSE_OUTPUT_LEN: Final = 2
CMD_SET_CONTROLLER_GAIN_LEN: Final = 13
CMD_GET_CONTROLLER_GAIN_LEN: Final = 1

# Base Control special radii [dox "Base Control"; drv diff_drive.cpp]
RADIUS_STRAIGHT_MM: Final = 0   # speed is the forward speed
RADIUS_ROTATE_MM: Final = 1     # pure rotation; speed is the wheel speed, > 0 = counter-clockwise
# Radius -1 is not special in any source; how the firmware treats it is UNCONFIRMED (never sent).
TWIST_EPSILON: Final = 0.0001   # [m/s] and [rad/s] thresholds of DiffDrive::velocityCommands [drv]
INT16_MIN: Final = -32768
INT16_MAX: Final = 32767

# Sound: note = 1 / (f * 0.00000275), f in Hz [dox "Sound"]
SOUND_NOTE_PERIOD: Final = 0.00000275  # [s] one note-count
# Sound sequence numbers [dox "Sound Sequence"; drv command.hpp SoundSequences]
SOUND_ON: Final = 0
SOUND_OFF: Final = 1
SOUND_RECHARGE: Final = 2
SOUND_BUTTON: Final = 3
SOUND_ERROR: Final = 4
SOUND_CLEANING_START: Final = 5
SOUND_CLEANING_END: Final = 6

# Request Extra flags [dox "Request Extra"; drv Command::GetVersionInfo sends 0x0B]
REQUEST_HARDWARE_VERSION: Final = 0x0001
REQUEST_FIRMWARE_VERSION: Final = 0x0002
REQUEST_UDID: Final = 0x0008
REQUEST_VERSION_INFO: Final = REQUEST_HARDWARE_VERSION | REQUEST_FIRMWARE_VERSION | REQUEST_UDID

# General Purpose Output flags [dox "General Purpose Output"; drv command.cpp]
GPO_DIGITAL_0: Final = 0x0001
GPO_DIGITAL_1: Final = 0x0002
GPO_DIGITAL_2: Final = 0x0004
GPO_DIGITAL_3: Final = 0x0008
GPO_POWER_3V3: Final = 0x0010
GPO_POWER_5V: Final = 0x0020
GPO_POWER_12V_5A: Final = 0x0040
GPO_POWER_12V_1A5: Final = 0x0080
GPO_LED1_RED: Final = 0x0100
GPO_LED1_GREEN: Final = 0x0200
GPO_LED2_RED: Final = 0x0400
GPO_LED2_GREEN: Final = 0x0800
GPO_DEFAULT: Final = 0x00F0  # driver's initial state: all external power on, LEDs off [drv]

# Controller gains: uint32 = gain x 1000 [dox "Set Controller Gain"]
GAIN_TYPE_FACTORY: Final = 0
GAIN_TYPE_USER: Final = 1
GAIN_SCALE: Final = 1000
FACTORY_P_X1000: Final = 100000
FACTORY_I_X1000: Final = 100
FACTORY_D_X1000: Final = 2000

# --- feedback sub-payload IDs and data lengths (robot -> host) [drv payload_headers.hpp; dox]
FB_BASIC_SENSOR_DATA: Final = 1
FB_DOCKING_IR: Final = 3
FB_INERTIAL_SENSOR: Final = 4
FB_CLIFF: Final = 5
FB_CURRENT: Final = 6
FB_HARDWARE_VERSION: Final = 10
FB_FIRMWARE_VERSION: Final = 11
FB_RAW_GYRO: Final = 13
FB_GENERAL_PURPOSE_INPUT: Final = 16
FB_UDID: Final = 19
FB_CONTROLLER_INFO: Final = 21  # doc erratum: docs show header 1, length 21; driver: ID 21, LEN 13

FB_BASIC_SENSOR_DATA_LEN: Final = 15
FB_DOCKING_IR_LEN: Final = 3
FB_INERTIAL_SENSOR_LEN: Final = 7
FB_CLIFF_LEN: Final = 6
# The docs draw the two current fields as 2 bytes each but give LEN 2; the driver reads one byte each.
FB_CURRENT_LEN: Final = 2
FB_VERSION_LEN: Final = 4          # patch, minor, major, 0 (uint32 LE = major<<16 | minor<<8 | patch)
FB_VERSION_LEGACY_LEN: Final = 2   # first firmwares: uint16 code [drv packets/firmware.hpp]
FB_RAW_GYRO_HEADER_LEN: Final = 2  # frame id, followed data length (uint16 words = 3N)
FB_GENERAL_PURPOSE_INPUT_LEN: Final = 16
FB_UDID_LEN: Final = 12
FB_CONTROLLER_INFO_LEN: Final = 13
STREAMED_FEEDBACK: Final = (FB_BASIC_SENSOR_DATA, FB_DOCKING_IR, FB_INERTIAL_SENSOR, FB_CLIFF,
                            FB_CURRENT, FB_RAW_GYRO, FB_GENERAL_PURPOSE_INPUT)  # every frame [dox]

# Old 2-byte firmware codes and their uint32 versions [drv packets/firmware.hpp deserialise]
FIRMWARE_LEGACY_CODES: Final = {123: 0x010000, 10100: 0x010100, 110: 0x010100,
                                10101: 0x010101, 111: 0x010101}
FIRMWARE_MAJOR: Final = 1                              # driver requires major 1 [drv firmware.hpp]
FIRMWARE_RECOMMENDED: Final = (0x010104, 0x010200)     # 1.1.4 and 1.2.0 [drv version_info.hpp]

# Basic sensor data bit masks [dox "Basic Sensor Data"; drv core_sensors.hpp]
BUMPER_RIGHT: Final = 0x01
BUMPER_CENTRE: Final = 0x02
BUMPER_LEFT: Final = 0x04
WHEEL_DROP_RIGHT: Final = 0x01
WHEEL_DROP_LEFT: Final = 0x02
CLIFF_RIGHT: Final = 0x01
CLIFF_CENTRE: Final = 0x02
CLIFF_LEFT: Final = 0x04
BUTTON_0: Final = 0x01
BUTTON_1: Final = 0x02
BUTTON_2: Final = 0x04
OVERCURRENT_LEFT: Final = 0x01
OVERCURRENT_RIGHT: Final = 0x02
# Charger byte: bit 0x10 = adapter (vs dock); low nibble 0 discharging, 2 charged, 6 charging.
CHARGER_DISCHARGING: Final = 0
CHARGER_DOCKING_CHARGED: Final = 2
CHARGER_DOCKING_CHARGING: Final = 6
CHARGER_ADAPTER_CHARGED: Final = 18
CHARGER_ADAPTER_CHARGING: Final = 22
CHARGER_ADAPTER_BIT: Final = 0x10
CHARGER_STATE_MASK: Final = 0x0F
CHARGER_STATE_CHARGED: Final = 2
CHARGER_STATE_CHARGING: Final = 6
# Battery byte is in 0.1 V; driver thresholds [drv battery.cpp, parameters.hpp]
BATTERY_SCALE: Final = 0.1          # [V] per count
BATTERY_CAPACITY_V: Final = 16.5    # [V]
BATTERY_LOW_V: Final = 14.0         # [V]
BATTERY_DANGEROUS_V: Final = 13.2   # [V]
CURRENT_SCALE: Final = 0.010        # [A] per count (10 mA)

# Docking IR bits, same in each of the right/central/left receivers [dox "Docking IR"]
DOCK_NEAR_LEFT: Final = 0x01
DOCK_NEAR_CENTER: Final = 0x02
DOCK_NEAR_RIGHT: Final = 0x04
DOCK_FAR_CENTER: Final = 0x08
DOCK_FAR_LEFT: Final = 0x10
DOCK_FAR_RIGHT: Final = 0x20

# ADC inputs (cliff PSDs, analog GPIO): 12 bits over 0..3.3 V [dox]
ADC_MAX: Final = 4095
ADC_FULL_SCALE: Final = 3.3  # [V]

# Digital inputs 0..3 (General Purpose Input) [dox]
GPI_DIGITAL_0: Final = 0x01
GPI_DIGITAL_1: Final = 0x02
GPI_DIGITAL_2: Final = 0x04
GPI_DIGITAL_3: Final = 0x08

# --- unit facts
# Inertial sensor: angle in hundredths of a degree, rate in hundredths of a degree per second [drv
# kobuki.cpp getHeading/getAngularVelocity]. The driver reports it as the ROS yaw (REP 103), hence
# counter-clockwise positive (sign inferred from that use, not stated in the sources).
INERTIA_SCALE: Final = 0.01   # [deg] (or [deg/s]) per count
# Raw gyro (L3G4200D): 0.00875 deg/s per digit; axes rotated 90 deg CCW about z:
# robot x = -raw_y, robot y = raw_x, robot z = raw_z [dox "Raw Data Of 3-axis Gyro"].
RAW_GYRO_SCALE: Final = 0.00875  # [deg/s] per digit
RAW_GYRO_MAX_SAMPLES: Final = 8  # driver buffer: MAX_DATA_SIZE = 3 * 8 words [drv three_axis_gyro.hpp]
TIMESTAMP_MODULUS: Final = 65536  # basic sensor timestamp [ms] wraps 65535 -> 0
ENCODER_MODULUS: Final = 65536    # encoders [ticks] wrap at 65536

# Geometry and odometry [dox en_appendix_parameters.dox; drv diff_drive.cpp]
WHEEL_BASE: Final = 0.230       # [m] "bias", wheel to wheel
WHEEL_BASE_MM: Final = 230.0    # [mm]
WHEEL_RADIUS: Final = 0.035     # [m]
WHEEL_WIDTH: Final = 0.021      # [m]
ENCODER_TICKS_PER_MOTOR_REV: Final = 52
GEAR_RATIO: Final = 6545 / 132  # motor : wheel = 49.5833
# Tick facts as printed in the parameter appendix (the driver stores tick_to_rad as a C float).
TICK_TO_METRE: Final = 0.000085292090497737556558    # [m/tick]
TICK_TO_RAD: Final = 0.002436916871363930187454      # [rad/tick] of the wheel
METRE_TO_TICK: Final = 11724.41658029856624751591    # [tick/m]
MM_TO_TICK: Final = 11.72441658029856624751591       # [tick/mm]
# Maximum speeds of the base: UNCONFIRMED (not stated in kobuki_core).
