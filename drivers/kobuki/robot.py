"""`KobukiRobot`: the `Robot` backend of a Yujin Kobuki (TurtleBot 2 base) over its serial protocol.

The only place where Kobuki units (mm, mm/s, ticks, 0.01 deg, 0.1 V) become SI. A background reader
thread decodes the 50 Hz feedback stream and keeps the newest state; `read()` returns it. The same
thread is the safety net:

- it re-sends the current Base Control with every chunk of feedback (as Yujin's `kobuki_driver` does
  per frame: the firmware's own safety controller is disabled since firmware 1.1.2, kobuki.md 5);
- a watchdog: when the control loop has not called `command()` for `watchdog` s (0.5 s), it sends a
  stop;
- hazards: while a bumper or a cliff sensor is active, forward motion is refused (the robot may still
  back away or turn in place); while a wheel is dropped every motion is refused. Hazards are reported
  as `RobotState.stalled`, `bumpers` (right, centre, left) and `extra` (`cliff`, `wheel_drop` masks);
  each new bumper press counts as one collision (`extra["collisions"]`);
- silence: no valid frame for `timeout` s (1 s), or an end of file, makes the next `read()` (and the
  paced clock) raise `ConnectionLost` - or `ProtocolError` when bytes did arrive but no valid frame.

Odometry: position from the wheel encoders (16-bit wrap, `encoder_delta`), heading from the factory-
calibrated gyro (inertial sensor, offset by its first reading, as the driver does), starting at the
`pose` given (default 0, 0, 0). Robot time is the sum of the feedback timestamps (20 ms per frame).

The Kobuki has no laser. For exploration the backend accepts an optional `laser` source: any object
whose `read()` returns a `LaserScan` in the robot frame (a real scanner's driver, or, against the
emulator, `robotexp_drivers.kobuki.emulator.EmulatorLaser`, which reads the emulator's simulated
scanner: the Kobuki protocol itself stays pure).

The reader loop, failure, watchdog, `wait_until` and `make_clock` are `robotexp_drivers.backend.StreamBackend`'s.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Protocol

from robotexp import (
    Capability, ConnectionLost, LaserScan, Limits, Pose, ProtocolError, RobotError, RobotState, Twist, wrap_angle)
from robotexp_drivers.backend import StreamBackend, require_positive
from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.kobuki.codec import (
    BaseControl,
    BasicSensorData,
    ControllerInfo,
    FirmwareVersion,
    Frame,
    FrameDecoder,
    GetControllerGain,
    HardwareVersion,
    InertialSensor,
    RequestExtra,
    SoundSequence,
    UniqueDeviceID,
    base_control_from_twist,
    diff_drive_update,
    encode_messages,
    encoder_delta,
)
from robotexp_drivers.kobuki.link import POLL_TIMEOUT, KobukiLink

__all__ = ["KobukiRobot", "LaserSource", "KOBUKI_LIMITS", "KOBUKI_RADIUS"]

log = logging.getLogger(__name__)

# Yujin's Kobuki spec sheet: 0.7 m/s, 180 deg/s (kobuki.md: not in kobuki_core, so UNCONFIRMED there);
# the same numbers as the simulator's "kobuki" preset, so a run behaves alike on both.
KOBUKI_LIMITS = Limits(v_max=0.7, w_max=math.pi, a_max=0.5, alpha_max=math.pi)
KOBUKI_RADIUS = 0.175           # [m] footprint (351.5 mm diameter)
_REQUEST_EVERY = 5              # [frames] between repeated version requests while answers are missing


class LaserSource(Protocol):
    """Anything that returns the newest laser scan in the robot frame."""

    def read(self) -> LaserScan:
        """The newest scan."""
        ...


class KobukiRobot(StreamBackend):
    """A Kobuki base on a serial port (or `socket://` to the emulator), 115200 8N1.

    Connecting waits for the feedback stream, asks for the hardware and firmware versions, the
    unique device ID and the controller gains (`describe()`), and plays the "on" sound. `move_to`
    only re-anchors odometry (the base cannot be moved by command).

    Args:
        address: anything `serial.serial_for_url` accepts (`/dev/kobuki`, `socket://127.0.0.1:PORT`).
        laser: optional source of laser scans (the base has none), see the module docstring.
        pose: where odometry starts (default 0, 0, 0).
        timeout: silence after which the link counts as lost [s].
        watchdog: stop the robot when `command()` was not called for this long [s].
        connect_timeout: wait this long for the first feedback frame [s].
        version_timeout: wait this long for the version answers before going on without them [s].
        sound: play the "on" sound sequence after connecting.
        baudrate: line speed [bit/s].

    Raises:
        ConnectionLost: the port cannot be opened or no byte arrives within `connect_timeout`.
        ProtocolError: bytes arrive but no valid Kobuki frame (wrong device or baud rate).
        ConfigError: a timeout out of range.
    """

    name = "kobuki"
    capabilities = frozenset({Capability.MOVE_TO, Capability.BUMPERS, Capability.CLIFFS, Capability.BATTERY,
                              Capability.PACED_CLOCK})
    radius = KOBUKI_RADIUS
    cycle = K.FEEDBACK_PERIOD   # [s] one feedback frame: a 0.1 s control period ticks every 5 frames
    _link: KobukiLink

    def __init__(self, address: str = K.DEFAULT_PORT, *, laser: LaserSource | None = None,
                 pose: Pose | None = None, timeout: float = 1.0, watchdog: float = 0.5,
                 connect_timeout: float = 2.0, version_timeout: float = 0.5, sound: bool = True,
                 baudrate: int = K.BAUD_RATE) -> None:
        require_positive("kobuki", timeout=timeout, watchdog=watchdog, connect_timeout=connect_timeout)
        self._init_stream(timeout, watchdog)
        self.address = address
        self.limits = KOBUKI_LIMITS
        self._laser = laser
        start = pose or Pose(0.0, 0.0, 0.0)
        # odometry and sensors (guarded by _cond)
        self._x, self._y, self._theta0 = start.x, start.y, start.theta
        self._theta = start.theta
        self._gyro_offset: float | None = None
        self._gyro_angle: float | None = None    # [rad] newest raw gyro heading
        self._last_enc: tuple[int, int] | None = None
        self._last_ts = 0
        self._time_ms = 0
        self._v = self._w = 0.0
        self._distance = 0.0
        self._basic: BasicSensorData | None = None
        self._collisions = 0
        self._sensor_frames = 0
        self._frames_since_request = 0
        self._hardware: HardwareVersion | None = None
        self._firmware: FirmwareVersion | None = None
        self._udid: UniqueDeviceID | None = None
        self._gains: ControllerInfo | None = None
        self.frame_time = 0.0      # [s] perf_counter() when the newest state frame was decoded
        self._decoder = FrameDecoder("feedback")
        self._link = KobukiLink(address, baudrate=baudrate, poll=POLL_TIMEOUT)
        self._start_reader(f"kobuki-reader {address}")
        try:
            self._connect(connect_timeout, version_timeout, sound)
        except BaseException:
            self._shutdown()
            raise
        super().__init__()

    # -- connection ------------------------------------------------------------------
    def _connect(self, connect_timeout: float, version_timeout: float, sound: bool) -> None:
        deadline = time.perf_counter() + connect_timeout
        with self._cond:
            while self._basic is None and self._error is None:
                left = deadline - time.perf_counter()
                if left <= 0:
                    break
                self._cond.wait(left)
            if self._error is not None:
                raise self._error
            if self._basic is None:
                got = self._link.bytes_in
                if got:
                    raise ProtocolError(f"kobuki: {got} bytes from {self.address!r} in {connect_timeout:g} s but "
                                        f"no valid Kobuki frame ({self._decoder.bad_checksums} bad checksums): "
                                        "is it a Kobuki, at 115200 baud?")
                raise ConnectionLost(f"kobuki: no data from {self.address!r} within {connect_timeout:g} s: "
                                     "is the robot switched on (or the emulator running)?")
        self._link.write(encode_messages(RequestExtra(K.REQUEST_VERSION_INFO)))
        self._link.write(encode_messages(GetControllerGain()))
        if sound:
            self._link.write(encode_messages(SoundSequence(K.SOUND_ON)))
        deadline = time.perf_counter() + version_timeout
        with self._cond:
            while not self._info_complete() and self._error is None:
                left = deadline - time.perf_counter()
                if left <= 0:
                    log.warning("kobuki: no version answer from %s within %g s", self.address, version_timeout)
                    break
                self._cond.wait(left)
            if self._error is not None:
                raise self._error
        fw = self._firmware
        if fw is not None and not fw.legacy and fw.major != K.FIRMWARE_MAJOR:
            log.warning("kobuki: firmware %d.%d.%d at %s; the protocol here is that of firmware 1.x",
                        fw.major, fw.minor, fw.patch, self.address)

    def _info_complete(self) -> bool:
        return None not in (self._hardware, self._firmware, self._udid, self._gains)

    def describe(self) -> dict[str, str]:
        """What the robot says about itself: hardware, firmware, udid, gains (as far as it answered)."""
        out = {"robot": self.name, "address": self.address}
        for key, version in (("hardware", self._hardware), ("firmware", self._firmware)):
            if version is not None:
                out[key] = (f"legacy code {version.version}" if version.legacy
                            else f"{version.major}.{version.minor}.{version.patch}")
        if self._udid is not None:
            out["udid"] = str(self._udid)
        if self._gains is not None:
            g = self._gains
            kind = "factory" if g.gain_type == K.GAIN_TYPE_FACTORY else "user"
            out["gains"] = (f"{kind} P={g.p_x1000 / K.GAIN_SCALE:g} I={g.i_x1000 / K.GAIN_SCALE:g} "
                            f"D={g.d_x1000 / K.GAIN_SCALE:g}")
        return out

    def move_to(self, pose: Pose) -> None:
        """Tell the robot it stands at `pose`: odometry reports poses from there on.

        A Kobuki cannot be moved by command; this only re-anchors its odometry (what `run_on_robot`
        needs to measure coverage in a known world). The robot is stopped first.

        Raises:
            RobotError: the robot is closed or the link is lost.
        """
        self._ensure_open()
        self._command(Twist.ZERO)
        with self._cond:
            self._x, self._y, self._theta, self._theta0 = pose.x, pose.y, pose.theta, pose.theta
            self._gyro_offset = self._gyro_angle

    # -- reader thread (StreamBackend hooks) ---------------------------------------------
    def _on_data(self, data: bytes, now: float) -> None:
        got_state = False
        for frame in self._decoder.feed(data) if data else []:
            got_state |= self._on_frame(frame, now)
        if got_state:
            self._frames_since_request += 1
            self._resend(now)
            if not self._info_complete() and self._frames_since_request >= _REQUEST_EVERY:
                self._frames_since_request = 0
                self._request_missing()
        self._watch(now)

    def _silence_error(self, now: float) -> RobotError:
        quiet = now - self._last_rx
        if self._decoder.bad_checksums or self._decoder.bad_lengths:
            return ProtocolError(f"kobuki: no valid frame from {self.address!r} for {quiet:.2f} s "
                                 f"({self._decoder.bad_checksums} bad checksums, {self._decoder.dropped_bytes} "
                                 "bytes dropped): the line is noisy or it is not a Kobuki")
        return ConnectionLost(f"kobuki: no data from {self.address!r} for {quiet:.2f} s "
                              f"(timeout {self.timeout:g} s): the robot or emulator stopped sending")

    def _robot_time(self) -> float:
        return self._time_ms / 1000.0

    def _on_frame(self, frame: Frame, now: float) -> bool:
        """Fold one frame into the state; True when it carried basic sensor data."""
        basic: BasicSensorData | None = None
        inertial: InertialSensor | None = None
        with self._cond:
            for m in frame:
                if isinstance(m, BasicSensorData):
                    basic = m
                elif isinstance(m, InertialSensor):
                    inertial = m
                elif isinstance(m, HardwareVersion):
                    self._hardware = m
                elif isinstance(m, FirmwareVersion):
                    self._firmware = m
                elif isinstance(m, UniqueDeviceID):
                    self._udid = m
                elif isinstance(m, ControllerInfo):
                    self._gains = m
            if basic is not None:
                self._odometry(basic, inertial)
                self._last_rx = self.frame_time = now
                self._sensor_frames += 1
                self._state_seen(self._time_ms / 1000.0, Pose(self._x, self._y, self._theta))
            self._cond.notify_all()
        return basic is not None

    def _odometry(self, basic: BasicSensorData, inertial: InertialSensor | None) -> None:
        """Advance the pose by one frame: encoders for the distance, the gyro for the heading."""
        if inertial is not None:
            self._gyro_angle = inertial.angle
            if self._gyro_offset is None:
                self._gyro_offset = inertial.angle
        enc = (basic.left_encoder, basic.right_encoder)
        if self._last_enc is None:          # first frame: only the references
            self._last_enc, self._last_ts = enc, basic.timestamp_ms
            self._basic = basic
            return
        dl = encoder_delta(enc[0], self._last_enc[0]) * K.TICK_TO_METRE
        dr = encoder_delta(enc[1], self._last_enc[1]) * K.TICK_TO_METRE
        dt_ms = encoder_delta(basic.timestamp_ms, self._last_ts)
        ds, dtheta = diff_drive_update(dl, dr)
        if inertial is not None and self._gyro_offset is not None:
            theta = wrap_angle(self._theta0 + inertial.angle - self._gyro_offset)
        else:
            theta = wrap_angle(self._theta + dtheta)
        mid = self._theta + wrap_angle(theta - self._theta) / 2.0
        self._x += ds * math.cos(mid)
        self._y += ds * math.sin(mid)
        self._theta = theta
        self._distance += abs(ds)
        if dt_ms > 0:
            self._time_ms += dt_ms
            self._v = ds / (dt_ms / 1000.0)
            self._w = inertial.angle_rate if inertial is not None else dtheta / (dt_ms / 1000.0)
        if basic.bumper and not (self._basic is not None and self._basic.bumper):
            self._collisions += 1
        self._last_enc, self._last_ts = enc, basic.timestamp_ms
        self._basic = basic

    def _request_missing(self) -> None:
        flags = ((K.REQUEST_HARDWARE_VERSION if self._hardware is None else 0)
                 | (K.REQUEST_FIRMWARE_VERSION if self._firmware is None else 0)
                 | (K.REQUEST_UDID if self._udid is None else 0))
        if flags:
            self._link.write(encode_messages(RequestExtra(flags)))
        if self._gains is None:
            self._link.write(encode_messages(GetControllerGain()))

    def _resend(self, now: float) -> None:
        """Re-send the command in force with each feedback chunk (kobuki_driver does per frame)."""
        with self._cmd_lock:
            if now - self._cmd_wall <= self.watchdog or self._twist == Twist.ZERO:
                self._send_twist(self._twist)

    def _safe_twist(self, twist: Twist) -> Twist:
        """`twist` with what the hazards forbid removed (see the module docstring)."""
        basic = self._basic
        if basic is None:
            return twist
        if basic.wheel_drop:
            return Twist.ZERO
        if (basic.bumper or basic.cliff) and twist.v > 0.0:
            return Twist(0.0, twist.w)
        return twist

    def _send_twist(self, twist: Twist) -> None:
        """Write the Base Control of `twist`, less what the hazards forbid (caller holds _cmd_lock)."""
        twist = self._safe_twist(twist)
        speed, radius = base_control_from_twist(twist.v, twist.w)
        self._link.write(encode_messages(BaseControl(speed, radius)))
        self.command_time = time.perf_counter()

    # -- Robot hooks -----------------------------------------------------------------
    def _read(self) -> RobotState:
        with self._cond:
            self._check()
            basic = self._basic
            assert basic is not None    # _connect waited for the first frame
            bumpers = tuple(bool(basic.bumper & bit) for bit in (K.BUMPER_RIGHT, K.BUMPER_CENTRE, K.BUMPER_LEFT))
            state = RobotState(
                time=self._time_ms / 1000.0, pose=Pose(self._x, self._y, self._theta),
                velocity=Twist(self._v, self._w),
                stalled=bool(basic.bumper or basic.wheel_drop or basic.cliff or basic.overcurrent),
                bumpers=bumpers, battery=basic.battery_voltage, distance=self._distance,
                extra={"collisions": float(self._collisions), "cliff": float(basic.cliff),
                       "wheel_drop": float(basic.wheel_drop), "overcurrent": float(basic.overcurrent),
                       "charger": float(basic.charger), "buttons": float(basic.buttons),
                       "frames": float(self._sensor_frames), "bad_checksums": float(self._decoder.bad_checksums),
                       "dropped_bytes": float(self._decoder.dropped_bytes),
                       "watchdog_stops": float(self.watchdog_stops)})
        if self._laser is None:
            return state
        return RobotState(time=state.time, pose=state.pose, velocity=state.velocity, laser=self._laser.read(),
                          stalled=state.stalled, bumpers=state.bumpers, battery=state.battery,
                          distance=state.distance, extra=state.extra)
