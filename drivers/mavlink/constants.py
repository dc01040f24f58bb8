"""Every MAVLink number the rover driver uses, once, with its source.

Sources (see shared/protocols/mavlink-rover.md): mavlink/mavlink message_definitions v1.0
(`minimal.xml`, `common.xml`), ArduPilot Rover (`defines.h`, `mode.h`, `GCS_Mavlink.cpp`,
`Parameters.cpp`) and pymavlink's `mavutil.py`. Message ids and CRC_EXTRA bytes live in pymavlink's
generated dialect; the few repeated here are for tests and documentation.
"""

from __future__ import annotations

# -- message ids (common.xml / minimal.xml) ---------------------------------------------
MSG_HEARTBEAT = 0
MSG_SYS_STATUS = 1
MSG_SET_MODE = 11
MSG_ATTITUDE = 30
MSG_LOCAL_POSITION_NED = 32
MSG_REQUEST_DATA_STREAM = 66
MSG_COMMAND_LONG = 76
MSG_COMMAND_ACK = 77
MSG_SET_POSITION_TARGET_LOCAL_NED = 84
MSG_OBSTACLE_DISTANCE = 330
CRC_EXTRA_HEARTBEAT = 50          # minimal.xml HEARTBEAT, as computed by the MAVLink generator

# -- MAV_TYPE / MAV_AUTOPILOT / MAV_STATE / MAV_MODE_FLAG ------------------------------------
MAV_TYPE_GCS = 6
MAV_TYPE_GROUND_ROVER = 10
MAV_TYPE_SURFACE_BOAT = 11
MAV_TYPE_ONBOARD_CONTROLLER = 18
MAV_TYPE_GIMBAL = 26
MAV_TYPE_ADSB = 27
NOT_A_VEHICLE = frozenset({MAV_TYPE_GCS, MAV_TYPE_ONBOARD_CONTROLLER, MAV_TYPE_GIMBAL, MAV_TYPE_ADSB})  # mavutil
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_INVALID = 8
MAV_STATE_STANDBY = 3
MAV_STATE_ACTIVE = 4
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 0x01
MAV_MODE_FLAG_GUIDED_ENABLED = 0x08
MAV_MODE_FLAG_SAFETY_ARMED = 0x80
MAVLINK_VERSION = 3               # HEARTBEAT.mavlink_version

# -- ArduPilot Rover custom modes (Rover mode.h) ---------------------------------------------
ROVER_MANUAL = 0
ROVER_HOLD = 4
ROVER_GUIDED = 15
ROVER_MODES = {0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
               8: "DOCK", 9: "CIRCLE", 10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED", 16: "INITIALISING"}

# -- MAV_CMD / MAV_RESULT -------------------------------------------------------------------
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_SET_MESSAGE_INTERVAL = 511
MAV_CMD_REQUEST_MESSAGE = 512
MAV_RESULT_ACCEPTED = 0
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3

# -- MAV_DATA_STREAM groups (ArduPilot GCS_Mavlink.cpp) -------------------------------------
STREAM_ALL = 0
STREAM_EXTENDED_STATUS = 2        # SYS_STATUS
STREAM_POSITION = 6               # LOCAL_POSITION_NED (and GLOBAL_POSITION_INT)
STREAM_EXTRA1 = 10                # ATTITUDE
STREAM_EXTRA3 = 12                # DISTANCE_SENSOR ...; the emulator adds OBSTACLE_DISTANCE here
DEFAULT_STREAM_RATE = 1.0         # [Hz] ArduPilot's default per-group rate (SRn_* parameters)

# -- MAV_FRAME / POSITION_TARGET_TYPEMASK (common.xml; Rover wiki "Rover Commands in Guided Mode") --
MAV_FRAME_GLOBAL = 0
MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_BODY_NED = 8
MAV_FRAME_BODY_OFFSET_NED = 9
MAV_FRAME_BODY_FRD = 12
IGNORE_X, IGNORE_Y, IGNORE_Z = 1, 2, 4
IGNORE_VX, IGNORE_VY, IGNORE_VZ = 8, 16, 32
IGNORE_AX, IGNORE_AY, IGNORE_AZ = 64, 128, 256
FORCE_SET = 512
IGNORE_YAW, IGNORE_YAW_RATE = 1024, 2048
MASK_VELOCITY = 0x0DE7            # 3559
MASK_YAW_RATE = 0x05FF            # 1535
MASK_VELOCITY_YAW_RATE = 0x05E7   # 1511: "turn rate and speed"

# -- MAV_DISTANCE_SENSOR / OBSTACLE_DISTANCE --------------------------------------------------
MAV_DISTANCE_SENSOR_LASER = 0
OBSTACLE_SECTORS = 72             # distances[72]
OBSTACLE_UNKNOWN = 65535          # UINT16_MAX: unknown / unused element

# -- ids, timeouts, ports ----------------------------------------------------------------------
GCS_SYSTEM_ID = 255               # mavutil's default source_system (the usual GCS id, SYSID_MYGCS)
GCS_COMPONENT_ID = 190            # MAV_COMP_ID_MISSIONPLANNER
VEHICLE_SYSTEM_ID = 1
VEHICLE_COMPONENT_ID = 1          # MAV_COMP_ID_AUTOPILOT1
HEARTBEAT_PERIOD = 1.0            # [s] both ways (mavlink.io heartbeat protocol)
GUID_TIMEOUT = 3.0                # [s] Rover stops when GUIDED velocity targets stop (Parameters.cpp)
DEFAULT_UDP_PORT = 14550          # the GCS port vehicles / MAVProxy send to
DEFAULT_TCP_PORT = 5760           # ArduPilot SITL SERIAL0
DEFAULT_BAUD = 115200             # mavutil's default; telemetry radios are often 57600
