"""A MAVLink rover emulator: the simulator's robot served as an ArduPilot-Rover-like vehicle.

Transports (one client at a time):

- UDP, listening on `host`:`port` (default): clients use ``udpout:127.0.0.1:PORT`` and send first
  (our backend sends HEARTBEAT at once); the stream starts with the first datagram;
- UDP to a ground station at `udp` = ``HOST:PORT`` (like SITL/MAVProxy ``--out``): clients bind it
  with ``udp:HOST:PORT``; the stream runs from start-up;
- TCP (`tcp`, like SITL's 5760): ``tcp:127.0.0.1:PORT``; a pseudo-terminal (`pty`): its device path.

Every `tick` (50 ms) of robot time, paced by wall time / `speedup`, it advances the `SimRobot` and
sends what is due: HEARTBEAT at 1 Hz (type GROUND_ROVER, autopilot ARDUPILOTMEGA, custom_mode the
Rover mode, 0x80 when armed), and per message the requested rate (REQUEST_DATA_STREAM groups
EXTENDED_STATUS: SYS_STATUS, POSITION: LOCAL_POSITION_NED, EXTRA1: ATTITUDE, EXTRA3:
OBSTACLE_DISTANCE; or SET_MESSAGE_INTERVAL; 1 Hz each by default, at most 1 / `tick`).
OBSTACLE_DISTANCE carries the sim laser, a full circle of 72 beams, one per 5-degree element (its
centre direction, clockwise from the nose, BODY_FRD), in cm (max_distance + 1 = nothing hit).

Commands: COMMAND_LONG DO_SET_MODE / ARM_DISARM / SET_MESSAGE_INTERVAL / REQUEST_MESSAGE (acked),
SET_MODE, REQUEST_DATA_STREAM, and SET_POSITION_TARGET_LOCAL_NED as Rover reads it in GUIDED and
armed: velocity + yaw rate (speed |vx, vy| signed by vx, turn rate -yaw_rate), yaw rate only (turn
in place), velocity only (straight; the heading-following of LOCAL frames is not emulated);
position targets are ignored. The rover stops on entering GUIDED or HOLD, on disarming, and when no
target came for `guid_timeout` s of robot time (GUID_TIMEOUT, 3 s). The last target received is
`last_target` (and `last_twist`), for fault tests. Serving, TCP and pty transports and fault
injection are `robotexp_drivers.emulation.StreamEmulator`'s.
"""

from __future__ import annotations

import logging
import math
import socket
from dataclasses import replace

from robotexp.errors import ConfigError
from robotexp.robot import Pose, Twist, wrap_angle
from robotexp.sim import LaserConfig, SimRobot, preset
from robotexp.world.model import World
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec, Message
from robotexp_drivers.backend import require_positive
from robotexp_drivers.emulation import StreamEmulator
from robotexp_drivers.mavlink.robot import ROVER_LIMITS, ROVER_RADIUS

__all__ = ["MavlinkEmulator", "STREAM_MESSAGES"]

log = logging.getLogger(__name__)

STREAM_MESSAGES = {C.STREAM_EXTENDED_STATUS: (C.MSG_SYS_STATUS,), C.STREAM_POSITION: (C.MSG_LOCAL_POSITION_NED,),
                   C.STREAM_EXTRA1: (C.MSG_ATTITUDE,), C.STREAM_EXTRA3: (C.MSG_OBSTACLE_DISTANCE,)}
_AUTO_MODES = {C.ROVER_GUIDED, 10, 11, 12}          # modes with the GUIDED_ENABLED flag (AUTO, RTL, SMART_RTL)


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
        scan_range: range of the obstacle sensor [m].
        guid_timeout: stop when no target came for this long [s of robot time].
        battery_mv: battery voltage reported [mV].

    Raises:
        WorldError: the pose is outside the world or touches an obstacle.
        ConfigError: a parameter out of range.
        OSError: the port cannot be bound.
    """

    label = "mavlink emulator"
    radius = ROVER_RADIUS                        # robotexp.robot.RobotEmulator: the simulated footprint [m]
    options = frozenset({"udp"})                 # `robotexp emulate mavlink --udp HOST:PORT`

    def __init__(self, world: World, *, pose: Pose | None = None, port: int = 0, host: str = "127.0.0.1",
                 udp: str | None = None, tcp: bool = False, pty: bool = False, speedup: float = 1.0, seed: int = 0,
                 tick: float = 0.05, scan_range: float = 3.0, guid_timeout: float = C.GUID_TIMEOUT,
                 battery_mv: int = 12600) -> None:
        require_positive("mavlink emulator", speedup=speedup, tick=tick, scan_range=scan_range,
                         guid_timeout=guid_timeout)
        self._init_stream(speedup)
        self.tick, self.guid_timeout, self.battery_mv = tick, guid_timeout, battery_mv
        rover = replace(preset("p3dx"), name="rover", radius=ROVER_RADIUS, limits=ROVER_LIMITS, sonar=None,
                       laser=LaserConfig(beams=C.OBSTACLE_SECTORS, fov=2 * math.pi, range_max=scan_range))
        self.sim = SimRobot(world, robot=rover, pose=pose, seed=seed, sonar=False, laser_in_state=False)
        self.codec = MavlinkCodec(C.VEHICLE_SYSTEM_ID, C.VEHICLE_COMPONENT_ID)
        self.mode, self.armed = C.ROVER_HOLD, False
        self.rates: dict[int, float] = {m: C.DEFAULT_STREAM_RATE for ms in STREAM_MESSAGES.values() for m in ms}
        self._due: dict[int, float] = dict.fromkeys(self.rates, 0.0)
        self._once: set[int] = set()
        self._next_heartbeat = 0.0
        self._last_cmd_time = 0.0
        self.last_target: Message | None = None
        self.last_command: Message | None = None
        self.commands_received = 0
        self.gcs_heartbeats = 0
        self.ignored_targets = 0
        self.packets_sent = 0
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

    # -- the vehicle -----------------------------------------------------------------------
    def _handle(self, m: Message) -> None:
        kind = m.get_type()
        mav = self.codec.mav
        if kind == "HEARTBEAT":
            self.gcs_heartbeats += 1
            return
        self.commands_received += 1
        self.last_command = m
        with self.lock:
            if kind == "SET_POSITION_TARGET_LOCAL_NED":
                self.last_target = m
                self._target(m)
            elif kind == "SET_MODE":
                self._set_mode(m.custom_mode)
            elif kind == "REQUEST_DATA_STREAM":
                groups = list(STREAM_MESSAGES) if m.req_stream_id == C.STREAM_ALL else [m.req_stream_id]
                for g in groups:
                    for msg_id in STREAM_MESSAGES.get(g, ()):
                        self._set_rate(msg_id, float(m.req_message_rate) if m.start_stop else 0.0)
            elif kind == "COMMAND_LONG":
                result = self._command_long(m)
                self._raw.append(self._pack(mav.command_ack_encode(m.command, result)))

    def _command_long(self, m: Message) -> int:
        if m.command == C.MAV_CMD_DO_SET_MODE:
            return self._set_mode(int(m.param2))
        if m.command == C.MAV_CMD_COMPONENT_ARM_DISARM:
            self.armed = m.param1 == 1
            if not self.armed:
                self.sim.command(Twist.ZERO)
            return C.MAV_RESULT_ACCEPTED
        if m.command == C.MAV_CMD_SET_MESSAGE_INTERVAL and int(m.param1) in self.rates:
            us = m.param2
            self._set_rate(int(m.param1), 0.0 if us < 0 else C.DEFAULT_STREAM_RATE if us == 0 else 1e6 / us)
            return C.MAV_RESULT_ACCEPTED
        if m.command == C.MAV_CMD_REQUEST_MESSAGE and int(m.param1) in self.rates:
            self._once.add(int(m.param1))
            return C.MAV_RESULT_ACCEPTED
        return C.MAV_RESULT_UNSUPPORTED

    def _set_mode(self, mode: int) -> int:
        if mode not in C.ROVER_MODES:
            return C.MAV_RESULT_DENIED
        self.mode = mode
        if mode in (C.ROVER_GUIDED, C.ROVER_HOLD):
            self.sim.command(Twist.ZERO)
        return C.MAV_RESULT_ACCEPTED

    def _set_rate(self, msg_id: int, hz: float) -> None:
        self.rates[msg_id] = max(hz, 0.0)
        self._due[msg_id] = self.sim.time

    def _target(self, m: Message) -> None:
        if self.mode != C.ROVER_GUIDED or not self.armed:
            self.ignored_targets += 1
            return
        mask = m.type_mask
        use_pos = not mask & (C.IGNORE_X | C.IGNORE_Y)
        use_vel = not mask & (C.IGNORE_VX | C.IGNORE_VY) and mask & (C.IGNORE_AX | C.IGNORE_AY)
        use_rate = not mask & C.IGNORE_YAW_RATE
        if use_pos or not (use_vel or use_rate):
            self.ignored_targets += 1
            return
        v = math.copysign(math.hypot(m.vx, m.vy), m.vx) if use_vel else 0.0
        w = -m.yaw_rate if use_rate else 0.0
        self.sim.command(Twist(v, w))
        self._last_cmd_time = self.sim.time

    def _pack(self, message: Message) -> bytes:
        self.packets_sent += 1
        return self._maybe_corrupt(self.codec.encode(message))

    def _step(self) -> bytes:
        """Advance the robot by one tick; the bytes of the messages then due."""
        mav = self.codec.mav
        with self.lock:
            if self.sim.time - self._last_cmd_time > self.guid_timeout - 1e-9:
                self.sim.command(Twist.ZERO)
            self.sim.advance(self.tick)
            t = self.sim.time
            state = self.sim.read()
            due = [i for i, hz in self.rates.items() if (hz > 0 and t >= self._due[i] - 1e-9) or i in self._once]
            for i in due:
                if self.rates[i] > 0:
                    self._due[i] = max(self._due[i] + 1.0 / self.rates[i], t + 1e-9)
            self._once.clear()
            scan = self.sim.scan() if C.MSG_OBSTACLE_DISTANCE in due else None
        ms = round(t * 1000) % (1 << 32)
        out: list[bytes] = []
        if t >= self._next_heartbeat - 1e-9:
            self._next_heartbeat += C.HEARTBEAT_PERIOD
            base = (C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (C.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
                    | (C.MAV_MODE_FLAG_GUIDED_ENABLED if self.mode in _AUTO_MODES else 0))
            status = C.MAV_STATE_STANDBY if self.mode == C.ROVER_HOLD else C.MAV_STATE_ACTIVE
            out.append(self._pack(mav.heartbeat_encode(C.MAV_TYPE_GROUND_ROVER, C.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                                       self.mode, status, C.MAVLINK_VERSION)))
        p, vel = state.pose, state.velocity
        yaw_ned = wrap_angle(math.pi / 2 - p.theta)
        for i in sorted(due):
            if i == C.MSG_SYS_STATUS:
                msg = mav.sys_status_encode(0, 0, 0, 0, self.battery_mv, -1, -1, 0, 0, 0, 0, 0, 0)
            elif i == C.MSG_LOCAL_POSITION_NED:
                msg = mav.local_position_ned_encode(ms, p.y, p.x, 0.0, vel.v * math.sin(p.theta),
                                                    vel.v * math.cos(p.theta), 0.0)
            elif i == C.MSG_ATTITUDE:
                msg = mav.attitude_encode(ms, 0.0, 0.0, yaw_ned, 0.0, 0.0, -vel.w)
            else:
                assert scan is not None
                max_cm = round(scan.range_max * 100)
                dist = [C.OBSTACLE_UNKNOWN] * C.OBSTACLE_SECTORS
                for a, r in zip(scan.angles.tolist(), scan.ranges.tolist(), strict=True):
                    k = round(-math.degrees(a) / 5.0) % C.OBSTACLE_SECTORS
                    dist[k] = max_cm + 1 if not math.isfinite(r) else min(max(round(r * 100), 0), max_cm)
                msg = mav.obstacle_distance_encode(round(t * 1e6), C.MAV_DISTANCE_SENSOR_LASER, dist, 5, 0, max_cm,
                                                   5.0, 0.0, C.MAV_FRAME_BODY_FRD)
            out.append(self._pack(msg))
        return b"".join(out)

    def _release(self) -> None:
        if self._udp is not None:
            self._udp.close()
            self._udp = None
        super()._release()
