"""`MavlinkRobot`: the `Robot` backend of a MAVLink ground rover (ArduPilot Rover in GUIDED mode).

The only place where MAVLink units and frames become ours. Connecting waits for the vehicle's
HEARTBEAT: the first valid one from a rover (MAV_TYPE_GROUND_ROVER, or SURFACE_BOAT as Rover reports
a boat frame, from a real autopilot) locks the run to its system and component ids and, on a
listening UDP link, to the address it came from (`UdpLink.lock`: commands go there only, datagrams
from elsewhere are dropped). Messages from other ids are refused (the vehicle's own other components
may still send OBSTACLE_DISTANCE / DISTANCE_SENSOR): counted in `refused` (state extra "refused"),
the first one logged. A non-finite position, velocity or attitude ends the run with a
`ProtocolError`. It then requests the streams (REQUEST_DATA_STREAM for ArduPilot and
SET_MESSAGE_INTERVAL for PX4-style autopilots), asks for the EKF origin (REQUEST_MESSAGE
GPS_GLOBAL_ORIGIN) and, when the vehicle has none within `ORIGIN_WAIT` and sends no local position
(indoors, no GPS: ArduPilot then ignores local position targets), sets one with
SET_GPS_GLOBAL_ORIGIN (`origin`), sets mode GUIDED (MAV_CMD_DO_SET_MODE) and arms
(MAV_CMD_COMPONENT_ARM_DISARM), then waits for the first pose.

Frames (mavlink-rover.md 3): the vehicle reports NED (x north, y east, yaw clockwise from north);
we use x east, y north, theta counter-clockwise from east, so
``x = y_ned, y = x_ned, theta = pi/2 - yaw_ned`` and ``w = -yawspeed``; the forward speed is the
NED velocity projected on the heading. `move_to(pose)` re-anchors that frame so the current pose
reads `pose` (a rover's EKF origin is wherever it started). Commands are
SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_BODY_NED with type mask 1511 (velocity + yaw rate, Rover
"turn rate and speed"): ``vx = v``, ``yaw_rate = -w``. OBSTACLE_DISTANCE (cm, clockwise sectors from
the nose in BODY_FRD, or from north in GLOBAL / LOCAL_NED frames) becomes a `LaserScan`: one beam per
element at the sector's direction; UINT16_MAX and readings below `min_distance` are left out,
readings above `max_distance` are "nothing hit" (inf). The scan is taken where the vehicle was at its
`time_usec` when that reads as the vehicle's boot clock (within `PAIR_SPAN` before the newest
LOCAL_POSITION_NED): the pose then is interpolated between the LOCAL_POSITION_NED (and ATTITUDE)
messages around it and every echo is moved to where it lies as seen from the newest pose (the scan
stream is slower than the pose stream, so a state's newest scan is often a pose or two old: taken
as from the newest pose, a turning rover would map its walls turned). Its stamp is its number
among the OBSTACLE_DISTANCE messages received (senders that leave `time_usec` 0 included), so a
run maps each scan once. Without OBSTACLE_DISTANCE, the horizontal
DISTANCE_SENSOR readings (orientation 0..7: 45-degree sectors clockwise from the nose, as ArduPilot
reports its proximity sectors and rangefinders) heard within the last second make the scan, one
beam per sensor; with neither, the state has no laser (a laser driver can be paired with the robot).

A background reader thread decodes the stream, keeps the newest state, sends our HEARTBEAT at 1 Hz,
re-sends the current target every `resend` s (the Rover stops after GUID_TIMEOUT = 3 s without
one) and is the watchdog: no `command()` for `watchdog` s (0.5 s) -> a zero-velocity target.
No message from the vehicle for `timeout` s (1 s), or a lost link, makes the next `read()` (and the
paced clock) raise `ConnectionLost` (`ProtocolError` when only bad frames arrived meanwhile); the
reader then sends a stop once. `close()` sends a stop and switches the vehicle to HOLD.
Robot time is the vehicle's `time_boot_ms` of LOCAL_POSITION_NED, counted from the first one.
The shared parts (reader loop, failure, watchdog, paced clock) are `robotexp_drivers.backend.StreamBackend`'s.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import replace

import numpy as np

from robotexp import (
    Capability, ConnectionLost, LaserScan, Limits, Pose, PoseHistory, ProtocolError, RobotError, RobotState, Twist,
    scan_in_robot_frame, wrap_angle)
from robotexp_drivers.backend import StreamBackend, require_positive
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec, Message
from robotexp_drivers.mavlink.link import POLL_TIMEOUT, Link, open_link

__all__ = ["MavlinkRobot", "ROVER_LIMITS", "ROVER_RADIUS", "scan_from_obstacle_distance", "scan_from_distance_sensors",
           "ned_to_enu"]

DISTANCE_SENSOR_FRESH = 1.0   # [s] DISTANCE_SENSOR readings older than this are left out of the scan
PAIR_SPAN = 1.0               # [s] an OBSTACLE_DISTANCE stamped this much before the newest pose, or less,
                              # is placed from the pose at its stamp (else: other clock, newest pose)
POSE_SAMPLES = 64             # poses kept for that (3 s at 20 Hz)
# range messages a vehicle's other components (a companion computer) may send under its system id
_COMPANION_MESSAGES = frozenset({"OBSTACLE_DISTANCE", "DISTANCE_SENSOR"})

log = logging.getLogger(__name__)

# A small skid-steer rover (the emulator's too); real vehicles differ: pass `limits` and `radius`.
ROVER_LIMITS = Limits(v_max=1.0, w_max=math.radians(120), a_max=0.5, alpha_max=math.radians(120))
ROVER_RADIUS = 0.25     # [m]


def ned_to_enu(x_ned: float, y_ned: float, yaw_ned: float) -> Pose:
    """A NED position [m] and yaw [rad, clockwise from north] as our pose (x east, y north, ccw)."""
    return Pose(y_ned, x_ned, wrap_angle(math.pi / 2 - yaw_ned))


def scan_from_obstacle_distance(msg: Message, yaw_ned: float) -> LaserScan:
    """An OBSTACLE_DISTANCE message as a scan in the robot frame (see the module docstring).

    Args:
        msg: the message (pymavlink `MAVLink_obstacle_distance_message`).
        yaw_ned: the vehicle's yaw [rad] (for north-aligned frames).
    """
    step = msg.increment_f if msg.increment_f else float(msg.increment)
    if msg.frame in (C.MAV_FRAME_GLOBAL, C.MAV_FRAME_LOCAL_NED):
        base = math.degrees(yaw_ned) - msg.angle_offset      # element 0: counter-clockwise from the nose
    else:
        base = -msg.angle_offset                             # body frames: the same, no yaw
    d = np.asarray(msg.distances, dtype=np.float64)
    i = np.arange(d.size, dtype=np.float64)
    n = min(d.size, int(360.0 / step)) if step > 0 else 0    # only 360/increment elements are used
    valid = (i < n) & (d != C.OBSTACLE_UNKNOWN) & (d >= msg.min_distance)
    angles = np.array([wrap_angle(a) for a in np.radians(base - i[valid] * step)], dtype=np.float64)
    ranges = np.where(d[valid] > msg.max_distance, np.inf, d[valid] / 100.0)
    return LaserScan(angles=angles, ranges=ranges.astype(np.float64), range_max=msg.max_distance / 100.0)


def scan_from_distance_sensors(msgs: list[Message]) -> LaserScan | None:
    """Horizontal DISTANCE_SENSOR readings as a scan in the robot frame (one beam per sensor).

    Orientation n = 0..7 is a direction n x 45 deg clockwise from the nose (ArduPilot's reading of
    MAV_SENSOR_ORIENTATION for proximity sectors and rangefinders; mavlink-rover.md 7.1); other
    orientations (up, down, custom) are left out, and so are readings below `min_distance`;
    readings above `max_distance` are "nothing hit" (inf). Distances are in cm.

    Returns:
        The scan, beams sorted by angle; None when no horizontal reading is left.
    """
    beams = sorted((wrap_angle(-math.radians(45.0 * m.orientation)), m) for m in msgs
                   if C.MAV_SENSOR_ROTATION_NONE <= m.orientation <= C.MAV_SENSOR_ROTATION_YAW_315
                   and m.current_distance >= m.min_distance)
    if not beams:
        return None
    angles = np.array([a for a, _ in beams], dtype=np.float64)
    ranges = np.array([math.inf if m.current_distance > m.max_distance else m.current_distance / 100.0
                       for _, m in beams], dtype=np.float64)
    return LaserScan(angles=angles, ranges=ranges, range_max=max(m.max_distance for _, m in beams) / 100.0)


class MavlinkRobot(StreamBackend):
    """A MAVLink ground rover (ArduPilot Rover, GUIDED mode) over UDP, TCP or a serial port.

    Args:
        address: a pymavlink-style address (`robotexp_drivers.mavlink.link`): ``udp:127.0.0.1:14550``
            (bind, the vehicle sends first; the default listens on loopback only: give the interface's
            address, or ``udp:0.0.0.0:14550``, for a vehicle on the network), ``udpout:HOST:PORT``,
            ``tcp:HOST:PORT``, ``/dev/ttyACM0``.
        pose: where our frame puts the vehicle once connected (default: as it reports).
        limits: speed limits of the vehicle.
        radius: footprint radius [m].
        timeout: silence after which the link counts as lost [s].
        watchdog: stop the vehicle when `command()` was not called for this long [s].
        connect_timeout: wait this long for the heartbeat, GUIDED, arming and the first pose [s].
        rate: requested rate of position and attitude [Hz].
        scan_rate: requested rate of OBSTACLE_DISTANCE [Hz].
        resend: re-send the current target this often [s].
        arm: set GUIDED and arm when connecting.
        origin: the EKF origin (latitude, longitude [deg], altitude [m]) to set on a vehicle that has
            none (None: never set one).
        system, component: our MAVLink ids (255 = ground station).
        baudrate: serial line speed [bit/s].

    Raises:
        ConfigError: a bad address or parameter.
        ConnectionLost: the link cannot be opened or no vehicle answers in time.
        ProtocolError: bytes arrive but no valid MAVLink frame.
        RobotError: the vehicle refuses GUIDED or arming.
    """

    name = "mavlink"
    capabilities = frozenset({Capability.MOVE_TO, Capability.BATTERY, Capability.PACED_CLOCK})

    def __init__(self, address: str = f"udp:127.0.0.1:{C.DEFAULT_UDP_PORT}", *, pose: Pose | None = None,  # noqa: PLR0913
                 limits: Limits = ROVER_LIMITS, radius: float = ROVER_RADIUS, timeout: float = 1.0,
                 watchdog: float = 0.5, connect_timeout: float = 5.0, rate: float = 20.0,
                 scan_rate: float = 10.0, resend: float = 0.25, arm: bool = True,
                 origin: tuple[float, float, float] | None = C.DEFAULT_ORIGIN,
                 system: int = C.GCS_SYSTEM_ID, component: int = C.GCS_COMPONENT_ID,
                 baudrate: int = C.DEFAULT_BAUD) -> None:
        require_positive("mavlink", timeout=timeout, watchdog=watchdog, connect_timeout=connect_timeout, rate=rate,
                         scan_rate=scan_rate, resend=resend)
        self._init_stream(timeout, watchdog)
        self.address = address
        self.limits, self.radius = limits, radius
        self.resend = resend
        self._codec = MavlinkCodec(system, component)
        self._tx_lock = threading.Lock()       # one message written at a time (inside _cmd_lock)
        self._target: tuple[int, int] | None = None
        self._heartbeat: Message | None = None
        self._position: Message | None = None
        self._attitude: Message | None = None
        self._scan_msg: Message | None = None
        self._scans = 0                        # OBSTACLE_DISTANCE messages received
        self._poses = PoseHistory(POSE_SAMPLES)   # vehicle boot time [s] -> our pose, at each LOCAL_POSITION_NED
        self._pose_t = -math.inf               # [s] vehicle boot time of the newest one
        self._ranges: dict[int, tuple[float, Message]] = {}   # DISTANCE_SENSOR id -> (perf_counter, message)
        self._origin: Message | None = None    # the vehicle's GPS_GLOBAL_ORIGIN
        self.origin_set = False                # we set the EKF origin
        self.origin = origin
        self._battery: float | None = None
        self._acks: dict[int, int] = {}
        self._t0_ms: int | None = None
        self._time_ms = 0
        self._distance = 0.0
        self._anchor = (0.0, 0.0, 0.0)         # (dx, dy, dtheta): our frame = R(dtheta) * vehicle ENU + d
        self._bad_mark = (0, 0)
        self.refused = 0                       # messages from other ids than the vehicle's
        self._sent_wall = self._hb_wall = 0.0
        self.state_time = 0.0                  # [s] perf_counter() of the newest LOCAL_POSITION_NED
        self._boot = time.perf_counter()
        self._link: Link = open_link(address, baudrate=baudrate, poll=POLL_TIMEOUT)
        self._start_reader(f"mavlink {address}")
        try:
            self._connect(connect_timeout, rate, scan_rate, arm)
            if pose is not None:
                self._anchor_at(pose)
        except BaseException:
            self._shutdown()
            raise
        super().__init__()

    # -- connecting ---------------------------------------------------------------------
    def _wait(self, ready: str, deadline: float, resend: list[Message] | None = None) -> bool:
        """Wait until `ready` (a predicate method name) holds; re-send `resend` every 0.5 s."""
        next_send = 0.0
        while True:
            now = time.perf_counter()
            if resend and now >= next_send:
                for m in resend:
                    self._send(m)
                next_send = now + 0.5
            with self._cond:
                if self._error is not None:
                    raise self._error
                if getattr(self, ready)():
                    return True
                left = deadline - time.perf_counter()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.05))

    def _has_vehicle(self) -> bool:
        return self._target is not None

    def _in_guided_armed(self) -> bool:
        hb = self._heartbeat
        return (hb is not None and hb.custom_mode == C.ROVER_MODE_GUIDED
                and bool(hb.base_mode & C.MAV_MODE_FLAG_SAFETY_ARMED))

    def _has_pose(self) -> bool:
        return self._position is not None and self._attitude is not None

    def _has_origin(self) -> bool:
        return self._origin is not None or self._position is not None

    def _ensure_origin(self, deadline: float) -> None:
        """Ask for the EKF origin; set `origin` when the vehicle has none (no answer, no local position)."""
        ts, tc = self._targets()
        mav = self._codec.mav
        self._send(mav.command_long_encode(ts, tc, C.MAV_CMD_REQUEST_MESSAGE, 0, C.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN,
                                           0, 0, 0, 0, 0, 0))
        if self.origin is None or self._wait("_has_origin", min(deadline, time.perf_counter() + C.ORIGIN_WAIT)):
            return
        lat, lon, alt = self.origin
        log.info("mavlink: the vehicle has no EKF origin: setting %.7f, %.7f, %.1f m", lat, lon, alt)
        self._send(mav.set_gps_global_origin_encode(ts, round(lat * C.DEG_E7), round(lon * C.DEG_E7),
                                                    round(alt * 1000), 0))
        self.origin_set = True

    def _connect(self, connect_timeout: float, rate: float, scan_rate: float, arm: bool) -> None:
        deadline = time.perf_counter() + connect_timeout
        if not self._wait("_has_vehicle", deadline):
            if self._codec.bad_frames or self._codec.dropped_bytes:
                raise ProtocolError(f"mavlink: bytes from {self.address!r} for {connect_timeout:g} s but no vehicle "
                                    f"HEARTBEAT ({self._codec.bad_frames} bad frames, {self._codec.dropped_bytes} "
                                    "bytes dropped): wrong baud rate, or not a MAVLink vehicle?")
            raise ConnectionLost(f"mavlink: no vehicle HEARTBEAT from {self.address!r} within {connect_timeout:g} s: "
                                 "is the vehicle (or `robotexp emulate mavlink`) running and sending there?")
        mav = self._codec.mav
        ts, tc = self._targets()
        requests = [mav.request_data_stream_encode(ts, tc, C.MAV_DATA_STREAM_POSITION, round(rate), 1),
                    mav.request_data_stream_encode(ts, tc, C.MAV_DATA_STREAM_EXTRA1, round(rate), 1),
                    mav.request_data_stream_encode(ts, tc, C.MAV_DATA_STREAM_EXTRA3, round(scan_rate), 1),
                    mav.request_data_stream_encode(ts, tc, C.MAV_DATA_STREAM_EXTENDED_STATUS, 1, 1)]
        intervals = ((C.MAVLINK_MSG_ID_LOCAL_POSITION_NED, rate), (C.MAVLINK_MSG_ID_ATTITUDE, rate),
                     (C.MAVLINK_MSG_ID_OBSTACLE_DISTANCE, scan_rate), (C.MAVLINK_MSG_ID_DISTANCE_SENSOR, scan_rate))
        for msg_id, hz in intervals:
            requests.append(mav.command_long_encode(ts, tc, C.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id,
                                                    1e6 / hz, 0, 0, 0, 0, 0))
        for m in requests:
            self._send(m)
        self._ensure_origin(deadline)
        if arm:
            setup = [mav.command_long_encode(ts, tc, C.MAV_CMD_DO_SET_MODE, 0, C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                             C.ROVER_MODE_GUIDED, 0, 0, 0, 0, 0),
                     mav.command_long_encode(ts, tc, C.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)]
            if not self._wait("_in_guided_armed", deadline, resend=setup):
                hb = self._heartbeat
                mode = C.ROVER_MODES.get(hb.custom_mode, str(hb.custom_mode)) if hb is not None else "?"
                raise RobotError(f"mavlink: the vehicle at {self.address!r} did not enter GUIDED armed within "
                                 f"{connect_timeout:g} s (mode {mode}, acks {self._acks}): check its pre-arm "
                                 "checks and that GUIDED is allowed")
        if not self._wait("_has_pose", deadline):
            raise ConnectionLost(f"mavlink: no LOCAL_POSITION_NED/ATTITUDE from {self.address!r} within "
                                 f"{connect_timeout:g} s: has the EKF an origin? are streams enabled?")

    def _targets(self) -> tuple[int, int]:
        return self._target if self._target is not None else (0, 0)

    def describe(self) -> dict[str, str]:
        """What the vehicle says about itself (ids, type, autopilot, mode, armed)."""
        out = {"robot": self.name, "address": self.address}
        hb = self._heartbeat
        if hb is not None and self._target is not None:
            out.update(system=str(self._target[0]), component=str(self._target[1]), type=str(hb.type),
                       autopilot=str(hb.autopilot), mode=C.ROVER_MODES.get(hb.custom_mode, str(hb.custom_mode)),
                       armed=str(bool(hb.base_mode & C.MAV_MODE_FLAG_SAFETY_ARMED)),
                       ekf_origin="set by robotexp" if self.origin_set else "the vehicle's")
        return out

    # -- frames ---------------------------------------------------------------------------
    def _raw_pose(self) -> Pose:
        p, a = self._position, self._attitude
        assert p is not None and a is not None
        return ned_to_enu(p.x, p.y, a.yaw)

    def _anchored(self, raw: Pose) -> Pose:
        dx, dy, dth = self._anchor
        c, s = math.cos(dth), math.sin(dth)
        return Pose(c * raw.x - s * raw.y + dx, s * raw.x + c * raw.y + dy, wrap_angle(raw.theta + dth))

    def _anchor_at(self, pose: Pose) -> None:
        with self._cond:
            raw = self._raw_pose()
            dth = wrap_angle(pose.theta - raw.theta)
            c, s = math.cos(dth), math.sin(dth)
            self._anchor = (pose.x - (c * raw.x - s * raw.y), pose.y - (s * raw.x + c * raw.y), dth)
            self._poses = PoseHistory(POSE_SAMPLES)    # poses in the old frame

    def move_to(self, pose: Pose) -> None:
        """Tell the robot it stands at `pose`: poses are reported from there on (the vehicle is stopped
        first; it is not moved).

        Raises:
            RobotError: the robot is closed or the link is lost.
        """
        self._ensure_open()
        self._command(Twist.ZERO)
        self._anchor_at(pose)

    # -- reader thread ----------------------------------------------------------------------
    def _send(self, message: Message) -> None:
        with self._tx_lock:
            self._link.write(self._codec.encode(message))

    def _on_data(self, data: bytes, now: float) -> None:
        for m in self._codec.feed(data) if data else []:
            self._on_message(m, now)
        if now - self._hb_wall >= C.HEARTBEAT_PERIOD:
            self._hb_wall = now
            self._send(self._codec.mav.heartbeat_encode(C.MAV_TYPE_GCS, C.MAV_AUTOPILOT_INVALID, 0, 0, 0,
                                                        C.MAVLINK_VERSION))
        if not self._watch(now):
            self._keep_alive(now)

    def _silent(self, now: float) -> bool:
        return self._target is not None and super()._silent(now)

    def _robot_time(self) -> float:
        return self._time_ms / 1000.0

    def _silence_error(self, now: float) -> RobotError:
        quiet = now - self._last_rx
        if (self._codec.bad_frames, self._codec.dropped_bytes) != self._bad_mark:
            return ProtocolError(f"mavlink: no valid message from the vehicle at {self.address!r} for {quiet:.2f} s "
                                 f"({self._codec.bad_frames} bad frames, {self._codec.dropped_bytes} bytes dropped "
                                 "in all): the link is noisy or the baud rate is wrong")
        return ConnectionLost(f"mavlink: no message from the vehicle at {self.address!r} for {quiet:.2f} s "
                              f"(timeout {self.timeout:g} s): the vehicle or emulator stopped sending")

    def _refuse(self, m: Message, src: tuple[int, int]) -> None:
        self.refused += 1
        if self.refused == 1:
            log.warning("mavlink: %s: ignoring %s from system %d component %d (the vehicle is %d/%d); further "
                        "messages from other sources are counted, not logged", self.address, m.get_type(), *src,
                        *(self._target or (0, 0)))

    def _on_message(self, m: Message, now: float) -> None:  # noqa: C901
        kind = m.get_type()
        src = (m.get_srcSystem(), m.get_srcComponent())
        with self._cond:
            if self._target is None:
                if (kind == "HEARTBEAT" and m.type in C.ROVER_TYPES
                        and m.autopilot != C.MAV_AUTOPILOT_INVALID):
                    self._target = src
                    lock = getattr(self._link, "lock", None)
                    source = getattr(self._link, "source", None)
                    if lock is not None and source is not None:
                        lock(source)
                else:
                    return
            if src != self._target and (src[0] != self._target[0] or kind not in _COMPANION_MESSAGES):
                self._refuse(m, src)
                return
            if kind == "LOCAL_POSITION_NED" and not all(map(math.isfinite, (m.x, m.y, m.vx, m.vy))):
                raise ProtocolError(f"mavlink: the vehicle at {self.address!r} sent a position that is not a number "
                                    f"(x {m.x}, y {m.y}, vx {m.vx}, vy {m.vy}): its position estimate failed; "
                                    "stopping the run")
            if kind == "ATTITUDE" and not all(map(math.isfinite, (m.yaw, m.yawspeed))):
                raise ProtocolError(f"mavlink: the vehicle at {self.address!r} sent an attitude that is not a number "
                                    f"(yaw {m.yaw}, yawspeed {m.yawspeed}): its attitude estimate failed; "
                                    "stopping the run")
            self._last_rx = now
            self._bad_mark = (self._codec.bad_frames, self._codec.dropped_bytes)
            if kind == "HEARTBEAT" and src == self._target:
                self._heartbeat = m
            elif kind == "LOCAL_POSITION_NED":
                old = self._position
                if old is not None:
                    self._distance += math.hypot(m.x - old.x, m.y - old.y)
                    self._time_ms += (m.time_boot_ms - old.time_boot_ms) % (1 << 32)
                self._position = m
                self.state_time = now
                if self._attitude is not None:
                    pose = self._anchored(self._raw_pose())
                    self._state_seen(self._time_ms / 1000.0, pose)
                    t = m.time_boot_ms / 1000.0
                    if t < self._pose_t:            # the vehicle rebooted (or its clock wrapped)
                        self._poses = PoseHistory(POSE_SAMPLES)
                    self._pose_t = t
                    self._poses.add(t, pose)
            elif kind == "ATTITUDE":
                self._attitude = m
            elif kind == "OBSTACLE_DISTANCE":
                self._scan_msg = m
                self._scans += 1                # the scan's stamp: whatever its time_usec holds (0, a repeat)
            elif kind == "DISTANCE_SENSOR":
                self._ranges[m.id] = (now, m)
            elif kind == "GPS_GLOBAL_ORIGIN":
                self._origin = m
            elif kind == "SYS_STATUS" and m.voltage_battery != 0xFFFF:
                self._battery = m.voltage_battery / 1000.0
            elif kind == "COMMAND_ACK":
                self._acks[m.command] = m.result
            self._cond.notify_all()

    def _keep_alive(self, now: float) -> None:
        """Re-send the target in force every `resend` s (the Rover stops after GUID_TIMEOUT without one)."""
        with self._cmd_lock:
            if self._target is not None and now - self._sent_wall > self.resend and self._in_guided_armed():
                self._send_twist(self._twist)

    def _send_twist(self, twist: Twist) -> None:
        ts, tc = self._targets()
        ms = round((time.perf_counter() - self._boot) * 1000) % (1 << 32)
        msg = self._codec.mav.set_position_target_local_ned_encode(
            ms, ts, tc, C.MAV_FRAME_BODY_NED, C.MASK_VELOCITY_YAW_RATE, 0, 0, 0, twist.v, 0, 0, 0, 0, 0, 0, -twist.w)
        self._send(msg)
        self._sent_wall = self.command_time = time.perf_counter()

    # -- Robot hooks -------------------------------------------------------------------------
    def _read(self) -> RobotState:
        with self._cond:
            self._check()
            p, a, hb = self._position, self._attitude, self._heartbeat
            assert p is not None and a is not None and hb is not None    # _connect waited for them
            pose = self._anchored(self._raw_pose())
            v = p.vx * math.cos(a.yaw) + p.vy * math.sin(a.yaw)
            scan = self._scan_msg
            if scan is not None:
                laser: LaserScan | None = self._placed_scan(scan, a.yaw, pose)
            else:
                fresh = time.perf_counter() - DISTANCE_SENSOR_FRESH
                laser = scan_from_distance_sensors([m for t, m in self._ranges.values() if t >= fresh])
            return RobotState(
                time=self._time_ms / 1000.0, pose=pose, velocity=Twist(v, -a.yawspeed), laser=laser,
                battery=self._battery, distance=self._distance,
                extra={"mode": float(hb.custom_mode), "armed": float(bool(hb.base_mode & C.MAV_MODE_FLAG_SAFETY_ARMED)),
                       "frames": float(self._codec.frames), "bad_frames": float(self._codec.bad_frames),
                       "dropped_bytes": float(self._codec.dropped_bytes),
                       "refused": float(self.refused + getattr(self._link, "refused", 0)),
                       "watchdog_stops": float(self.watchdog_stops)})

    def _placed_scan(self, msg: Message, yaw_ned: float, pose: Pose) -> LaserScan:
        """OBSTACLE_DISTANCE `msg` as the robot at `pose` (the newest) sees it, placed from where the
        vehicle was at its stamp when that is on the vehicle's boot clock (see the module); under
        `_cond`."""
        t = msg.time_usec / 1e6
        at = self._poses.at(t) if 0.0 <= self._pose_t - t <= PAIR_SPAN else None
        if at is None:
            return replace(scan_from_obstacle_distance(msg, yaw_ned), stamp=float(self._scans))
        raw_theta = wrap_angle(at.theta - self._anchor[2])
        scan = scan_from_obstacle_distance(msg, wrap_angle(math.pi / 2 - raw_theta))   # the yaw at the stamp
        return replace(scan_in_robot_frame(scan, at, pose), stamp=float(self._scans))

    def _close(self) -> None:
        try:
            ts, tc = self._targets()
            self._send(self._codec.mav.command_long_encode(ts, tc, C.MAV_CMD_DO_SET_MODE, 0,
                                                           C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, C.ROVER_MODE_HOLD,
                                                           0, 0, 0, 0, 0))
        except ConnectionLost as exc:
            log.warning("mavlink: could not switch to HOLD: %s", exc)
        finally:
            self._shutdown()
