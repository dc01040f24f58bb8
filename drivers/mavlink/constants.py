"""Every MAVLink number the rover driver uses, once, with its source.

Sources (see shared/protocols/mavlink-rover.md): mavlink/mavlink message_definitions v1.0
(`minimal.xml`, `common.xml`, `ardupilotmega.xml`), ArduPilot Rover (`defines.h`, `mode.h`,
`GCS_Mavlink.cpp`, `Parameters.cpp`), ArduPilot `GCS_Common.cpp` and pymavlink's `mavutil.py`.
Message ids and CRC_EXTRA bytes live in pymavlink's generated dialect; the few repeated here are for
tests and documentation (tests check them against the dialect).

Naming (all drivers, docs/protocols/README.md): a protocol number is a module constant named as its
maker names it, its group's prefix first: the MAVLink XML entry names as they are (MAV_CMD_*,
MAV_RESULT_*, MAVLINK_MSG_ID_* as the generated C headers and pymavlink spell them, ROVER_MODE_* from
ardupilotmega.xml); our own figures (timeouts, ports) are plain UPPER_CASE names with their unit.
"""

from __future__ import annotations

# -- message ids (common.xml / minimal.xml) ---------------------------------------------
MAVLINK_MSG_ID_HEARTBEAT = 0
MAVLINK_MSG_ID_SYS_STATUS = 1
MAVLINK_MSG_ID_PARAM_REQUEST_READ = 20
MAVLINK_MSG_ID_PARAM_REQUEST_LIST = 21
MAVLINK_MSG_ID_PARAM_VALUE = 22
MAVLINK_MSG_ID_PARAM_SET = 23
MAVLINK_MSG_ID_SET_GPS_GLOBAL_ORIGIN = 48
MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN = 49
MAVLINK_MSG_ID_SET_MODE = 11
MAVLINK_MSG_ID_ATTITUDE = 30
MAVLINK_MSG_ID_LOCAL_POSITION_NED = 32
MAVLINK_MSG_ID_GLOBAL_POSITION_INT = 33
MAVLINK_MSG_ID_MISSION_ITEM_REACHED = 46
MAVLINK_MSG_ID_COMMAND_INT = 75
MAVLINK_MSG_ID_REQUEST_DATA_STREAM = 66
MAVLINK_MSG_ID_COMMAND_LONG = 76
MAVLINK_MSG_ID_COMMAND_ACK = 77
MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED = 84
MAVLINK_MSG_ID_DISTANCE_SENSOR = 132
MAVLINK_MSG_ID_HOME_POSITION = 242
MAVLINK_MSG_ID_OBSTACLE_DISTANCE = 330
MAVLINK_MSG_ID_HEARTBEAT_CRC = 50          # minimal.xml HEARTBEAT, as computed by the MAVLink generator

# -- MAV_TYPE / MAV_AUTOPILOT / MAV_STATE / MAV_MODE_FLAG ------------------------------------
MAV_TYPE_GCS = 6
MAV_TYPE_GROUND_ROVER = 10
MAV_TYPE_SURFACE_BOAT = 11
MAV_TYPE_ONBOARD_CONTROLLER = 18
MAV_TYPE_GIMBAL = 26
MAV_TYPE_ADSB = 27
ROVER_TYPES = frozenset({MAV_TYPE_GROUND_ROVER, MAV_TYPE_SURFACE_BOAT})   # Rover GCS_Mavlink.cpp frame_type
NOT_A_VEHICLE = frozenset({MAV_TYPE_GCS, MAV_TYPE_ONBOARD_CONTROLLER, MAV_TYPE_GIMBAL, MAV_TYPE_ADSB})  # mavutil
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_INVALID = 8
MAV_STATE_STANDBY = 3
MAV_STATE_ACTIVE = 4
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 0x01
MAV_MODE_FLAG_MANUAL_INPUT_ENABLED = 0x40
MAV_MODE_FLAG_GUIDED_ENABLED = 0x08
MAV_MODE_FLAG_SAFETY_ARMED = 0x80
MAVLINK_VERSION = 3               # HEARTBEAT.mavlink_version

# -- ArduPilot Rover custom modes (Rover mode.h; ardupilotmega.xml ROVER_MODE) ----------------
ROVER_MODE_MANUAL = 0
ROVER_MODE_ACRO = 1
ROVER_MODE_STEERING = 3
ROVER_MODE_HOLD = 4
ROVER_MODE_LOITER = 5
ROVER_MODE_FOLLOW = 6
ROVER_MODE_DOCK = 8
ROVER_MODE_CIRCLE = 9
ROVER_MODE_AUTO = 10
ROVER_MODE_RTL = 11
ROVER_MODE_SMART_RTL = 12
ROVER_MODE_GUIDED = 15
ROVER_MODE_INITIALIZING = 16      # reported while booting; never settable
# Rover mode.h: modes whose has_manual_input() is true (MANUAL_INPUT_ENABLED in HEARTBEAT base_mode),
# autopilot modes (is_autopilot_mode(): GUIDED_ENABLED), modes that need no position estimate
# (requires_position() false) and modes that cannot be armed in (allows_arming() false)
ROVER_MANUAL_INPUT_MODES = frozenset({ROVER_MODE_MANUAL, ROVER_MODE_ACRO, ROVER_MODE_STEERING, ROVER_MODE_INITIALIZING})
ROVER_AUTOPILOT_MODES = frozenset({ROVER_MODE_LOITER, ROVER_MODE_FOLLOW, ROVER_MODE_DOCK, ROVER_MODE_CIRCLE,
                                   ROVER_MODE_AUTO, ROVER_MODE_RTL, ROVER_MODE_SMART_RTL, ROVER_MODE_GUIDED})
ROVER_NO_POSITION_MODES = frozenset({ROVER_MODE_MANUAL, ROVER_MODE_ACRO, ROVER_MODE_STEERING, ROVER_MODE_HOLD})
ROVER_UNARMABLE_MODES = frozenset({ROVER_MODE_RTL, ROVER_MODE_SMART_RTL})
ROVER_MODES = {0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
               8: "DOCK", 9: "CIRCLE", 10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED", 16: "INITIALISING"}

# -- MAV_CMD / MAV_RESULT -------------------------------------------------------------------
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_DO_REPOSITION = 192
MAV_DO_REPOSITION_FLAGS_CHANGE_MODE = 1
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_SET_MESSAGE_INTERVAL = 511
MAV_CMD_GET_HOME_POSITION = 410
MAV_CMD_REQUEST_MESSAGE = 512
MAV_RESULT_ACCEPTED = 0
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3
MAV_RESULT_FAILED = 4
MAV_MISSION_ACCEPTED = 0
MAV_MISSION_ERROR = 1

# -- MAV_SYS_STATUS_SENSOR (SYS_STATUS onboard_control_sensors_present / enabled / health) -----
MAV_SYS_STATUS_SENSOR_3D_GYRO = 0x01
MAV_SYS_STATUS_SENSOR_3D_ACCEL = 0x02
MAV_SYS_STATUS_SENSOR_3D_MAG = 0x04
MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE = 0x08
MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS = 0x8000
MAV_SYS_STATUS_GEOFENCE = 0x100000    # healthy (not breached) even with no fence, as GCS_Common.cpp reports it
MAV_SYS_STATUS_AHRS = 0x200000
MAV_SYS_STATUS_SENSOR_BATTERY = 0x2000000
MAV_SYS_STATUS_SENSOR_PROXIMITY = 0x4000000
MAV_SYS_STATUS_PREARM_CHECK = 0x10000000

# -- MAV_PARAM_TYPE (PARAM_VALUE / PARAM_SET param_type; ArduPilot AP_Int8/16/32, AP_Float) ---
MAV_PARAM_TYPE_INT8 = 2
MAV_PARAM_TYPE_INT16 = 4
MAV_PARAM_TYPE_INT32 = 6
MAV_PARAM_TYPE_REAL32 = 9
PARAM_ID_LEN = 16                 # param_id: char[16], NUL-padded (no NUL when 16 long)

# -- MAV_DATA_STREAM groups (ArduPilot GCS_Mavlink.cpp) -------------------------------------
MAV_DATA_STREAM_ALL = 0
MAV_DATA_STREAM_EXTENDED_STATUS = 2        # SYS_STATUS
MAV_DATA_STREAM_POSITION = 6               # LOCAL_POSITION_NED (and GLOBAL_POSITION_INT)
MAV_DATA_STREAM_EXTRA1 = 10                # ATTITUDE
MAV_DATA_STREAM_EXTRA3 = 12                # DISTANCE_SENSOR ...; the emulator adds OBSTACLE_DISTANCE here
DEFAULT_STREAM_RATE = 1.0         # [Hz] ArduPilot's default per-group rate (SRn_* parameters)

# -- MAV_FRAME / POSITION_TARGET_TYPEMASK (common.xml; Rover wiki "Rover Commands in Guided Mode") --
MAV_FRAME_GLOBAL = 0
MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
MAV_FRAME_LOCAL_OFFSET_NED = 7
MAV_FRAME_BODY_NED = 8
MAV_FRAME_BODY_OFFSET_NED = 9
MAV_FRAME_BODY_FRD = 12
POSITION_TARGET_TYPEMASK_X_IGNORE = 1
POSITION_TARGET_TYPEMASK_Y_IGNORE = 2
POSITION_TARGET_TYPEMASK_Z_IGNORE = 4
POSITION_TARGET_TYPEMASK_VX_IGNORE = 8
POSITION_TARGET_TYPEMASK_VY_IGNORE = 16
POSITION_TARGET_TYPEMASK_VZ_IGNORE = 32
POSITION_TARGET_TYPEMASK_AX_IGNORE = 64
POSITION_TARGET_TYPEMASK_AY_IGNORE = 128
POSITION_TARGET_TYPEMASK_AZ_IGNORE = 256
POSITION_TARGET_TYPEMASK_FORCE_SET = 512
POSITION_TARGET_TYPEMASK_YAW_IGNORE = 1024
POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE = 2048
MASK_VELOCITY = 0x0DE7            # 3559 (the wiki's "velocity"; z ignored too)
MASK_VELOCITY_MAVPROXY = 0x0FC7   # 4039: MAVProxy's `velocity x y z` (vz not ignored; Rover ignores z)
MASK_YAW_RATE = 0x05FF            # 1535
MASK_VELOCITY_YAW_RATE = 0x05E7   # 1511: "turn rate and speed"
MASK_POSITION = 0x0DF8            # 3576: MAVProxy's `position x y z` (x, y, z only)
MASK_YAW = 0x09FF                 # 2559: heading only
MASK_VELOCITY_YAW = 0x09C7        # 2503: velocity and heading
# Rover defines.h: a group counts as ignored when any of its x / y bits is set (z is not looked at)
ROVER_POS_IGNORE = POSITION_TARGET_TYPEMASK_X_IGNORE | POSITION_TARGET_TYPEMASK_Y_IGNORE
ROVER_VEL_IGNORE = POSITION_TARGET_TYPEMASK_VX_IGNORE | POSITION_TARGET_TYPEMASK_VY_IGNORE
ROVER_ACC_IGNORE = POSITION_TARGET_TYPEMASK_AX_IGNORE | POSITION_TARGET_TYPEMASK_AY_IGNORE

# -- MAV_DISTANCE_SENSOR / OBSTACLE_DISTANCE --------------------------------------------------
MAV_DISTANCE_SENSOR_LASER = 0
MAV_SENSOR_ROTATION_NONE = 0      # orientation 0..7: sectors every 45 deg (clockwise for ArduPilot)
MAV_SENSOR_ROTATION_YAW_315 = 7
PROXIMITY_SENSOR_ID_START = 10    # AP_Proximity.h: DISTANCE_SENSOR ids 10.. are proximity sectors
PROXIMITY_SECTORS = 8             # ArduPilot's send_proximity: one DISTANCE_SENSOR per 45-deg sector
PRX_TYPE_NONE = 0                 # PRX1_TYPE: 0 none, 2 MAVLink, 10 SITL
PRX_TYPE_MAVLINK = 2
PRX_TYPE_SITL = 10
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
# EKF origin the backend sets on a vehicle that has none (indoors, no GPS): UFMG, Belo Horizonte
# (where the built-in worlds come from); any valid latitude/longitude works.
DEFAULT_ORIGIN = (-19.8697, -43.9637, 800.0)    # [deg, deg, m]
ORIGIN_WAIT = 0.5                 # [s] how long the backend waits for GPS_GLOBAL_ORIGIN before setting one
DEG_E7 = 10_000_000               # latitude/longitude scale of int32 fields
