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
from start-up and frames nobody reads are dropped, as on a serial line.
"""

from __future__ import annotations

import logging
import math
import os
import select
import socket
import threading
import time
import tty
from typing import Self

from robotexp.errors import ConfigError, ConnectionLost
from robotexp.robot import LaserScan, Pose, Twist, wrap_angle
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

__all__ = ["KobukiEmulator", "EmulatorLaser", "HARDWARE_VERSION", "FIRMWARE_VERSION"]

log = logging.getLogger(__name__)

HARDWARE_VERSION = 0x010004   # what the emulator reports: hardware 1.0.4
FIRMWARE_VERSION = 0x010200   # firmware 1.2.0, one the driver recommends (constants.FIRMWARE_RECOMMENDED)
CLIFF_FLOOR_ADC = 2000        # cliff PSD reading over the floor (a plausible value, not a calibration)
GYRO_SAMPLES = 2              # raw gyro samples per frame (the robot sends 2-3)


class KobukiEmulator:
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

    def __init__(self, world: World, *, pose: Pose | None = None, port: int = 0, host: str = "127.0.0.1",
                 pty: bool = False, speedup: float = 1.0, seed: int = 0, laser: LaserConfig | None = None,
                 odometry: OdometryError | None = None, command_timeout: float | None = 1.0,
                 battery_dv: int = 165) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"kobuki emulator: speedup must be > 0, got {speedup}")
        if command_timeout is not None and not command_timeout > 0:
            raise ConfigError(f"kobuki emulator: command_timeout must be > 0 s or None, got {command_timeout}")
        self.speedup = speedup
        self.command_timeout = command_timeout
        self.battery_dv = battery_dv
        self.lock = threading.RLock()      # guards the simulator: the emulator thread and EmulatorLaser
        self.sim = SimRobot(world, robot="kobuki", pose=pose, seed=seed, laser=laser, odometry=odometry,
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
        self._paused = False
        self._raw: list[bytes] = []
        self._corrupt = 0
        self._drop = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._client: socket.socket | None = None
        self._listener: socket.socket | None = None
        self._master = self._slave = -1
        self._decoder = FrameDecoder("command")
        self._reset_stream()
        try:
            if pty:
                self._master, self._slave = os.openpty()
                tty.setraw(self._slave)        # binary bytes: no echo, no CR/LF translation
                os.set_blocking(self._master, False)
                self.address = os.ttyname(self._slave)
            else:
                self._listener = socket.create_server((host, port))
                self._listener.setblocking(False)
                bound_host, bound_port = self._listener.getsockname()[:2]
                self.address = f"socket://{bound_host}:{bound_port}"
        except BaseException:
            self._release()
            raise

    # -- control -----------------------------------------------------------------------
    def start(self) -> Self:
        """Start serving in a background thread; returns self."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name=f"kobuki-emulator {self.address}",
                                            daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving, drop the client and close the simulator. Safe to call twice."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._release()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """True once `close()` ran."""
        return self.sim.closed

    @property
    def connected(self) -> bool:
        """A TCP client is connected (always True on a pseudo-terminal)."""
        return self._client is not None or self._master >= 0

    # -- fault injection (tests, and trying out drivers) ---------------------------------
    def pause_stream(self) -> None:
        """Stop sending feedback (and advancing the robot) without closing: a stalled link."""
        self._paused = True

    def resume_stream(self) -> None:
        """Undo `pause_stream`."""
        self._paused = False

    def send_raw(self, data: bytes) -> None:
        """Send `data` as is before the next frame (e.g. a burst of garbage)."""
        self._raw.append(bytes(data))

    def corrupt_frames(self, n: int) -> None:
        """Send the next `n` frames with a wrong checksum."""
        self._corrupt += n

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

    def _serve(self) -> None:
        cycle = K.FEEDBACK_PERIOD / self.speedup
        next_frame = time.perf_counter()
        while not self._stop.is_set():
            try:
                if self._listener is not None and self._client is None and not self._accept():
                    next_frame = time.perf_counter()
                    continue
                if self._drop:
                    self._drop = False
                    self._disconnect()
                    continue
                now = time.perf_counter()
                if now >= next_frame:
                    if not self._paused:
                        self._send(self._raw_bytes() + self._next_frame())
                    next_frame = max(next_frame + cycle, now)   # late: no burst of frames
                self._receive(max(0.0, next_frame - time.perf_counter()))
            except OSError as exc:
                log.info("kobuki emulator: client gone (%s)", exc)
                self._disconnect()

    def _accept(self) -> bool:
        assert self._listener is not None
        ready, _, _ = select.select([self._listener], [], [], 0.05)
        if not ready:
            return False
        try:
            client, peer = self._listener.accept()
        except BlockingIOError:
            return False
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client = client
        self._reset_stream()
        log.info("kobuki emulator: client %s connected", peer)
        return True

    def _disconnect(self) -> None:
        with self.lock:
            self.sim.command(Twist.ZERO)
        if self._client is not None:
            self._client.close()
            self._client = None

    def _raw_bytes(self) -> bytes:
        taken, self._raw = self._raw, []      # take the list first: a concurrent send_raw() is not lost
        raw = b"".join(taken)
        return raw

    def _send(self, data: bytes) -> None:
        if self._client is not None:
            self._client.sendall(data)
        elif self._master >= 0:
            _, writable, _ = select.select([], [self._master], [], 0)
            if writable:            # nobody reading the terminal: drop the frame, as a serial line does
                try:
                    os.write(self._master, data)
                except BlockingIOError:
                    pass

    def _receive(self, wait: float) -> None:
        """Wait up to `wait` s for command bytes and handle the frames they complete."""
        fd: socket.socket | int = self._client if self._client is not None else self._master
        ready, _, _ = select.select([fd], [], [], wait)
        if not ready:
            return
        if isinstance(fd, socket.socket):
            data = fd.recv(4096)
            if not data:
                log.info("kobuki emulator: client closed the connection")
                self._disconnect()
                return
        else:
            try:
                data = os.read(fd, 4096)
            except BlockingIOError:
                return
        before = self._decoder.dropped_bytes
        for frame in self._decoder.feed(data):
            for message in frame:
                self._handle(message)
        self.bad_command_bytes += self._decoder.dropped_bytes - before

    def _handle(self, m: Message) -> None:
        self.commands_received += 1
        self.last_command = m
        if isinstance(m, BaseControl):
            self.last_base_control = m
            v, w = twist_from_base_control(m.speed_mm_s, m.radius_mm)
            with self.lock:
                self.sim.command(Twist(v, w))
                self._last_cmd_time = self.sim.time
        elif isinstance(m, RequestExtra):
            self._pending_extra |= m.flags
        elif isinstance(m, GetControllerGain):
            self._pending_gain = True
        elif isinstance(m, SetControllerGain):
            self.gains = ControllerInfo(m.gain_type, m.p_x1000, m.i_x1000, m.d_x1000)
        elif isinstance(m, (Sound, SoundSequence)):
            self.sounds.append(m)
        elif isinstance(m, GeneralPurposeOutput):
            self.gpo = m.flags

    def _next_frame(self) -> bytes:
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
        frame = encode_messages(*messages)
        self.frames_sent += 1
        if self._corrupt > 0:
            self._corrupt -= 1
            frame = frame[:-1] + bytes((frame[-1] ^ 0x5A,))
        return frame

    def _release(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1
        with self.lock:
            self.sim.close()


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
