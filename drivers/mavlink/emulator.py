"""A MAVLink rover emulator: the simulator's robot served as ArduPilot Rover runs it.

Transports (one client at a time):

- UDP, listening on `host`:`port` (default): clients use ``udpout:127.0.0.1:PORT`` and send first
  (our backend sends HEARTBEAT at once); the stream starts with the first datagram;
- UDP to a ground station at `udp` = ``HOST:PORT`` (like SITL/MAVProxy ``--out``): clients bind it
  with ``udp:HOST:PORT``; the stream runs from start-up;
- TCP (`tcp`, like SITL's 5760): ``tcp:127.0.0.1:PORT``; a pseudo-terminal (`pty`): its device path.

Every `tick` (50 ms) of robot time, paced by wall time / `speedup`, it advances the `SimRobot` and
sends what is due: HEARTBEAT at 1 Hz (type GROUND_ROVER, autopilot ARDUPILOTMEGA, custom_mode the
Rover mode, base_mode as Rover's base_mode(): CUSTOM_MODE_ENABLED, MANUAL_INPUT_ENABLED in MANUAL,
ACRO and STEERING, GUIDED_ENABLED in the autopilot modes, SAFETY_ARMED when armed; system_status
STANDBY in HOLD, else ACTIVE), and per message the requested rate (REQUEST_DATA_STREAM groups
EXTENDED_STATUS: SYS_STATUS, POSITION: GLOBAL_POSITION_INT and LOCAL_POSITION_NED, EXTRA1: ATTITUDE,
EXTRA3: DISTANCE_SENSOR and OBSTACLE_DISTANCE; or SET_MESSAGE_INTERVAL; 1 Hz each by default, at
most 1 / `tick`).

As ArduPilot Rover (GCS_Common.cpp, Rover GCS_Mavlink.cpp, mode.cpp, mode_guided.cpp, AP_Arming.cpp):

- it boots in MANUAL (INITIAL_MODE 0), disarmed;
- the EKF has no origin indoors (`origin` None): no position estimate, so no LOCAL_POSITION_NED
  (GLOBAL_POSITION_INT is sent, latitude/longitude 0), local position targets ignored, arming
  refused in the modes that need a position (all but MANUAL, ACRO, STEERING, HOLD: "Need Position
  Estimate", FAILED) and, armed, switching to them FAILED; never armable in RTL / SMART_RTL. A
  SET_GPS_GLOBAL_ORIGIN (answered with GPS_GLOBAL_ORIGIN) gives it one; home is then set where the
  rover stands (GET_HOME_POSITION / REQUEST_MESSAGE 242 -> HOME_POSITION; FAILED before);
- parameters (`ROVER_PARAMS`, names and types of Rover's) over PARAM_REQUEST_LIST (all at once),
  PARAM_REQUEST_READ (by name or index) and PARAM_SET (answered with the new PARAM_VALUE); GUID_TIMEOUT,
  WP_PIVOT_ANGLE, ATC_STR_ANG_P, ATC_STR_RAT_MAX, CRUISE_SPEED, WP_SPEED and PRX1_TYPE act on the
  emulated rover;
- modes: DO_SET_MODE / SET_MODE need the CUSTOM_MODE_ENABLED base-mode flag (else DENIED), an
  unknown or unsettable mode FAILS; SET_MODE is acked with command 11; every COMMAND_ACK carries
  the sender's ids as target; messages for another system id are ignored;
- SET_POSITION_TARGET_LOCAL_NED in GUIDED with an origin, in LOCAL_NED, LOCAL_OFFSET_NED, BODY_NED or
  BODY_OFFSET_NED (other frames, MAV_FRAME_GLOBAL included, ignored); the type mask is read as
  Rover reads it (a group is ignored when its x or y bit is set; z never looked at): a position
  (mask 3576: from the origin, from the rover, or rotated by its heading in body frames) is driven
  to and stopped at (within 5 cm; MISSION_ITEM_REACHED 0 on arrival; no GUID_TIMEOUT); velocity
  only (3559, 4039) or velocity + heading (2503): turn to the heading - atan2(vy, vx) or `yaw`,
  plus the heading in body frames - at the speed |vx, vy| (capped at WP_SPEED, else CRUISE_SPEED;
  negative with vx < 0 when a heading or rate is given); heading only (2559): turn in place;
  velocity + yaw rate (1511) and yaw rate only (1535): that speed and turn rate. Heading control
  pivots in place while the error exceeds WP_PIVOT_ANGLE until within 10 deg, steering at
  ATC_STR_ANG_P x error up to ATC_STR_RAT_MAX. Heading and turn-rate targets stop after GUID_TIMEOUT
  s of robot time without a new one. A disarmed rover does not move; any mode change stops it;
- COMMAND_INT (and COMMAND_LONG) MAV_CMD_DO_REPOSITION: outside GUIDED DENIED unless the CHANGE_MODE
  flag switches to GUIDED; latitude/longitude out of range or 0, 0 DENIED; param1 > 0 sets the speed;
  then driven to like a position target (FAILED without an origin). MISSION_ITEM_INT with current 2
  (a guided waypoint) likewise, answered with MISSION_ACK (ERROR outside GUIDED); other COMMAND_INTs
  as their COMMAND_LONG;
- SYS_STATUS reports its sensors present, enabled (motor outputs only when armed) and healthy, and
  the geofence healthy though not present (no fence: a ground station sees no breach);
- range data only when configured: `proximity` (PRX1_TYPE 10, SITL) sends one DISTANCE_SENSOR per
  45-degree sector (ids 10..17, orientation 0..7 clockwise from the nose, the nearest echo in the
  sector in cm, max_distance + 1 when none), as ArduPilot reports a proximity sensor;
  `obstacle_distance` sends OBSTACLE_DISTANCE (72 elements of 5 degrees clockwise from the nose,
  BODY_FRD; a companion's or PX4's message, not ArduPilot's).

The last target received is `last_target` (and `last_twist`), for fault tests. Serving, TCP and pty
transports and fault injection are `robotexp_drivers.emulation.StreamEmulator`'s. Messages and
commands are dispatched through tables (`_message_handlers`, `_command_handlers`).
"""

from __future__ import annotations

import collections
import logging
import math
import socket
from collections.abc import Callable
from dataclasses import replace

from robotexp import ConfigError, Footprint, Pose, Twist, wrap_angle
from robotexp.sim import LaserConfig, OdometryError, SimRobot, preset
from robotexp.world.model import World
from robotexp_drivers.backend import require_positive
from robotexp_drivers.emulation import StreamEmulator, odometry_model
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec, Message
from robotexp_drivers.mavlink.robot import ROVER_LIMITS, ROVER_RADIUS

__all__ = ["MavlinkEmulator", "ROVER_PARAMS", "STREAM_MESSAGES"]

log = logging.getLogger(__name__)

STREAM_MESSAGES = {C.MAV_DATA_STREAM_EXTENDED_STATUS: (C.MAVLINK_MSG_ID_SYS_STATUS,),
                   C.MAV_DATA_STREAM_POSITION: (C.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                                                C.MAVLINK_MSG_ID_LOCAL_POSITION_NED),
                   C.MAV_DATA_STREAM_EXTRA1: (C.MAVLINK_MSG_ID_ATTITUDE,),
                   C.MAV_DATA_STREAM_EXTRA3: (C.MAVLINK_MSG_ID_DISTANCE_SENSOR, C.MAVLINK_MSG_ID_OBSTACLE_DISTANCE)}
# SET_POSITION_TARGET_LOCAL_NED frames Rover accepts (GCS_Mavlink.cpp handle_set_position_target_local_ned)
_TARGET_FRAMES = {C.MAV_FRAME_LOCAL_NED, C.MAV_FRAME_LOCAL_OFFSET_NED, C.MAV_FRAME_BODY_NED,
                  C.MAV_FRAME_BODY_OFFSET_NED}
_BODY_FRAMES = {C.MAV_FRAME_BODY_NED, C.MAV_FRAME_BODY_OFFSET_NED}
_ARRIVED = 0.05                      # [m] a position target counts as reached this close
_INT_TYPES = {C.MAV_PARAM_TYPE_INT8, C.MAV_PARAM_TYPE_INT16, C.MAV_PARAM_TYPE_INT32}
_PIVOT_EXIT = math.radians(10.0)     # Rover leaves a pivot turn within 10 deg of the heading
_EARTH_RADIUS = 6378137.0            # [m] WGS84 semi-major axis (ArduPilot's LATLON_TO_M scale)

# A small realistic Rover parameter set: (name, MAV_PARAM_TYPE of Rover's AP_Int8/16/32 or AP_Float,
# value). Values are the emulated rover's where it has one (speed, turn rate, acceleration).
ROVER_PARAMS: tuple[tuple[str, int, float], ...] = (
    ("SYSID_THISMAV", C.MAV_PARAM_TYPE_INT16, C.VEHICLE_SYSTEM_ID),
    ("SYSID_MYGCS", C.MAV_PARAM_TYPE_INT16, C.GCS_SYSTEM_ID),
    ("FRAME_CLASS", C.MAV_PARAM_TYPE_INT8, 1),                  # 1 = Rover
    ("ARMING_CHECK", C.MAV_PARAM_TYPE_INT32, 1),
    ("BATT_MONITOR", C.MAV_PARAM_TYPE_INT8, 4),                 # analog voltage and current
    ("CRUISE_SPEED", C.MAV_PARAM_TYPE_REAL32, ROVER_LIMITS.v_max),
    ("CRUISE_THROTTLE", C.MAV_PARAM_TYPE_INT8, 50),
    ("WP_SPEED", C.MAV_PARAM_TYPE_REAL32, 0.0),                 # 0: CRUISE_SPEED
    ("WP_RADIUS", C.MAV_PARAM_TYPE_REAL32, 2.0),
    ("WP_PIVOT_ANGLE", C.MAV_PARAM_TYPE_INT16, 60),
    ("ATC_STR_ANG_P", C.MAV_PARAM_TYPE_REAL32, 2.0),
    ("ATC_STR_RAT_MAX", C.MAV_PARAM_TYPE_REAL32, math.degrees(ROVER_LIMITS.w_max)),
    ("ATC_ACCEL_MAX", C.MAV_PARAM_TYPE_REAL32, ROVER_LIMITS.a_max),
    ("GUID_TIMEOUT", C.MAV_PARAM_TYPE_REAL32, C.GUID_TIMEOUT),
    ("PRX1_TYPE", C.MAV_PARAM_TYPE_INT8, C.PRX_TYPE_NONE),
)


class MavlinkEmulator(StreamEmulator):
    """Serve a simulated rover of `world` over MAVLink (call `start()`, or use `with`).

    Args:
        world: the environment.
        pose: start pose (default: the world's first named pose, else its home).
        port: UDP (or TCP) port to listen on (0: any free one; read `address`).
        host: interface to listen on (127.0.0.1: local clients only).
        udp: ``HOST:PORT`` of a ground station to send to instead of listening.
        tcp: listen on TCP instead of UDP.
        pty: serve on a pseudo-terminal.
        speedup: robot seconds per wall second.
        seed: seed of the simulator's noise.
        tick: simulation step and send period [s].
        scan_range: range of the range sensors [m].
        guid_timeout: GUID_TIMEOUT, stop when no target came for this long [s of robot time].
        battery_mv: battery voltage reported [mV].
        origin: the EKF origin (latitude, longitude [deg], altitude [m]) the vehicle starts with
            (outdoors, with GPS); None (indoors): none until a ground station sets one.
        proximity: a 360-degree proximity sensor reported as 8 DISTANCE_SENSOR sectors (PRX1_TYPE 10).
        obstacle_distance: send OBSTACLE_DISTANCE (72 sectors) too.

    Raises:
        WorldError: the pose is outside the world or touches an obstacle.
        ConfigError: a parameter out of range.
        OSError: the port cannot be bound.
    """

    label = "mavlink emulator"
    radius = ROVER_RADIUS                        # robotexp.robot.RobotEmulator: the simulated footprint [m]
    options = frozenset({"udp", "odometry"})     # `robotexp emulate mavlink --udp HOST:PORT --odometry-error SPEC`

    def __init__(self, world: World, *, pose: Pose | None = None, port: int = 0, host: str = "127.0.0.1",  # noqa: PLR0913
                 udp: str | None = None, tcp: bool = False, pty: bool = False, speedup: float = 1.0, seed: int = 0,
                 tick: float = 0.05, scan_range: float = 3.0, guid_timeout: float = C.GUID_TIMEOUT,
                 battery_mv: int = 12600, origin: tuple[float, float, float] | None = None,
                 proximity: bool = True, obstacle_distance: bool = False,
                 odometry: OdometryError | str | None = None) -> None:
        require_positive("mavlink emulator", speedup=speedup, tick=tick, scan_range=scan_range,
                         guid_timeout=guid_timeout)
        if origin is not None and not (-90 <= origin[0] <= 90 and -180 <= origin[1] <= 180):
            raise ConfigError(f"mavlink emulator: origin {origin}: latitude must be in -90..90 and longitude "
                              "in -180..180 deg")
        self._init_stream(speedup)
        self.tick, self.battery_mv = tick, battery_mv
        self.obstacle_distance = obstacle_distance
        rover = replace(preset("p3dx"), name="rover", radius=ROVER_RADIUS, footprint=Footprint.disc(ROVER_RADIUS),
                        limits=ROVER_LIMITS, sonar=None,
                        laser=LaserConfig(beams=C.OBSTACLE_SECTORS, fov=2 * math.pi, range_max=scan_range))
        self.sim = SimRobot(world, robot=rover, pose=pose, seed=seed, sonar=False, laser_in_state=False,
                            odometry=odometry_model(odometry))
        self.codec = MavlinkCodec(C.VEHICLE_SYSTEM_ID, C.VEHICLE_COMPONENT_ID)
        self.mode, self.armed = C.ROVER_MODE_MANUAL, False         # Rover boots in MANUAL (INITIAL_MODE 0)
        self.params: dict[str, list[float]] = {name: [float(value), float(kind)] for name, kind, value in ROVER_PARAMS}
        self.params["GUID_TIMEOUT"][0] = float(guid_timeout)
        self.params["PRX1_TYPE"][0] = float(C.PRX_TYPE_SITL if proximity else C.PRX_TYPE_NONE)
        self._param_names = [name for name, _, _ in ROVER_PARAMS]
        self.origin: tuple[float, float, float] | None = None
        self.home: tuple[float, float, float, float, float] | None = None   # lat, lon, alt, x_ned, y_ned
        if origin is not None:
            self._set_origin(origin)
        self.rates: dict[int, float] = {m: C.DEFAULT_STREAM_RATE for ms in STREAM_MESSAGES.values() for m in ms}
        self._due: dict[int, float] = dict.fromkeys(self.rates, 0.0)
        self._once: set[int] = set()
        self._next_heartbeat = 0.0
        self._last_cmd_time = 0.0
        # the GUIDED submode (Rover mode_guided.cpp): None (stop), ("heading", yaw NED [rad], speed [m/s]),
        # ("rate", turn rate NED [rad/s], speed), ("wp", north, east [m from the origin], speed)
        self._guided: tuple[str, float, float, float] | None = None
        self._wp_speed: float | None = None       # DO_REPOSITION's ground speed [m/s] (None: the default)
        self._pivoting = False
        self.last_target: Message | None = None
        self.last_command: Message | None = None
        self.acks: list[Message] = []
        self.commands_received = 0
        self.received: collections.Counter[str] = collections.Counter()   # messages by type
        self.gcs_heartbeats = 0
        self.ignored_targets = 0
        self.packets_sent = 0
        self._messages = self._message_handlers()
        self._commands = self._command_handlers()
        self._udp: socket.socket | None = None
        self._peer: tuple[str, int] | None = None
        try:
            if pty:
                self.address = self._open_pty()
            elif tcp:
                self.address = f"tcp:{host}:{self._listen(host, port)[1]}"
            else:
                self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                if udp is not None:
                    gcs_host, _, gcs_port = udp.rpartition(":")
                    if not gcs_host or not gcs_port.isdigit():
                        raise ConfigError(f"mavlink emulator: udp {udp!r}: expected HOST:PORT, e.g. 127.0.0.1:14550")
                    self._udp.bind((host, 0))
                    self._peer = (gcs_host, int(gcs_port))
                    self.address = f"udp:{udp}"
                else:
                    self._udp.bind((host, port))
                    self.address = f"udpout:{host}:{self._udp.getsockname()[1]}"
        except BaseException:
            self._release()
            raise

    @property
    def _period(self) -> float:
        return self.tick / self.speedup

    @property
    def last_twist(self) -> Twist | None:
        """The last velocity target received, as (v, w) in our convention (None before any)."""
        m = self.last_target
        return None if m is None else Twist(math.copysign(math.hypot(m.vx, m.vy), m.vx) + 0.0, -m.yaw_rate + 0.0)

    def param(self, name: str) -> float:
        """The value of parameter `name` (KeyError if the rover has none)."""
        return self.params[name][0]

    # -- serving (UDP; the rest is StreamEmulator's) ---------------------------------------
    def _active(self) -> bool:
        return self._peer is not None or super()._active()

    def _transmit(self, data: bytes) -> None:
        if data and self._udp is not None and self._peer is not None:
            self._udp.sendto(data, self._peer)
        else:
            super()._transmit(data)

    def _input(self) -> socket.socket | int | None:
        return self._udp or super()._input()

    def _read_input(self, fd: socket.socket | int) -> bytes:
        if fd is not self._udp:
            return super()._read_input(fd)
        assert self._udp is not None
        try:
            data, peer = self._udp.recvfrom(65536)
        except ConnectionRefusedError:    # ICMP from a ground station not listening yet
            return b""
        if self._peer is None:
            log.info("mavlink emulator: client %s", peer)
            self._peer = peer
        return data

    def _on_bytes(self, data: bytes) -> None:
        for m in self.codec.feed(data):
            self._handle(m)

    # -- the vehicle: dispatch -------------------------------------------------------------

    def _message_handlers(self) -> dict[str, Callable[[Message], None]]:
        """Message type -> handler (messages of other types are ignored, as by a vehicle)."""
        return {"SET_POSITION_TARGET_LOCAL_NED": self._on_target, "SET_MODE": self._on_set_mode,
                "REQUEST_DATA_STREAM": self._on_request_data_stream, "COMMAND_LONG": self._on_command_long,
                "COMMAND_INT": self._on_command_int, "MISSION_ITEM_INT": self._on_mission_item_int,
                "PARAM_REQUEST_LIST": self._on_param_request_list, "PARAM_REQUEST_READ": self._on_param_request_read,
                "PARAM_SET": self._on_param_set, "SET_GPS_GLOBAL_ORIGIN": self._on_set_gps_global_origin}

    def _command_handlers(self) -> dict[int, Callable[[Message], int]]:
        """MAV_CMD -> handler returning the MAV_RESULT (others: UNSUPPORTED)."""
        return {C.MAV_CMD_DO_SET_MODE: lambda m: self._set_mode(int(m.param1), int(m.param2)),
                C.MAV_CMD_COMPONENT_ARM_DISARM: self._cmd_arm_disarm,
                C.MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_set_message_interval,
                C.MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
                C.MAV_CMD_GET_HOME_POSITION: self._cmd_get_home_position}

    @property
    def _heading_goal(self) -> tuple[float, float] | None:
        """(yaw NED [rad], speed [m/s]) of a heading target in force (None otherwise)."""
        g = self._guided
        return (g[1], g[2]) if g is not None and g[0] == "heading" else None

    def _handle(self, m: Message) -> None:
        kind = m.get_type()
        self.received[kind] += 1
        if kind == "HEARTBEAT":
            self.gcs_heartbeats += 1
            return
        target = getattr(m, "target_system", 0)
        if target not in (0, C.VEHICLE_SYSTEM_ID):
            return                               # for another vehicle
        self.commands_received += 1
        self.last_command = m
        handler = self._messages.get(kind)
        if handler is not None:
            with self.lock:
                handler(m)

    def _ack(self, m: Message, command: int, result: int) -> None:
        """COMMAND_ACK as ArduPilot fills it: the sender's ids as target."""
        ack = self.codec.mav.command_ack_encode(command, result, 0, 0, m.get_srcSystem(), m.get_srcComponent())
        self.acks.append(ack)
        self._raw.append(self._pack(ack))

    # -- commands -----------------------------------------------------------------------------
    def _on_command_long(self, m: Message) -> None:
        if m.command == C.MAV_CMD_DO_REPOSITION:    # GCS_Common: a location command, handled as COMMAND_INT
            result = self._do_reposition(m.param1, m.param2, round(m.param5 * C.DEG_E7), round(m.param6 * C.DEG_E7))
            self._ack(m, m.command, result)
            return
        handler = self._commands.get(m.command)
        self._ack(m, m.command, C.MAV_RESULT_UNSUPPORTED if handler is None else handler(m))

    def _on_command_int(self, m: Message) -> None:
        """COMMAND_INT: DO_REPOSITION (Rover handle_command_int_do_reposition); the other commands as
        COMMAND_LONG's (GCS_Common handles both alike)."""
        if m.command == C.MAV_CMD_DO_REPOSITION:
            self._ack(m, m.command, self._do_reposition(m.param1, m.param2, m.x, m.y))
            return
        handler = self._commands.get(m.command)
        self._ack(m, m.command, C.MAV_RESULT_UNSUPPORTED if handler is None else handler(m))

    def _do_reposition(self, speed: float, flags: float, lat_e7: int, lon_e7: int) -> int:
        """Drive to a latitude/longitude in GUIDED (switching to it when the CHANGE_MODE flag is set)."""
        change = int(flags) & C.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if math.isfinite(flags) else 0
        if self.mode != C.ROVER_MODE_GUIDED and not change:
            return C.MAV_RESULT_DENIED
        if not (abs(lat_e7) <= 90 * C.DEG_E7 and abs(lon_e7) <= 180 * C.DEG_E7) or (lat_e7 == 0 and lon_e7 == 0):
            return C.MAV_RESULT_DENIED
        if self.mode != C.ROVER_MODE_GUIDED and self._set_mode(C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                                               C.ROVER_MODE_GUIDED) != C.MAV_RESULT_ACCEPTED:
            return C.MAV_RESULT_FAILED
        if self.origin is None:
            return C.MAV_RESULT_FAILED           # no EKF origin: the location cannot be placed
        north, east = self._ned(lat_e7 / C.DEG_E7, lon_e7 / C.DEG_E7)
        if math.isfinite(speed) and speed > 0:
            self._wp_speed = float(speed)
        self._go_to(north, east)
        return C.MAV_RESULT_ACCEPTED

    def _on_mission_item_int(self, m: Message) -> None:
        """A guided-mode waypoint (current == 2; GCS_Common handle_mission_item -> handle_guided_request),
        answered with MISSION_ACK; mission upload is not emulated (ignored)."""
        if m.current != 2:
            return
        ok = (self.mode == C.ROVER_MODE_GUIDED and self.origin is not None and m.command == C.MAV_CMD_NAV_WAYPOINT
              and abs(m.x) <= 90 * C.DEG_E7 and abs(m.y) <= 180 * C.DEG_E7)
        if ok:
            self._go_to(*self._ned(m.x / C.DEG_E7, m.y / C.DEG_E7))
        ack = self.codec.mav.mission_ack_encode(m.get_srcSystem(), m.get_srcComponent(),
                                                C.MAV_MISSION_ACCEPTED if ok else C.MAV_MISSION_ERROR)
        self._raw.append(self._pack(ack))

    def _on_set_mode(self, m: Message) -> None:
        self._ack(m, C.MAVLINK_MSG_ID_SET_MODE, self._set_mode(m.base_mode, m.custom_mode))

    def _set_mode(self, base_mode: int, mode: int) -> int:
        """ArduPilot's _set_mode_common: custom modes only (DENIED otherwise); unknown ones FAIL, and so
        does a mode that needs a position estimate while armed without one (Rover Mode::enter)."""
        if not base_mode & C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return C.MAV_RESULT_DENIED
        if mode not in C.ROVER_MODES or mode == C.ROVER_MODE_INITIALIZING:
            return C.MAV_RESULT_FAILED
        if self.armed and not self._position_ok(mode):
            return C.MAV_RESULT_FAILED
        self.mode = mode
        self._wp_speed = None
        self._halt_rover()                   # GUIDED starts stopped; no RC input in the manual modes
        return C.MAV_RESULT_ACCEPTED

    def _position_ok(self, mode: int) -> bool:
        """Mode `mode` can run: it needs no position estimate, or the EKF has one (it has an origin)."""
        return mode in C.ROVER_NO_POSITION_MODES or self.origin is not None

    def _cmd_arm_disarm(self, m: Message) -> int:
        if m.param1 == 1:
            # Rover AP_Arming: mode_checks (allows_arming) and gps_checks ("Need Position Estimate")
            if self.mode in C.ROVER_UNARMABLE_MODES or not self._position_ok(self.mode):
                return C.MAV_RESULT_FAILED
            self.armed = True
        elif m.param1 == 0:
            self.armed = False
            self._halt_rover()
        else:
            return C.MAV_RESULT_UNSUPPORTED
        return C.MAV_RESULT_ACCEPTED

    def _cmd_set_message_interval(self, m: Message) -> int:
        msg_id, us = int(m.param1), m.param2
        if msg_id not in self.rates:
            return C.MAV_RESULT_FAILED
        self._set_rate(msg_id, 0.0 if us < 0 else C.DEFAULT_STREAM_RATE if us == 0 else 1e6 / us)
        return C.MAV_RESULT_ACCEPTED

    def _cmd_request_message(self, m: Message) -> int:
        msg_id = int(m.param1)
        if msg_id in self.rates or msg_id in (C.MAVLINK_MSG_ID_HOME_POSITION, C.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
            self._once.add(msg_id)           # sent with the next step (nothing while it is not set)
            return C.MAV_RESULT_ACCEPTED
        return C.MAV_RESULT_UNSUPPORTED

    def _cmd_get_home_position(self, m: Message) -> int:
        if self.home is None:
            return C.MAV_RESULT_FAILED       # ArduPilot: home not set
        self._once.add(C.MAVLINK_MSG_ID_HOME_POSITION)
        return C.MAV_RESULT_ACCEPTED

    def _on_request_data_stream(self, m: Message) -> None:
        groups = list(STREAM_MESSAGES) if m.req_stream_id == C.MAV_DATA_STREAM_ALL else [m.req_stream_id]
        for g in groups:
            for msg_id in STREAM_MESSAGES.get(g, ()):
                self._set_rate(msg_id, float(m.req_message_rate) if m.start_stop else 0.0)

    def _set_rate(self, msg_id: int, hz: float) -> None:
        self.rates[msg_id] = max(hz, 0.0)
        self._due[msg_id] = self.sim.time

    # -- parameters ------------------------------------------------------------------------------
    def _param_value(self, name: str) -> Message:
        value, kind = self.params[name]
        return self.codec.mav.param_value_encode(name.encode(), value, int(kind), len(self._param_names),
                                                 self._param_names.index(name))

    def _on_param_request_list(self, m: Message) -> None:
        self._raw.extend(self._pack(self._param_value(name)) for name in self._param_names)

    def _on_param_request_read(self, m: Message) -> None:
        if m.param_index >= 0:
            name = self._param_names[m.param_index] if m.param_index < len(self._param_names) else None
        else:
            name = _param_name(m.param_id)
        if name in self.params:
            self._raw.append(self._pack(self._param_value(name)))

    def _on_param_set(self, m: Message) -> None:
        name = _param_name(m.param_id)
        if name not in self.params or not math.isfinite(m.param_value):
            return                          # ArduPilot ignores unknown names
        kind = self.params[name][1]
        self.params[name][0] = float(round(m.param_value)) if kind in _INT_TYPES else float(m.param_value)
        self._raw.append(self._pack(self._param_value(name)))

    # -- EKF origin and home -----------------------------------------------------------------------
    def _on_set_gps_global_origin(self, m: Message) -> None:
        lat, lon = m.latitude / C.DEG_E7, m.longitude / C.DEG_E7
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            return
        self._set_origin((lat, lon, m.altitude / 1000.0))
        self._once.add(C.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)

    def _ned(self, lat: float, lon: float) -> tuple[float, float]:
        """North, east [m] of a latitude/longitude [deg] from the origin (inverse of `_latlon`)."""
        assert self.origin is not None
        lat0, lon0, _ = self.origin
        return (math.radians(lat - lat0) * _EARTH_RADIUS,
                math.radians(lon - lon0) * _EARTH_RADIUS * math.cos(math.radians(lat0)))

    def _set_origin(self, origin: tuple[float, float, float]) -> None:
        self.origin = origin
        if self.home is None:                # home: where the rover stands once it knows where that is
            p = self.sim.read().pose
            lat, lon = self._latlon(p.y, p.x)
            self.home = (lat, lon, origin[2], p.y, p.x)

    def _latlon(self, x_ned: float, y_ned: float) -> tuple[float, float]:
        assert self.origin is not None
        lat0, lon0, _ = self.origin
        return (lat0 + math.degrees(x_ned / _EARTH_RADIUS),
                lon0 + math.degrees(y_ned / (_EARTH_RADIUS * math.cos(math.radians(lat0)))))

    # -- guided targets ---------------------------------------------------------------------------
    def _halt_rover(self) -> None:
        self._guided = None
        self.sim.command(Twist.ZERO)

    def _speed_default(self) -> float:
        """WP_SPEED, or CRUISE_SPEED when it is 0 (Rover Mode::get_speed_default)."""
        wp = self.param("WP_SPEED")
        return wp if wp > 0 else self.param("CRUISE_SPEED")

    def _go_to(self, north: float, east: float) -> None:
        self._guided = ("wp", north, east, self._wp_speed or self._speed_default())
        self._pivoting = False

    def _on_target(self, m: Message) -> None:
        """Rover's handle_set_position_target_local_ned: GUIDED only, with an EKF origin, in a local or
        body frame; the type mask picks position, velocity (+ heading or turn rate), heading or turn
        rate. Armed or not, the target is taken (a disarmed rover does not move)."""
        self.last_target = m
        if self.mode != C.ROVER_MODE_GUIDED or self.origin is None or m.coordinate_frame not in _TARGET_FRAMES:
            self.ignored_targets += 1
            return
        mask = m.type_mask
        pos_ignore = bool(mask & C.ROVER_POS_IGNORE)
        vel_ignore = bool(mask & C.ROVER_VEL_IGNORE)
        acc_ignore = bool(mask & C.ROVER_ACC_IGNORE)
        yaw_ignore = bool(mask & C.POSITION_TARGET_TYPEMASK_YAW_IGNORE)
        rate_ignore = bool(mask & C.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
        values = (m.x, m.y, m.vx, m.vy, m.yaw, m.yaw_rate)
        if not all(map(math.isfinite, values)):
            self.ignored_targets += 1
            return
        pose = self.sim.read().pose
        yaw_now = math.pi / 2 - pose.theta                 # NED yaw
        body = m.coordinate_frame in _BODY_FRAMES
        speed, yaw = 0.0, 0.0
        if not vel_ignore:
            speed = min(math.hypot(m.vx, m.vy), self._speed_default())
            yaw = math.atan2(m.vy, m.vx) + (yaw_now if body else 0.0)
        if not yaw_ignore:
            yaw = m.yaw + (yaw_now if body else 0.0)
        direction = -1.0 if not vel_ignore and (not yaw_ignore or not rate_ignore) and m.vx < 0 else 1.0
        if not pos_ignore:
            here_n, here_e = pose.y, pose.x
            if m.coordinate_frame == C.MAV_FRAME_LOCAL_NED:
                north, east = m.x, m.y                      # from the EKF origin
            elif m.coordinate_frame == C.MAV_FRAME_LOCAL_OFFSET_NED:
                north, east = here_n + m.x, here_e + m.y
            else:                                           # body frames: rotated by the heading
                c, s_ = math.cos(yaw_now), math.sin(yaw_now)
                north, east = here_n + m.x * c - m.y * s_, here_e + m.x * s_ + m.y * c
            self._go_to(north, east)
        elif not vel_ignore and acc_ignore and rate_ignore:        # velocity, or velocity and heading
            self._guided = ("heading", wrap_angle(yaw), direction * speed, 0.0)
        elif not vel_ignore and acc_ignore and yaw_ignore:         # velocity and turn rate
            self._guided = ("rate", m.yaw_rate, direction * speed, 0.0)
        elif vel_ignore and acc_ignore and not yaw_ignore and rate_ignore:   # heading only
            self._guided = ("heading", wrap_angle(yaw), 0.0, 0.0)
        elif vel_ignore and acc_ignore and yaw_ignore and not rate_ignore:   # turn rate only
            self._guided = ("rate", m.yaw_rate, 0.0, 0.0)
        else:
            self.ignored_targets += 1
            return
        self._last_cmd_time = self.sim.time
        g = self._guided
        if g is not None and g[0] == "rate" and self.armed:
            self.sim.command(Twist(g[2], -g[1]))

    def _steer(self, yaw_goal: float, speed: float) -> None:
        """Heading-and-speed control (pivot turns as a skid-steer Rover)."""
        err = wrap_angle(yaw_goal - (math.pi / 2 - self.sim.read().pose.theta))   # NED: clockwise
        pivot_deg = self.param("WP_PIVOT_ANGLE")
        if pivot_deg > 0 and abs(err) > math.radians(pivot_deg):
            self._pivoting = True
        elif abs(err) < _PIVOT_EXIT or pivot_deg <= 0:
            self._pivoting = False
        rate_max = math.radians(self.param("ATC_STR_RAT_MAX"))
        rate = max(-rate_max, min(rate_max, self.param("ATC_STR_ANG_P") * err))
        self.sim.command(Twist(0.0 if self._pivoting else speed, -rate))

    def _guide(self) -> bool:
        """One tick of the GUIDED submode (under the lock); True when a position target was reached now."""
        g = self._guided
        if g is None:
            return False
        if self.mode != C.ROVER_MODE_GUIDED or not self.armed:
            self._halt_rover()
            return False
        kind, a, b, speed = g
        if kind != "wp":
            if self.sim.time - self._last_cmd_time > self.param("GUID_TIMEOUT") - 1e-9:
                self._halt_rover()               # heading / turn-rate targets time out (GUID_TIMEOUT)
            elif kind == "heading":
                self._steer(a, b)
            return False
        pose = self.sim.read().pose
        d_north, d_east = a - pose.y, b - pose.x
        dist = math.hypot(d_north, d_east)
        if dist < _ARRIVED:
            self._halt_rover()
            return True
        # slow down to stop at the point: v^2 = 2 a d
        self._steer(math.atan2(d_east, d_north), min(speed, math.sqrt(2.0 * ROVER_LIMITS.a_max * dist)))
        return False

    # -- one tick -------------------------------------------------------------------------------
    def _pack(self, message: Message) -> bytes:
        self.packets_sent += 1
        return self._maybe_corrupt(self.codec.encode(message))

    def _sensors(self) -> tuple[int, int, int]:
        """SYS_STATUS present, enabled, healthy bits."""
        # GCS_Common.cpp update_sensor_status_flags: no fence configured, so the geofence is neither present
        # nor enabled, but healthy (not breached): a ground station reads "unhealthy" as a fence breach
        present = (C.MAV_SYS_STATUS_SENSOR_3D_GYRO | C.MAV_SYS_STATUS_SENSOR_3D_ACCEL | C.MAV_SYS_STATUS_SENSOR_3D_MAG
                   | C.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE | C.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                   | C.MAV_SYS_STATUS_AHRS | C.MAV_SYS_STATUS_SENSOR_BATTERY | C.MAV_SYS_STATUS_PREARM_CHECK
                   | (C.MAV_SYS_STATUS_SENSOR_PROXIMITY if self.param("PRX1_TYPE") else 0))
        enabled = present if self.armed else present & ~C.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        return present, enabled, present | C.MAV_SYS_STATUS_GEOFENCE

    def _step(self) -> bytes:
        """Advance the robot by one tick; the bytes of the messages then due."""
        mav = self.codec.mav
        with self.lock:
            reached = self._guide()
            self.sim.advance(self.tick)
            t = self.sim.time
            state = self.sim.read()
            due = [i for i, hz in self.rates.items() if (hz > 0 and t >= self._due[i] - 1e-9) or i in self._once]
            for i in due:
                if self.rates.get(i, 0.0) > 0:
                    self._due[i] = max(self._due[i] + 1.0 / self.rates[i], t + 1e-9)
            due += [i for i in self._once if i not in self.rates]
            self._once.clear()
            ranging = (C.MAVLINK_MSG_ID_OBSTACLE_DISTANCE in due and self.obstacle_distance) or (
                C.MAVLINK_MSG_ID_DISTANCE_SENSOR in due and self.param("PRX1_TYPE"))
            scan = self.sim.scan() if ranging else None
            sensors = self._sensors()
        ms = round(t * 1000) % (1 << 32)
        out: list[bytes] = []
        if t >= self._next_heartbeat - 1e-9:
            self._next_heartbeat += C.HEARTBEAT_PERIOD
            # Rover GCS_Mavlink.cpp base_mode(): manual input in MANUAL/ACRO/STEERING, guided in autopilot modes
            base = (C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (C.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
                    | (C.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED if self.mode in C.ROVER_MANUAL_INPUT_MODES else 0)
                    | (C.MAV_MODE_FLAG_GUIDED_ENABLED if self.mode in C.ROVER_AUTOPILOT_MODES else 0))
            status = C.MAV_STATE_STANDBY if self.mode == C.ROVER_MODE_HOLD else C.MAV_STATE_ACTIVE
            out.append(self._pack(mav.heartbeat_encode(C.MAV_TYPE_GROUND_ROVER, C.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                                       self.mode, status, C.MAVLINK_VERSION)))
        p, vel = state.pose, state.velocity
        yaw_ned = wrap_angle(math.pi / 2 - p.theta)
        if reached:                                  # Rover ModeGuided::update: send_mission_item_reached_message(0)
            out.append(self._pack(mav.mission_item_reached_encode(0)))
        for i in sorted(due):
            msgs: list[Message] = []
            if i == C.MAVLINK_MSG_ID_SYS_STATUS:
                msgs = [mav.sys_status_encode(*sensors, 0, self.battery_mv, -1, -1, 0, 0, 0, 0, 0, 0)]
            elif i == C.MAVLINK_MSG_ID_LOCAL_POSITION_NED and self.origin is not None:
                msgs = [mav.local_position_ned_encode(ms, p.y, p.x, 0.0, vel.v * math.sin(p.theta),
                                                      vel.v * math.cos(p.theta), 0.0)]
            elif i == C.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
                msgs = [self._global_position(ms, p, vel, yaw_ned)]
            elif i == C.MAVLINK_MSG_ID_ATTITUDE:
                msgs = [mav.attitude_encode(ms, 0.0, 0.0, yaw_ned, 0.0, 0.0, -vel.w)]
            elif i == C.MAVLINK_MSG_ID_DISTANCE_SENSOR and scan is not None and self.param("PRX1_TYPE"):
                msgs = self._distance_sensors(ms, scan)
            elif i == C.MAVLINK_MSG_ID_OBSTACLE_DISTANCE and scan is not None and self.obstacle_distance:
                msgs = [self._obstacle_distance(t, scan)]
            elif i == C.MAVLINK_MSG_ID_HOME_POSITION and self.home is not None:
                lat, lon, alt, hx, hy = self.home
                msgs = [mav.home_position_encode(round(lat * C.DEG_E7), round(lon * C.DEG_E7), round(alt * 1000),
                                                 hx, hy, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, round(t * 1e6))]
            elif i == C.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN and self.origin is not None:
                lat0, lon0, alt0 = self.origin
                msgs = [mav.gps_global_origin_encode(round(lat0 * C.DEG_E7), round(lon0 * C.DEG_E7), round(alt0 * 1000),
                                                     round(t * 1e6))]
            out.extend(self._pack(msg) for msg in msgs)
        return b"".join(out)

    def _global_position(self, ms: int, p: Pose, vel: Twist, yaw_ned: float) -> Message:
        """GLOBAL_POSITION_INT as GCS_Common's send_global_position_int: sent with or without a position
        (then latitude/longitude 0), altitude [mm], velocity NED [cm/s], heading [cdeg, 0..35999]."""
        lat = lon = 0.0
        alt = 0.0
        if self.origin is not None:
            lat, lon = self._latlon(p.y, p.x)
            alt = self.origin[2]
        return self.codec.mav.global_position_int_encode(
            ms, round(lat * C.DEG_E7), round(lon * C.DEG_E7), round(alt * 1000), 0,
            round(vel.v * math.sin(p.theta) * 100), round(vel.v * math.cos(p.theta) * 100), 0,
            round(math.degrees(yaw_ned) * 100) % 36000)

    def _distance_sensors(self, ms: int, scan: object) -> list[Message]:
        """One DISTANCE_SENSOR per 45-degree sector (ArduPilot's send_proximity): the nearest echo [cm]."""
        max_cm = round(scan.range_max * 100)                     # type: ignore[attr-defined]
        nearest = [math.inf] * C.PROXIMITY_SECTORS
        for a, r in zip(scan.angles.tolist(), scan.ranges.tolist(), strict=True):   # type: ignore[attr-defined]
            k = round(-math.degrees(a) / 45.0) % C.PROXIMITY_SECTORS
            nearest[k] = min(nearest[k], r)
        return [self.codec.mav.distance_sensor_encode(
                    ms, 0, max_cm, max_cm + 1 if not math.isfinite(r) else min(max(round(r * 100), 0), max_cm),
                    C.MAV_DISTANCE_SENSOR_LASER, C.PROXIMITY_SENSOR_ID_START + k, k, 0)
                for k, r in enumerate(nearest)]

    def _obstacle_distance(self, t: float, scan: object) -> Message:
        max_cm = round(scan.range_max * 100)                     # type: ignore[attr-defined]
        dist = [C.OBSTACLE_UNKNOWN] * C.OBSTACLE_SECTORS
        for a, r in zip(scan.angles.tolist(), scan.ranges.tolist(), strict=True):   # type: ignore[attr-defined]
            k = round(-math.degrees(a) / 5.0) % C.OBSTACLE_SECTORS
            dist[k] = max_cm + 1 if not math.isfinite(r) else min(max(round(r * 100), 0), max_cm)
        return self.codec.mav.obstacle_distance_encode(round(t * 1e6), C.MAV_DISTANCE_SENSOR_LASER, dist, 5, 0, max_cm,
                                                       5.0, 0.0, C.MAV_FRAME_BODY_FRD)

    def _release(self) -> None:
        if self._udp is not None:
            self._udp.close()
            self._udp = None
        super()._release()


def _param_name(param_id: str | bytes) -> str:
    """A PARAM_* message's param_id as a name (pymavlink may give bytes; NUL padding dropped)."""
    raw = param_id.decode("ascii", "replace") if isinstance(param_id, bytes) else str(param_id)
    return raw.split("\x00", 1)[0]
