"""A Kobuki emulator: the simulator's `kobuki` robot served over the Kobuki serial protocol.

It listens on TCP (127.0.0.1 only, by default; address ``socket://127.0.0.1:PORT``) or on a
pseudo-terminal (`os.openpty`; the address is the slave device path, so a driver opens a real
serial device). Like the robot it streams a feedback frame (IDs 1, 3, 4, 5, 6, 13, 16) every 20 ms of
robot time, advancing the `SimRobot` by 20 ms per frame, paced by wall time divided by `speedup`.

Commands: Base Control drives the simulated base (kobuki.md 3.1 inverse conversion); Request Extra
and Get Controller Gain are answered in the next frame; sounds and outputs are recorded. The last
Base Control received is kept in `last_base_control` (fault tests check it is a stop).

Emulation choices (documented, not the firmware's): a blocked base (the simulator's stall) presses
the centre bumper; the cliff sensors read a constant floor value; encoders count the simulator's
odometry (so its odometry-error model applies), the gyro reads the true heading; and, as a
conservative choice where the real firmware keeps going (kobuki.md 5), the base stops when no Base
Control arrived for `command_timeout` s of robot time (1 s; the host driver re-sends at 50 Hz).
The stream starts when a TCP client connects (one client at a time); on a pseudo-terminal it runs
from start-up and frames nobody reads are dropped, as on a serial line. Serving, transports and
fault injection are `robotexp_drivers.emulation.StreamEmulator`'s.
"""

from __future__ import annotations

import logging
import math

from robotexp import ConfigError, ConnectionLost, LaserScan, Pose, Twist, wrap_angle
from robotexp.sim import LaserConfig, OdometryError, SimRobot
from robotexp.world.model import World
from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.kobuki.codec import (
    BaseControl,
    BasicSensorData,
    CliffSensors,
    ControllerInfo,
    DockingIR,
    FirmwareVersion,
    FrameDecoder,
    GeneralPurposeInput,
    GeneralPurposeOutput,
    GetControllerGain,
    HardwareVersion,
    InertialSensor,
    Message,
    MotorCurrent,
    RawGyro,
    RequestExtra,
    SetControllerGain,
    Sound,
    SoundSequence,
    UniqueDeviceID,
    encode_messages,
    twist_from_base_control,
)
from robotexp_drivers.emulation import StreamEmulator, odometry_model
from robotexp_drivers.kobuki.robot import KOBUKI_RADIUS

__all__ = ["KobukiEmulator", "EmulatorLaser", "HARDWARE_VERSION", "FIRMWARE_VERSION"]

log = logging.getLogger(__name__)

HARDWARE_VERSION = 0x010004   # what the emulator reports: hardware 1.0.4
FIRMWARE_VERSION = 0x010200   # firmware 1.2.0, one the driver recommends (constants.FIRMWARE_RECOMMENDED)
CLIFF_FLOOR_ADC = 2000        # cliff PSD reading over the floor (a plausible value, not a calibration)
GYRO_SAMPLES = 2              # raw gyro samples per frame (the robot sends 2-3)


class KobukiEmulator(StreamEmulator):
    """Serve a simulated Kobuki of `world` over the Kobuki protocol (call `start()`, or use `with`).

    Args:
        world: the environment.
        pose: start pose (default: the world's first named pose, else its home).
        port: TCP port on `host` (0: any free one; read `address`). Ignored with `pty`.
        host: interface to listen on (127.0.0.1 by default: local clients only).
        pty: serve on a pseudo-terminal instead of TCP.
        speedup: robot seconds per wall second (1.0 = real time).
        seed: seed of the simulator's noise.
        laser: the simulated scanner read through `EmulatorLaser` (default: the preset's).
        odometry: odometry error model of the encoders (default: perfect).
        command_timeout: stop the base when no Base Control arrived for this long [s of robot time];
            None keeps the last command forever, like the firmware.
        battery_dv: battery voltage reported [0.1 V].

    Raises:
        WorldError: the pose is outside the world or touches an obstacle.
        ConfigError: a parameter out of range.
        OSError: the port cannot be bound.
    """

    label = "kobuki emulator"
    radius = KOBUKI_RADIUS                       # robotexp.robot.RobotEmulator: the simulated footprint [m]
    options = frozenset({"odometry"})            # `robotexp emulate kobuki --odometry-error SPEC`

    def __init__(self, world: World, *, pose: Pose | None = None, port: int = 0, host: str = "127.0.0.1",  # noqa: PLR0913
                 pty: bool = False, speedup: float = 1.0, seed: int = 0, laser: LaserConfig | None = None,
                 odometry: OdometryError | str | None = None, command_timeout: float | None = 1.0,
                 battery_dv: int = 165) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"kobuki emulator: speedup must be > 0, got {speedup}")
        if command_timeout is not None and not command_timeout > 0:
            raise ConfigError(f"kobuki emulator: command_timeout must be > 0 s or None, got {command_timeout}")
        self._init_stream(speedup)
        self.command_timeout = command_timeout
        self.battery_dv = battery_dv
        self.sim = SimRobot(world, robot="kobuki", pose=pose, seed=seed, laser=laser, odometry=odometry_model(odometry),
                            sonar=False, laser_in_state=False)
        self.last_base_control: BaseControl | None = None
        self.last_command: Message | None = None
        self.commands_received = 0
        self.sounds: list[Sound | SoundSequence] = []
        self.gpo = K.GPO_DEFAULT
        self.gains = ControllerInfo(K.GAIN_TYPE_FACTORY, K.FACTORY_P_X1000, K.FACTORY_I_X1000, K.FACTORY_D_X1000)
        self.frames_sent = 0
        self.bad_command_bytes = 0
        self.hazards = (0, 0, 0)           # (bumper, cliff, wheel_drop) masks forced by `set_hazards`
        self._decoder = FrameDecoder("command")
        self._reset_stream()
        try:
            if pty:
                self.address = self._open_pty()
            else:
                bound_host, bound_port = self._listen(host, port)
                self.address = f"socket://{bound_host}:{bound_port}"
        except BaseException:
            self._release()
            raise

    @property
    def _period(self) -> float:
        return K.FEEDBACK_PERIOD / self.speedup

    # -- fault injection (tests, and trying out drivers) ---------------------------------
    def drop_client(self) -> None:
        """Close the current TCP connection (the robot 'vanishes'); the next client may connect."""
        self._drop = True

    def set_hazards(self, *, bumper: int = 0, cliff: int = 0, wheel_drop: int = 0) -> None:
        """Force bumper / cliff / wheel-drop bits (`constants.BUMPER_*` ...) into every frame; 0 clears."""
        self.hazards = (bumper, cliff, wheel_drop)

    # -- serving -------------------------------------------------------------------------
    def _reset_stream(self) -> None:
        self._frame = 0
        self._left = self._right = 0.0          # [m] wheel travel since the start
        self._gyro_frame = 0
        self._pending_extra = 0
        self._pending_gain = False
        self._last_cmd_time = 0.0
        with self.lock:
            self._odom = self.sim.read().pose
            self.sim.command(Twist.ZERO)
        self._decoder = FrameDecoder("command")

    def _on_connect(self) -> None:
        self._reset_stream()

    def _on_bytes(self, data: bytes) -> None:
        before = self._decoder.dropped_bytes
        for frame in self._decoder.feed(data):
            for message in frame:
                self._handle(message)
        self.bad_command_bytes += self._decoder.dropped_bytes - before

    def _handle(self, m: Message) -> None:
        self.commands_received += 1
        self.last_command = m
        match m:                                  # one case per command sub-payload (the codec's classes)
            case BaseControl(speed_mm_s=speed, radius_mm=radius):
                self.last_base_control = m
                v, w = twist_from_base_control(speed, radius)
                with self.lock:
                    self.sim.command(Twist(v, w))
                    self._last_cmd_time = self.sim.time
            case RequestExtra(flags=flags):
                self._pending_extra |= flags
            case GetControllerGain():
                self._pending_gain = True
            case SetControllerGain():
                self.gains = ControllerInfo(m.gain_type, m.p_x1000, m.i_x1000, m.d_x1000)
            case Sound() | SoundSequence():
                self.sounds.append(m)
            case GeneralPurposeOutput(flags=flags):
                self.gpo = flags

    def _step(self) -> bytes:
        """Advance the robot by one cycle and encode the feedback frame of its new state."""
        b = K.WHEEL_BASE
        with self.lock:
            if (self.command_timeout is not None
                    and self.sim.time - self._last_cmd_time > self.command_timeout - 1e-9):
                self.sim.command(Twist.ZERO)
            self.sim.advance(K.FEEDBACK_PERIOD)
            state = self.sim.read()
        old, new = self._odom, state.pose
        self._odom = new
        chord = math.hypot(new.x - old.x, new.y - old.y)
        fwd = math.cos(old.theta) * (new.x - old.x) + math.sin(old.theta) * (new.y - old.y)
        dth = wrap_angle(new.theta - old.theta)
        arc = chord * (dth / 2) / math.sin(dth / 2) if abs(dth) > 1e-9 else chord   # arc length, not chord
        ds = math.copysign(arc, fwd)
        dl, dr = ds - dth * b / 2, ds + dth * b / 2
        self._left += dl
        self._right += dr
        self._frame += 1
        true = state.true_pose or state.pose
        bumper, cliff, wheel_drop = self.hazards
        bumper |= K.BUMPER_CENTRE if state.stalled else 0
        dt = K.FEEDBACK_PERIOD
        basic = BasicSensorData(
            timestamp_ms=(self._frame * round(K.FEEDBACK_PERIOD * 1000)) % K.TIMESTAMP_MODULUS,
            bumper=bumper, wheel_drop=wheel_drop, cliff=cliff,
            left_encoder=round(self._left * K.METRE_TO_TICK) % K.ENCODER_MODULUS,
            right_encoder=round(self._right * K.METRE_TO_TICK) % K.ENCODER_MODULUS,
            left_pwm=_pwm(dl / dt), right_pwm=_pwm(dr / dt),
            buttons=0, charger=K.CHARGER_DISCHARGING, battery_dv=self.battery_dv, overcurrent=0)
        rate_deg = math.degrees(state.velocity.w)
        raw_z = _clamp(round(rate_deg / K.RAW_GYRO_SCALE), 32767)
        gyro = RawGyro(self._gyro_frame, tuple((0, 0, raw_z) for _ in range(GYRO_SAMPLES)))
        self._gyro_frame = (self._gyro_frame + GYRO_SAMPLES) % 256
        moving = 20 if (dl or dr) else 0
        messages: list[Message] = [
            basic, DockingIR(0, 0, 0),
            InertialSensor(_clamp(round(math.degrees(true.theta) / K.INERTIA_SCALE), 32767),
                           _clamp(round(rate_deg / K.INERTIA_SCALE), 32767)),
            CliffSensors(CLIFF_FLOOR_ADC, CLIFF_FLOOR_ADC, CLIFF_FLOOR_ADC), MotorCurrent(moving, moving),
            gyro, GeneralPurposeInput(0, 0, 0, 0, 0)]
        if self._pending_extra & K.REQUEST_HARDWARE_VERSION:
            messages.append(HardwareVersion(HARDWARE_VERSION))
        if self._pending_extra & K.REQUEST_FIRMWARE_VERSION:
            messages.append(FirmwareVersion(FIRMWARE_VERSION))
        if self._pending_extra & K.REQUEST_UDID:
            messages.append(UniqueDeviceID(0x4B4F4255, 0x4B49454D, 1))   # "KOBU" "KIEM" 1
        if self._pending_gain:
            messages.append(self.gains)
        self._pending_extra, self._pending_gain = 0, False
        self.frames_sent += 1
        return self._maybe_corrupt(encode_messages(*messages))

class EmulatorLaser:
    """The emulator's simulated scanner as a `laser` source of `KobukiRobot` (a Kobuki has no laser).

    `read()` casts the simulator's laser at the robot's current simulated pose. It stays outside the
    Kobuki protocol: the backend gets it as a separate sensor, like a real scanner with its own
    driver. The scan is of the emulator's present instant, which may be a frame (20 ms of robot
    time) newer than the newest feedback frame the backend has decoded when the control loop lags.
    """

    def __init__(self, emulator: KobukiEmulator) -> None:
        self.emulator = emulator

    def read(self) -> LaserScan:
        """The scan now, in the robot frame.

        Raises:
            ConnectionLost: the emulator was closed.
        """
        with self.emulator.lock:
            if self.emulator.closed:
                raise ConnectionLost(f"kobuki emulator at {self.emulator.address}: closed, no laser scan")
            return self.emulator.sim.scan()


def _clamp(value: int, bound: int) -> int:
    return max(-bound, min(bound, value))


def _pwm(wheel_speed: float) -> int:
    """A plausible applied PWM [%] for a wheel speed [m/s] (full scale at 0.7 m/s; not a calibration)."""
    return _clamp(round(wheel_speed / 0.7 * 100), 100)
