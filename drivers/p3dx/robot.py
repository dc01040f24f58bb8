"""`P3DXRobot`: the Pioneer P3-DX backend (ARCOS over a serial cable, or MobileSim over TCP).

The only place where the protocol's units (mm, degrees, SIP units) become SI. Connect runs
ARIA's handshake (SYNC0/1/2, OPEN, CONFIG, ENABLE, SONAR and, on a simulator, the simulated
laser); a reader thread then decodes the stream, keeps the newest state and acts as a watchdog:
it stops the robot when the control loop has not commanded for `watchdog` seconds, sends PULSE
when nothing else went out for 0.5 s, and fails the link after `silence` seconds without data
(the shared parts are `robotexp_drivers.backend.StreamBackend`'s; robot time is SIPs x cycle).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import replace
from types import MappingProxyType

import numpy as np

from robotexp import (
    Capability, ConnectionLost, LaserScan, Limits, Pose, ProtocolError, RobotError, RobotState, SonarScan, Twist,
    compose_pose, relative_pose, wrap_angle)
from robotexp_drivers.backend import StreamBackend, reads_until, require_positive

from . import codec as k
from . import constants as c
from .link import SerialLink

__all__ = ["P3DXRobot"]

log = logging.getLogger(__name__)

_SONAR_ANGLES = np.radians(np.array([p[2] for p in c.SONAR_POSES], dtype=np.float64))
_SONAR_RANGE_MAX = c.SONAR_NO_ECHO_MM / 1000.0
_SONAR_POSITIONS = np.array([p[:2] for p in c.SONAR_POSES], dtype=np.float64) / 1000.0


def _int16(value: int) -> int:
    return value - 0x10000 if value >= 0x8000 else value


CLOSE_DRAIN = 0.5   # [s] input read and dropped after CLOSE before the link closes (see P3DXLink.drain)

class P3DXRobot(StreamBackend):
    """A Pioneer P3-DX (or any ARCOS robot, or MobileSim / our emulator) as a `Robot`.

    Args:
        address: serial device ("/dev/ttyUSB0"), "host" or "host:port" (MobileSim, port 8101), or
            any `serial_for_url` URL.
        baudrate: serial speed [baud]; 9600 (ARCOS default). Ignored over TCP.
        laser: request MobileSim's simulated laser when the robot is a simulator.
        laser_range: [m] laser ranges at or beyond this read as no hit (`inf`).
        laser_offset: [m] laser position ahead of the robot centre (18 mm on a P3-DX).
        max_speed: forward speed limit [m/s] (default: the robot's CONFIG maximum).
        watchdog: [s] stop the robot when no command came from the control loop for this long.
        silence: [s] the link counts as lost after this long without a packet from the robot.
        connect_timeout: [s] longest handshake, and longest wait for the first SIP after it.
        ground_truth: on a simulator (MobileSim, our emulator), ask for a SIMSTAT packet before every
            SIP and report the simulator's true pose as `RobotState.true_pose`, so a run's path,
            coverage and ATE are measured against the truth while the explorer sees odometry.

    Raises:
        ConnectionLost: the port cannot be opened, or the robot stops answering.
        ProtocolError: the handshake fails.
        ConfigError: a parameter out of range.
    """

    name = "p3dx"
    capabilities = frozenset({Capability.SONAR, Capability.LASER, Capability.MOVE_TO})
    radius = c.ROBOT_RADIUS_MM / 1000.0
    # with a laser device mounted (robotexp.run.laser_mount.robot_options): no simulated-laser packets
    mounted_laser_options: Mapping[str, object] = MappingProxyType({"laser": False})
    _join_timeout = 2.0

    def __init__(self, address: str, *, baudrate: int = c.SERIAL_BAUD, laser: bool = True,
                 laser_range: float = c.LASER_NO_HIT_MM / 1000.0, laser_offset: float = c.LASER_X_MM / 1000.0,
                 max_speed: float | None = None, watchdog: float = 0.5, silence: float = 1.0,
                 connect_timeout: float = 5.0, ground_truth: bool = True) -> None:
        require_positive("p3dx", watchdog=watchdog, silence=silence, connect_timeout=connect_timeout,
                         laser_range=laser_range)
        self._init_stream(silence, watchdog)
        self._last_byte = time.perf_counter()   # [s] when the last bytes came (ARIA's 100 ms gap rule)
        self._bytes_since_sip = 0               # bytes received since the last valid SIP
        self._first_sip_wait = 2.0 + silence    # [s] silence allowed before the first SIP
        self.address = address
        self.silence = silence
        self.laser_range, self.laser_offset = laser_range, laser_offset
        self.decoder = k.PacketDecoder(max_count=255)
        self.config: k.ConfigPacket | None = None
        self.robot_name = self.robot_type = self.robot_subtype = ""
        self._state: RobotState | None = None
        self._pending: RobotState | None = None
        # odometry [mm] and [rad] in the robot's own frame; the reported pose is anchored by move_to
        self._raw_xy: tuple[int, int] | None = None
        self._odom_mm = [0.0, 0.0]
        self._odom = Pose(0.0, 0.0)
        self._frame = (Pose(0.0, 0.0), Pose(0.0, 0.0))    # (reported pose, odometry) at the anchor
        self._ground_truth = ground_truth
        self._truth: Pose | None = None     # the simulator's true pose (SIMSTAT), in the world's frame
        self._distance = 0.0
        self._sips = 0
        self._stalled = False
        self._collisions = 0
        self._sonar = np.full(c.SONAR_NUM, np.inf)
        self._scan: LaserScan | None = None
        self._scans = 0                 # laser scans completed
        self._scan_buf: np.ndarray | None = None
        self._laser_active = False
        self._laser_cfg = (c.LASER_DEFAULT_START_DEG, c.LASER_DEFAULT_END_DEG)
        self._last_write = time.perf_counter()
        self.link = SerialLink(address, baudrate=baudrate)
        try:
            self._connect(connect_timeout, laser)
            self.limits = self._limits_from_config()
            if max_speed is not None:
                self.set_max_speed(max_speed)
            self._first_sip_wait = max(connect_timeout, silence)
            self._start_reader(f"p3dx-reader {address}")
            self._wait_state(lambda s: True, self._first_sip_wait)
            if laser and self.is_simulator:
                try:    # the explorer learns the laser's range from the first state it reads
                    self._wait_state(lambda s: s.laser is not None, self.silence)
                except ConnectionLost:
                    if self._error is not None:
                        raise
                    log.warning("p3dx: %s sends no simulated laser packets", self.robot_name)
        except BaseException:
            self._shutdown()
            raise
        super().__init__()

    # -- connection ------------------------------------------------------------------
    @property
    def is_simulator(self) -> bool:
        """True for MobileSim, AMRISim and our emulator (SYNC2 name or CONFIG serial "SIM")."""
        sim_serial = self.config is not None and self.config.serial_number == c.SIM_SERIAL
        return self.robot_name in (c.SIM_NAME, c.AMRISIM_NAME) or sim_serial

    @property
    def dist_conv(self) -> float:
        """DistConvFactor [mm/unit] of the reported subclass (§9)."""
        return c.DIST_CONV_FACTOR_SH if self.robot_subtype.lower() == "p3dx-sh" else c.DIST_CONV_FACTOR

    @property
    def cycle(self) -> float:
        """The robot's SIP cycle [s] (CONFIG, else 100 ms)."""
        ms = self.config.sip_cycle_ms if self.config is not None else 0
        return ms / 1000.0 if ms > 0 else c.SIP_PERIOD_S

    def describe(self) -> dict[str, str]:
        """What the robot says about itself: name, type, subtype, serial, firmware, link."""
        cfg = self.config
        return {"name": self.robot_name, "type": self.robot_type, "subtype": self.robot_subtype,
                "serial": cfg.serial_number if cfg else "?", "firmware": cfg.firmware_version if cfg else "?",
                "simulator": str(self.is_simulator), "link": self.link.url}

    def _write(self, data: bytes) -> None:
        self.link.write(data)
        self._last_write = time.perf_counter()

    def _next_packet(self, deadline: float, kinds: tuple[type, ...]) -> k.Packet | None:
        """Read until a packet of one of `kinds` arrives (others are dropped) or `deadline` passes."""
        for _ in reads_until(deadline):
            data = self.link.read()
            packets = self.decoder.feed(data) if data else self.decoder.flush()
            for pkt in packets:
                if isinstance(pkt, kinds):
                    return pkt
        return None

    def _connect(self, timeout: float, laser: bool) -> None:
        deadline = time.monotonic() + timeout
        self.link.reset_input()
        seq, reply = 0, None
        while seq < 3:
            if time.monotonic() >= deadline:
                raise ProtocolError(f"p3dx: no handshake with {self.link.url!r} within {timeout:g} s (last "
                                    f"step SYNC{seq}); is it a Pioneer/MobileSim, and the baud rate right?")
            self._write(k.frame(seq))
            reply = self._next_packet(min(deadline, time.monotonic() + c.SYNC_REPLY_TIMEOUT_S),
                                      (k.SyncReply, k.StandardSip))
            if isinstance(reply, k.StandardSip):
                # §3: the robot is still open from a previous session; close it and start again
                self._write(k.cmd_close())
                time.sleep(0.1)
                self.link.reset_input()
                self.decoder = k.PacketDecoder(max_count=255)
                seq = 0
            elif isinstance(reply, k.SyncReply) and reply.seq == seq:
                seq += 1
            else:
                seq = 0
        assert isinstance(reply, k.SyncReply)
        self.robot_name, self.robot_type, self.robot_subtype = reply.name, reply.robot_type, reply.robot_subtype
        log.info("p3dx: connected to %s (%s %s) at %s", reply.name, reply.robot_type, reply.robot_subtype,
                 self.link.url)
        self._write(k.cmd_open() + k.cmd_config())
        cfg = self._next_packet(min(deadline, time.monotonic() + c.CONFIG_WAIT_S), (k.ConfigPacket,))
        self.config = cfg if isinstance(cfg, k.ConfigPacket) else None
        self._write(k.cmd_enable(True) + k.cmd_sonar(True))
        if self._ground_truth and self.is_simulator:
            self._write(k.cmd_sim_stat(c.SIM_STAT_EVERY_SIP))
        if laser and self.is_simulator:
            start, end = self._laser_cfg
            self._write(k.cmd_sim_laser(start, end, c.LASER_DEFAULT_RES_CDEG, c.LRF_EXTENDED))

    def _limits_from_config(self) -> Limits:
        cfg = self.config
        v_max = c.MAX_VELOCITY_MM_S / 1000.0
        w_max = math.radians(c.MAX_RVELOCITY_DEG_S)
        a_max, alpha_max = c.SIM_TRANS_ACCEL_MM_S2 / 1000.0, math.radians(c.SIM_ROT_ACCEL_DEG_S2)
        if cfg is not None:
            v_max = min(v_max, cfg.trans_vel_max / 1000.0) if cfg.trans_vel_max > 0 else v_max
            w_max = min(w_max, math.radians(cfg.rot_vel_max)) if cfg.rot_vel_max > 0 else w_max
            a_max = cfg.trans_accel / 1000.0 if cfg.trans_accel > 0 else a_max
            alpha_max = math.radians(cfg.rot_accel) if cfg.rot_accel > 0 else alpha_max
        return Limits(v_max, w_max, a_max, alpha_max)

    # -- reader thread (StreamBackend hooks) -----------------------------------------
    def _receive(self) -> bytes:
        return self.link.read()

    def _on_data(self, data: bytes, now: float) -> None:
        if data:
            self._last_byte = now
            self._bytes_since_sip += len(data)
            packets = self.decoder.feed(data)
        elif self.decoder.buffered and now - self._last_byte > c.BODY_GAP_S:
            packets = self.decoder.flush()     # §2.1: a gap > 100 ms drops a partial packet
        else:
            packets = []
        for pkt in packets:
            if isinstance(pkt, k.StandardSip):   # the state stream is the robot's life; other bytes are not
                self._last_rx = now
                self._bytes_since_sip = 0
            self._handle(pkt)
        if not self._watch(now) and now - self._last_write > c.REFRESH_S:
            self._write(k.cmd_pulse())

    def _silent(self, now: float) -> bool:
        # before the first SIP the robot (or a loaded MobileSim) may take the connect wait to start its stream
        limit = self.timeout if self._sips else max(self.timeout, self._first_sip_wait)
        return now - self._last_rx > limit

    def _silence_error(self, now: float) -> RobotError:
        if self._bytes_since_sip:
            return ProtocolError(f"p3dx: no valid SIP from {self.link.url!r} for {now - self._last_rx:.2f} s "
                                 f"(silence {self.silence:g} s) though {self._bytes_since_sip} bytes came: the line "
                                 "is noisy, the baud rate is wrong or it is not a Pioneer")
        return ConnectionLost(f"p3dx: no data from {self.link.url!r} for {now - self._last_rx:.2f} s (silence "
                              f"{self.silence:g} s); the robot or the link is down")

    def _send_twist(self, twist: Twist) -> None:
        v_mm = max(c.INT_ARG_MIN, min(c.INT_ARG_MAX, round(twist.v * 1000.0)))
        w_deg = max(c.INT_ARG_MIN, min(c.INT_ARG_MAX, round(math.degrees(twist.w))))
        self._write(k.cmd_vel(v_mm) + k.cmd_rvel(w_deg))
        self.command_time = time.perf_counter()

    def _robot_time(self) -> float:
        return self._state.time if self._state is not None else 0.0

    def _time_tolerance(self) -> float:
        return self.cycle / 4

    def _handle(self, pkt: k.Packet) -> None:
        if isinstance(pkt, k.StandardSip):
            if self._pending is not None:        # the scan for the previous SIP never completed
                self._publish(self._pending)
            state = self._sip_state(pkt)
            if self._laser_active:
                self._pending = state
            else:
                self._publish(state)
        elif isinstance(pkt, k.SimLaserPacket):
            self._laser_packet(pkt)
        elif isinstance(pkt, k.ConfigPacket):
            self.config = pkt
        elif isinstance(pkt, k.SimStat) and self._ground_truth:
            self._truth = Pose(pkt.true_x_mm / 1000.0, pkt.true_y_mm / 1000.0,
                               wrap_angle(math.radians(pkt.true_th_deg)))

    def _publish(self, state: RobotState) -> None:
        self._pending = None
        with self._cond:
            self._state = state
            self._cond.notify_all()
        self._state_seen(state.time, state.pose)

    def _sip_state(self, sip: k.StandardSip) -> RobotState:
        dist = self.dist_conv
        if self._raw_xy is None:
            # first SIP: take the position as MobileSim sends it (a wrapping int16 of units)
            self._odom_mm = [_int16(sip.xpos) * dist, _int16(sip.ypos) * dist]
        else:
            self._odom_mm[0] += k.unwrap_position_delta(self._raw_xy[0], sip.xpos) * dist
            self._odom_mm[1] += k.unwrap_position_delta(self._raw_xy[1], sip.ypos) * dist
        self._raw_xy = (sip.xpos, sip.ypos)
        old = self._odom
        self._odom = Pose(self._odom_mm[0] / 1000.0, self._odom_mm[1] / 1000.0,
                          wrap_angle(sip.thpos * c.ANGLE_CONV_FACTOR))
        if self._sips:
            self._distance += old.distance_to(self._odom)
        self._sips += 1
        left, right = sip.left_vel * c.VEL_CONV_FACTOR, sip.right_vel * c.VEL_CONV_FACTOR
        v = (left + right) / 2000.0
        w = (math.radians(sip.rot_vel_x10 / c.ROTVEL_SCALE) if sip.rot_vel_x10 is not None
             else (right - left) * c.DIFF_CONV_FACTOR / 2.0)
        for num, rng in sip.sonar:
            if 0 <= num < c.SONAR_NUM:
                mm = rng * c.RANGE_CONV_FACTOR
                self._sonar[num] = math.inf if mm >= c.SONAR_NO_ECHO_MM else mm / 1000.0
        front = tuple(bool(sip.front_bumpers >> i & 1) for i in range(7))
        rear = tuple(bool(sip.rear_bumpers >> i & 1) for i in range(7))
        stalled = sip.left_stalled or sip.right_stalled or any(front) or any(rear)
        if stalled and not self._stalled:
            self._collisions += 1
        self._stalled = stalled
        battery = (sip.battery_x10 if sip.battery_x10 is not None else sip.battery_dv) / c.BATTERY_SCALE
        anchor, anchor_odom = self._frame
        pose = compose_pose(anchor, relative_pose(anchor_odom, self._odom))
        extra = {"collisions": float(self._collisions), "motors_enabled": float(sip.motors_enabled),
                 "estop": float(sip.estop)}
        return RobotState(time=self._sips * self.cycle, pose=pose, velocity=Twist(v, w), laser=self._scan,
                          sonar=SonarScan(_SONAR_ANGLES, self._sonar.copy(), _SONAR_RANGE_MAX, _SONAR_POSITIONS),
                          stalled=stalled, bumpers=front + rear, battery=battery, distance=self._distance,
                          extra=extra, true_pose=self._truth)

    def _laser_packet(self, pkt: k.SimLaserPacket) -> None:
        if pkt.total <= 0:
            return
        if pkt.first == 0 or self._scan_buf is None or len(self._scan_buf) != pkt.total:
            self._scan_buf = np.full(pkt.total, np.nan)
        end = min(pkt.first + len(pkt.ranges), pkt.total)
        self._scan_buf[pkt.first:end] = np.asarray(pkt.ranges[:end - pkt.first], dtype=np.float64) / 1000.0
        if pkt.first + len(pkt.ranges) < pkt.total:
            return
        ranges = self._scan_buf
        self._scan_buf = None
        ranges[(ranges >= self.laser_range) | (ranges >= c.LASER_NO_HIT_MM / 1000.0)] = np.inf
        lo, hi = sorted(self._laser_cfg)
        angles = np.radians(np.linspace(lo, hi, len(ranges))) if len(ranges) > 1 else np.zeros(1)
        self._scans += 1                # every SIP until the next scan repeats this one: its number tells
        self._scan = LaserScan(angles, ranges, min(self.laser_range, c.LASER_NO_HIT_MM / 1000.0), self.laser_offset,
                               stamp=float(self._scans))
        self._laser_active = True
        if self._pending is not None:
            self._publish(replace(self._pending, laser=self._scan))

    # -- Robot hooks -----------------------------------------------------------------
    def _wait_state(self, ready: object, timeout: float) -> RobotState:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                if self._error is not None:
                    raise self._error
                if self._state is not None and ready(self._state):  # type: ignore[operator]
                    return self._state
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ConnectionLost(f"p3dx: no state from {self.link.url!r} for {timeout:g} s")
                self._cond.wait(left)

    def _read(self) -> RobotState:
        with self._cond:
            self._check()
            assert self._state is not None
            return self._state

    def move_to(self, pose: Pose) -> None:
        """Move the robot to `pose` in MobileSim (SIM_SET_POSE) and report poses from there on.

        On a real robot only the reported pose changes: tell it where the robot stands. The
        heading sent is whole degrees, so the pose is taken with its heading rounded.

        Raises:
            RobotError: the robot is closed or the link is lost.
        """
        self._ensure_open()
        x_mm, y_mm, th_deg = round(pose.x * 1000), round(pose.y * 1000), round(math.degrees(pose.theta))
        self._command(Twist.ZERO)
        self._write(k.cmd_sim_set_pose(x_mm, y_mm, th_deg))
        with self._cond:
            self._frame = (Pose(x_mm / 1000.0, y_mm / 1000.0, wrap_angle(math.radians(th_deg))), self._odom)
            self._scan = None
            t = self._state.time if self._state is not None else 0.0
        # two cycles: the packets in flight when the command left were measured before the move
        self._wait_state(lambda s: s.time >= t + 2 * self.cycle - 1e-6 and (s.laser is not None
                                                                          or not self._laser_active),
                         self.silence + 0.5)

    def _release(self) -> None:
        """Stop the robot, send CLOSE (and let the peer read it), then close the link."""
        if not self.link.closed:
            try:
                self.link.write(k.cmd_vel(0) + k.cmd_rvel(0) + k.cmd_enable(False) + k.cmd_close())
                self.link.drain(CLOSE_DRAIN)      # so the peer reads them before the socket closes
            except ConnectionLost:
                pass
        self.link.close()
