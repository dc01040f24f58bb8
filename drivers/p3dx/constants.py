"""Every number of the ARIA / Pioneer robot protocol (ARCOS, MobileSim, AMRISim), once.

The specification is `shared/protocols/aria-sip.md`; each group below names its section as
"§n". Where that page says UNCONFIRMED, the comment gives what AriaCoda (reedhedges/AriaCoda) or
MobileSim 0.9.8 (thommann/MobileSim) sources show. Units are those of the wire: mm, mm/s,
degrees, deg/s, decivolts, and the raw "units" of the SIP that need a conversion factor.
"""

from __future__ import annotations

# --- §1 Transport ------------------------------------------------------------------------------
SIM_TCP_PORT = 8101                 # MobileSim/AMRISim first robot; more robots take 8102, 8103, ...
SERIAL_BAUD = 9600                  # ARIA -robotBaud default; 8 data bits, no parity, 1 stop bit
SWITCH_TO_BAUD = 38400              # p3dx.p SwitchToBaudRate (serial only, CONFIG autobaud == 2)
HOSTBAUD_CODES = {9600: 0, 19200: 1, 38400: 2, 57600: 3, 115200: 4}  # §4 HOSTBAUD argument
AUTOBAUD_ENABLED = 2                # §1: CONFIG autobaud byte value that allows HOSTBAUD

# --- §2 Framing --------------------------------------------------------------------------------
HEADER = b"\xfa\xfb"                # every packet, both directions
HEADER_0 = 0xFA
HEADER_1 = 0xFB
MIN_COUNT = 3                       # COUNT = 1 (ID) + len(DATA) + 2 (checksum)
# §2: "the protocol limit is 200 bytes of packet". ARIA's receiver comment reads the limit as
# COUNT <= 200 ("if c > 200 than there is a problem, spec says packet max size is 200") although
# it only rejects COUNT > 255; decoders take `max_count` to relax it.
MAX_COUNT = 200
COUNT_OVERHEAD = 3                  # ID + 2 checksum bytes counted in COUNT
FRAME_OVERHEAD = 5                  # header (2) + COUNT (1) + checksum (2) around ID + DATA
MAX_DATA = MAX_COUNT - COUNT_OVERHEAD
BODY_GAP_S = 0.1                    # §2.1: ARIA drops a packet whose body has a gap > 100 ms

# --- §2.2 Command argument type bytes -----------------------------------------------------------
ARG_INT = 0x3B                      # INTARG: uint16 LE value 0..32767
ARG_NINT = 0x1B                     # NINTARG: uint16 LE absolute value, the value is negative
ARG_STR = 0x2B                      # STRARG: length byte, characters (comStr adds a NUL)
INT_ARG_MIN = -32768                # ARIA comInt takes a C short; -32768 is sent as NINT 0x8000
INT_ARG_MAX = 32767
MAX_STR_ARG = 199                   # ARIA comStr refuses more than 199 characters


# Client-to-robot command numbers (§4, §4.1, §8.1; AriaCoda ArCommands.h).
CMD_SYNC0 = 0
CMD_PULSE = 0                       # same number as SYNC0 (alias)
CMD_SYNC1 = 1
CMD_OPEN = 1                        # alias of SYNC1
CMD_SYNC2 = 2
CMD_CLOSE = 2                       # alias of SYNC2
CMD_POLLING = 3
CMD_ENABLE = 4
CMD_SETA = 5
CMD_SETV = 6
CMD_SETO = 7
CMD_MOVE = 8
CMD_ROTATE = 9
CMD_SETRV = 10
CMD_VEL = 11
CMD_HEAD = 12
CMD_DHEAD = 13
CMD_SAY = 15
CMD_JOYINFO = 17
CMD_CONFIG = 18
CMD_ENCODER = 19
CMD_SETRVDIR = 20
CMD_RVEL = 21
CMD_DCHEAD = 22
CMD_SETRA = 23
CMD_IMUREQUEST = 26
CMD_SONAR = 28
CMD_STOP = 29
CMD_DIGOUT = 30
CMD_LASER_POWER = 31                # Notes §2: ARIA sends 2 bytes (11, 1) before laser setup; ignore
CMD_VEL2 = 32
CMD_GRIPPER = 33
CMD_ADSEL = 35
CMD_OLD_SIM_LRF_ENABLE = 35         # §8.1 SRISim number, alias of ADSEL
CMD_OLD_SIM_LRF_SET_FOV_START = 36
CMD_OLD_SIM_LRF_SET_FOV_END = 37
CMD_OLD_SIM_LRF_SET_RES = 38
CMD_IOREQUEST = 40
CMD_BUMPSTALL = 44
CMD_JOYDRIVE = 47
CMD_HOSTBAUD = 50
CMD_ESTOP = 55
CMD_QSTOP = 57                      # §4: MobileSim also treats 57 as a quick stop
CMD_GYRO = 58
CMD_BATTERYINFO = 62                # Notes §1: ARIA sends it (int 1) after CONFIG; never "exit"
CMD_LATVEL = 110
CMD_LATACCEL = 113
CMD_SIM_SET_POSE = 224
CMD_SIM_RESET = 225
CMD_SIM_MODEL_CONFIG = 226
CMD_SIM_LRF_ENABLE = 230
CMD_SIM_LRF_SET_FOV_START = 231
CMD_SIM_LRF_SET_FOV_END = 232
CMD_SIM_LRF_SET_RES = 233
CMD_SIM_CTRL = 236
CMD_SIM_STAT = 237
CMD_SIM_MESSAGE = 238
CMD_SIM_EXIT = 239
CMD_BATTEST = 250
CMD_RESET = 253
CMD_MAINTENANCE = 255


# §4 deprecated SRISim numbers accepted by MobileSim with a warning (66-68 only in --srisim-compat).
SRISIM_LOADPARAM = 61
SRISIM_END_SIM = 62
SRISIM_LOADWORLD = 63
SRISIM_STEP = 64
SRISIM_SET_TRUE_X = 66
SRISIM_SET_TRUE_Y = 67
SRISIM_SET_TRUE_TH = 68
SRISIM_RESET_TO_ORIGIN = 69

# §4.1 SIM_CTRL operation codes (MobileSim EmulatePioneer.hh).
SIM_CTRL_LOAD_MAP = 1
SIM_CTRL_MASTER_LOAD_MAP = 2
SIM_CTRL_CLEAR_MASTER_MAP = 3
SIM_CTRL_ROTATE_LOGS = 4
SIM_CTRL_LOG_STATE = 5
SIM_CTRL_SIMINFO = 6
SIM_CTRL_GHOST = 7
SIM_CTRL_SNAPSHOT = 8

# §4.1 / §8.1 laser enable values and SIM_STAT modes.
LRF_OFF = 0
LRF_BASIC = 1                       # packets 0x60
LRF_EXTENDED = 2                    # packets 0x61 (what ARIA's ArSimulatedLaser asks for)
SIM_STAT_STOP = 0
SIM_STAT_ONCE = 1
SIM_STAT_EVERY_SIP = 2


# Robot-to-client packet types (§3, §5, §5.2, §8).
PTYPE_SYNC0 = 0x00
PTYPE_SYNC1 = 0x01
PTYPE_SYNC2 = 0x02                    # data: name, class, subclass, each NUL-terminated
PTYPE_CONFIG = 0x20
PTYPE_SIP_STOPPED = 0x32              # standard SIP, motors stopped (MobileSim always sends this)
PTYPE_SIP_MOVING = 0x33               # standard SIP, moving
PTYPE_SIM_LASER = 0x60
PTYPE_SIM_LASER_EXT = 0x61
PTYPE_SIMSTAT = 0x62
PTYPE_SIMINFO = 0x63
PTYPE_SIM_MAP_CHANGED = 0x66
PTYPE_ENCODER = 0x90
PTYPE_IO = 0xF0                       # layout not documented in aria-sip.md: decoded as unknown


# --- §3 Handshake and §7 watchdog timing -----------------------------------------------------------
SIM_NAME = "MobileSim"              # SYNC2 name and CONFIG name of MobileSim
AMRISIM_NAME = "AMRISim"            # Notes §4: AMRISim's SYNC2 name
SIM_SERIAL = "SIM"                  # CONFIG serial number of both simulators
DEFAULT_CLASS = "Pioneer"
DEFAULT_SUBCLASS = "p3dx"
SYNC_REPLY_TIMEOUT_S = 1.0          # ARIA waits up to 1000 ms per sync step
SYNC_MAX_NO_REPLY = 10              # ARIA gives up after > 10 silent tries ...
SYNC_MAX_ATTEMPTS = 50              # ... or 50 attempts
SIM_SYNC_TIMEOUT_S = 10.0           # MobileSim SYNC_TIMEOUT
CONFIG_RESEND_S = 0.2               # ARIA re-sends CONFIG at most every 200 ms
CONFIG_WAIT_S = 1.0                 # ... and waits 1 s for the 0x20 reply
DISCONNECT_ENABLE_WAIT_S = 0.1      # ENABLE 0, wait 100 ms, CLOSE 1, wait 1 s
DISCONNECT_CLOSE_WAIT_S = 1.0
SIP_PERIOD_S = 0.1                  # §5: MobileSim and ARIA SIP cycle 100 ms
WATCHDOG_S = 2.0                    # §7: CONFIG watchdog [2000 ms]. UNCONFIRMED what a real robot
                                    # does after it beyond "stops"; simulators only warn (Notes §8).
REFRESH_S = 0.5                     # ARIA StateReflectionRefreshTime and PULSE interval
CONNECTION_TIMEOUT_S = 8.0          # ARIA drops the link after 8 s without a packet

# --- §5 Standard SIP -------------------------------------------------------------------------------
POS_MASK = 0x7FFF                   # §5.1: ARIA keeps the low 15 bits of XPOS/YPOS
POS_MODULUS = 0x8000
POS_WRAP_THRESHOLD = 0x1000         # |delta| beyond this wraps (1987 mm at 0.485 mm/unit)
ANGLE_UNITS_PER_REV = 4096          # THPOS: 2*pi rad = 4096 units
COMPASS_SCALE_DEG = 2               # COMPASS byte = degrees / 2
ROTVEL_SCALE = 10                   # ROTVEL = deg/s x 10
BATTERY_SCALE = 10                  # BATTERY and BATTERYX10 are volts x 10 (decivolts)
MAX_SONAR_PER_SIP = 32              # §9: MobileSim sends at most 32 sonar readings per SIP
TEMPERATURE_NONE = -127             # §5 field 23: MobileSim sends -127 when there is none

# STALL AND BUMPERS (§5 field 7).
STALL_LEFT = 0x0001
REAR_BUMPERS_MASK = 0x00FE          # bits 1..7
REAR_BUMPERS_SHIFT = 1
STALL_RIGHT = 0x0100
FRONT_BUMPERS_MASK = 0xFE00         # bits 9..15
FRONT_BUMPERS_SHIFT = 9

# FLAGS (§5 field 9). UNCONFIRMED other bits: AriaCoda ArRobot.h reads only bits 0..5 of this
# word (areMotorsEnabled, areSonarsEnabledLegacy, isEStopPressed); MobileSim sets bits 0..4 only.
FLAG_MOTORS_ENABLED = 0x0001
FLAG_SONARS_MASK = 0x001E           # bits 1..4, one per sonar array
FLAG_ESTOP = 0x0020

FAULT_HIGH_TEMPERATURE = 0x0002     # §5 field 21, as MobileSim sets it


# CHARGESTATE byte (§5 field 19; AriaCoda ArRobot::ChargeState).
CHARGE_STATE_NOT_CHARGING = 0
CHARGE_STATE_BULK = 1
CHARGE_STATE_OVERCHARGE = 2
CHARGE_STATE_FLOAT = 3
CHARGE_STATE_BALANCE = 4
CHARGE_STATE_UNKNOWN = 255                   # what ARIA shows as -1 when the field is absent


# --- §8 Simulated laser -----------------------------------------------------------------------------
LASER_MAX_PER_PACKET = 32           # §8.2: a scan is split into packets of at most 32 readings
LASER_DEFAULT_START_DEG = -90       # §8.1 ARIA LMS2xx defaults: -90..90 at 1 deg, 181 readings
LASER_DEFAULT_END_DEG = 90
LASER_DEFAULT_RES_CDEG = 100        # 38 / 233 carry the increment in 1/100 degree
LASER_DEFAULT_READINGS = 181
# §8.2 said UNCONFIRMED; Notes §7: AMRISim reports 32767 mm when nothing is in range (also the
# 32.767 m range of MobileSim's sicklms200 model).
LASER_NO_HIT_MM = 32767
# MobileSim / AMRISim PioneerRobotModels.world.inc `sicklms200`: range_max 32.767 m, samples 181,
# fov 180, noise 0.005 (uniform in +-5 mm).
SIM_LMS200_RANGE_MM = 32767
SIM_LMS200_NOISE_MM = 5
LASER_FLAG_ROBOT_MOVED = 0x01       # 0x61 flags byte
SONAR_NO_ECHO_MM = 5000             # Notes §7: AMRISim's sonar value with nothing in range

SIMSTAT_HAVE_MAP = 0x01             # §8.3 SIMSTAT flags
SIMSTAT_GEOREFERENCED = 0x02
SIMSTAT_ODOM_ERROR = 0x04
SIMSTAT_LATLON_SCALE = 10_000_000   # latitude/longitude degrees x 1e7
SIMSTAT_ODOM_ERROR_SCALE = 10_000_000
SIMSTAT_DOP_SCALE = 100

# --- §9 Pioneer P3-DX parameters (AriaCoda p3dx.p, ArRobotP3DX) ------------------------------------
ANGLE_CONV_FACTOR = 0.001534        # rad/unit; built-in and MobileSim. p3dx.p text says 0.00153.
DIST_CONV_FACTOR = 0.485            # mm/unit for subclass "p3dx"
DIST_CONV_FACTOR_SH = 1.0           # mm/unit for subclass "p3dx-sh"
VEL_CONV_FACTOR = 1.0               # (mm/s)/unit
RANGE_CONV_FACTOR = 1.0             # mm/unit (sonar)
DIFF_CONV_FACTOR = 0.0056           # rad/s per (mm/s) of wheel speed difference
# ArCommands.h's comment says "first 8 bits = right"; ArRobot::setVel2 and MobileSim's handler
# agree with §4: high byte = left, low byte = right.
VEL2_DIVISOR = 20                   # mm/s per VEL2 byte unit
GYRO_SCALER = 1.626
ROBOT_RADIUS_MM = 250
ROBOT_DIAGONAL_MM = 120
ROBOT_WIDTH_MM = 425
ROBOT_LENGTH_MM = 511
ROBOT_LENGTH_FRONT_MM = 210
ROBOT_LENGTH_REAR_MM = 301
MAX_VELOCITY_MM_S = 2200
MAX_RVELOCITY_DEG_S = 500
LASER_X_MM = 18                     # LMS2xx mount; 21 mm on p3dx-sh
LASER_X_MM_SH = 21
SONAR_NUM = 16
SONAR_MAX_RANGE_MM = 4335           # MTX boards (param file); legacy boards UNCONFIRMED
# (x mm forward, y mm left, heading deg) of sonar 0..15: 0-7 front ring left to right, 8-15 rear.
SONAR_POSES: tuple[tuple[int, int, int], ...] = (
    (69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10),
    (166, -27, -10), (148, -78, -30), (114, -119, -50), (69, -136, -90),
    (-157, -136, -90), (-203, -119, -130), (-237, -78, -150), (-255, -27, -170),
    (-255, 27, 170), (-237, 78, 150), (-203, 119, 130), (-157, 136, 90),
)

# MobileSim session defaults (§9).
SIM_TRANS_VEL_MAX_MM_S = 3000
SIM_TRANS_ACCEL_MM_S2 = 300
SIM_ROT_VEL_MAX_DEG_S = 150
SIM_ROT_ACCEL_DEG_S2 = 100
SIM_BATTERY_DV = 130                # 13.0 V
SIM_DIGIN = 0xFF
SIM_DIGOUT = 0xFF
SIM_CONFIG_TOP = 9999               # CONFIG RotVelTop..TransAccTop in MobileSim
SIM_PWM_MAX = 400
SIM_FIRMWARE = "S.0"
