"""`P3DXEmulator`: the `sim` robot of a world served over the ARIA protocol, as MobileSim would.

Answers ARIA clients (and our `P3DXRobot`) on TCP (127.0.0.1:8101 by default) or on a
pseudo-terminal whose slave device path a driver opens as a serial port. It replies to
SYNC0/1/2 with "MobileSim"/"Pioneer"/"p3dx", to CONFIG with MobileSim's CONFIG packet (carrying the
emulated robot's limits), sends a SIP every 100 ms of robot time after OPEN (sonar included) and,
once the simulated laser is enabled (35 or 230), the scan right after each SIP, with the field of
view and increment that 36..38 (or 231..233) asked for, as MobileSim does (ARIA labels reading i
`min(start, end) + i * increment` and counts them as MobileSim does). Odometry restarts at 0, 0, 0
with each client, as in MobileSim's new session.
SIM_SET_POSE moves the robot without changing odometry (`SimRobot.move_to`), SIM_RESET goes back
to the start. Robot time advances one SIP cycle per SIP sent, paced by wall time / `speedup`; within
a cycle the world moves as wall time passes (each time the serving loop wakes, at least every
`SUBSTEP_S` of robot time, the simulator catches up with the time due), so a laser emulator measuring
it between two SIPs sees the robot where it is, and the SIP goes out at the cycle's end (lockstep:
the whole cycle at once).
Motion is ARCOS's (`ArcosMotion`): VEL / RVEL / VEL2 velocities, MOVE (distance) and HEAD / DHEAD /
DCHEAD (heading) position control, each ramped by the SETA / SETRA accelerations and capped by
SETV / SETRV / SETRVDIR; the session starts with the limits CONFIG reports. Sonar is cast from
p3dx.p's transducer poses (`P3DX_SONAR_ARIA`), the laser is MobileSim's LMS200 model. Commands are
dispatched through a table (`_dispatch_table`).

For fault tests it records the commands it received (`last_command`, `commanded`) and can
`inject` raw bytes, `stall` (stop sending without closing) or `vanish` (drop the connection).
"""

from __future__ import annotations

import collections
import logging
import math
import os
import select
import socket
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, Pose, Twist, WorldError, compose_pose, relative_pose, wrap_angle
from robotexp.sim.presets import P3DX_SONAR, P3DX_SONAR_ARIA, LaserConfig, OdometryError
from robotexp.sim.robot import approach     # the simulator's own velocity ramp, applied per cycle
from robotexp.world.model import World
from robotexp_drivers.emulation import EmulatorBase, odometry_model

from . import codec as k
from . import constants as c
from .motion import ArcosMotion, RotMode

__all__ = ["P3DXEmulator", "reading_beams"]

log = logging.getLogger(__name__)

SUBSTEP_S = 0.02       # [s of robot time] longest step of the world within a SIP cycle (the Kobuki's frame)

# commands after which a lockstep emulator may send the next SIP at once
_VELOCITY_COMMANDS = frozenset({c.CMD_VEL, c.CMD_RVEL, c.CMD_ROTATE, c.CMD_VEL2, c.CMD_STOP, c.CMD_ESTOP,
                                c.CMD_QSTOP})
# laser field-of-view commands -> which of (start, end, increment) they set
_LRF_FOV: dict[int, int] = {c.CMD_OLD_SIM_LRF_SET_FOV_START: 0, c.CMD_SIM_LRF_SET_FOV_START: 0,
                            c.CMD_OLD_SIM_LRF_SET_FOV_END: 1, c.CMD_SIM_LRF_SET_FOV_END: 1,
                            c.CMD_OLD_SIM_LRF_SET_RES: 2, c.CMD_SIM_LRF_SET_RES: 2}


EMULATED_NAME = "robotexp"      # SYNC2 / CONFIG name when not posing as a simulator
EMULATED_SERIAL = "EMU"         # CONFIG serial number then (ARIA takes "SIM" for a simulator)


class _Closed(Exception):
    """The client connection ended (EOF or error)."""


class _TcpConn:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def recv(self, timeout: float) -> bytes:
        ready, _, _ = select.select([self.sock], [], [], max(timeout, 0.0))
        if not ready:
            return b""
        try:
            data = self.sock.recv(65536)
        except OSError as exc:
            raise _Closed(str(exc)) from exc
        if not data:
            raise _Closed("client closed the connection")
        return data

    def send(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except OSError as exc:
            raise _Closed(str(exc)) from exc

    def close(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass        # already disconnected
        self.sock.close()


class _PtyConn:
    """The master side of a pseudo-terminal; the slave stays open so the device always exists."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)          # no echo, no line editing before the client configures it
        self.path = os.ttyname(self.slave)

    def recv(self, timeout: float) -> bytes:
        ready, _, _ = select.select([self.master], [], [], max(timeout, 0.0))
        if not ready:
            return b""
        try:
            return os.read(self.master, 65536)
        except OSError as exc:
            raise _Closed(str(exc)) from exc

    def send(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.master, view)
            except BlockingIOError:
                select.select([], [self.master], [], 0.1)
                continue
            except OSError as exc:
                raise _Closed(str(exc)) from exc
            view = view[n:]

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass    # closed already


class P3DXEmulator(EmulatorBase):
    """Serve a simulated P3-DX over the ARIA protocol.

    Args:
        world: a World, or a world name / map path (`robotexp.world.loader.load_world`).
        pose: start pose: a Pose, a pose name of the world or "x,y,theta" (mm, mm, deg); default
            as `robotexp explore`.
        port: TCP port on `host` (0 picks a free one); ignored with `pty`.
        host: address to listen on (127.0.0.1 by default: only this machine).
        pty: serve on a pseudo-terminal instead of TCP (`address` is its device path).
        speedup: robot time per wall time (1.0 = real time).
        seed: seed of the simulator's noise.
        laser: the simulated laser (default: MobileSim's LMS200 model, 181 beams over 180 deg up to
            32.767 m with +-5 mm uniform noise, mounted where ARIA's parameter file and `P3DXRobot`
            put it: 18 mm ahead, 21 mm on p3dx-sh). A
            client's field of view and increment are picked from its beams (nearest beam), so a
            finer increment than the laser's repeats beams.
        robot: simulator preset name.
        robot_type, robot_subtype: what SYNC2 and CONFIG report.
        simulator: identify as MobileSim (SYNC2 and CONFIG name "MobileSim", serial "SIM": ARIA then
            uses its simulated laser, packets 0x60/0x61); False: as a real robot (name
            `EMULATED_NAME`, serial `EMULATED_SERIAL`), so ARIA opens its own laser driver (-laserPort).
        watchdog: [s of robot time] stop the robot when no command came for this long (None:
            never, as MobileSim, which only warns).
        lockstep: send the next SIP as soon as a velocity command answers the last one (at the
            latest after one cycle / `speedup` of wall time): a client that keeps up then runs
            exactly as on the embedded simulator, as fast as it can (tests, benchmarks).

    Raises:
        WorldError: unknown world or a start pose in an obstacle.
        ConfigError: a parameter out of range.
        OSError: the port is taken.
    """

    label = "p3dx emulator"
    join_timeout = 5.0
    radius = c.ROBOT_RADIUS_MM / 1000.0          # robotexp.robot.RobotEmulator: the simulated footprint [m]
    options = frozenset({"odometry"})            # `robotexp emulate p3dx --odometry-error SPEC`

    def __init__(self, world: World | str, *, pose: Pose | str | None = None, port: int = c.SIM_TCP_PORT,  # noqa: PLR0913
                 host: str = "127.0.0.1", pty: bool = False, speedup: float = 1.0, seed: int = 0,
                 laser: LaserConfig | None = None, robot: str = "p3dx", robot_type: str = c.DEFAULT_CLASS,
                 robot_subtype: str = c.DEFAULT_SUBCLASS, simulator: bool = True, watchdog: float | None = None,
                 lockstep: bool = False, odometry: OdometryError | str | None = None) -> None:
        from robotexp.world.poses import resolve_pose
        from robotexp.sim import SimRobot, preset
        from robotexp.world.loader import load_world

        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"p3dx emulator: speedup must be > 0, got {speedup}")
        if watchdog is not None and not watchdog > 0:
            raise ConfigError(f"p3dx emulator: watchdog must be > 0 s or None, got {watchdog}")
        odometry_err = odometry_model(odometry)
        self.world = load_world(world) if isinstance(world, str) else world
        robot_preset = preset(robot)
        if robot_preset.sonar == P3DX_SONAR:       # cast from the transducers where ARIA (p3dx.p) puts them
            robot_preset = replace(robot_preset, sonar=P3DX_SONAR_ARIA)
        if isinstance(pose, Pose):
            self.start_pose = pose
        else:
            self.start_pose, _ = resolve_pose(self.world, pose, robot_preset.radius)
        self.speedup, self.watchdog, self.lockstep = speedup, watchdog, lockstep
        self._stepped = False
        self._cycle_wall: float | None = None      # wall time the cycle in progress began (None: none)
        self._cycle_done = 0.0                     # [s of robot time] of it simulated so far
        self.robot_type, self.robot_subtype = robot_type, robot_subtype
        sh = robot_subtype.lower() == "p3dx-sh"
        self.dist_conv = c.DIST_CONV_FACTOR_SH if sh else c.DIST_CONV_FACTOR
        if laser is None:       # MobileSim's LMS200 model, cast from p3dx.p's LaserX (where ARIA puts it)
            laser = replace(robot_preset.laser, range_max=c.SIM_LMS200_RANGE_MM / 1000.0,
                            uniform=c.SIM_LMS200_NOISE_MM / 1000.0,
                            offset_x=(c.LASER_X_MM_SH if sh else c.LASER_X_MM) / 1000.0)
        self.commands: collections.deque[k.Command] = collections.deque(maxlen=10000)
        self.last_command: k.Command | None = None      # the last command other than PULSE
        self.commanded = (0, 0)                         # last VEL [mm/s] and RVEL [deg/s] in force
        self.sessions = 0
        self.sips_sent = 0
        self._init_serving()
        self._stall = threading.Event()
        self._vanish = threading.Event()
        self._inject: collections.deque[bytes] = collections.deque()
        self._server: socket.socket | None = None
        self._pty: _PtyConn | None = None
        self.sim = SimRobot(self.world, robot=robot_preset, pose=self.start_pose, seed=seed,
                            laser=laser, sonar=False, odometry=odometry_err)
        try:
            lim = self.sim.limits
            self.config = replace(k.mobilesim_config(robot_type, robot_subtype),
                                  trans_vel_max=round(lim.v_max * 1000), rot_vel_max=round(math.degrees(lim.w_max)),
                                  trans_accel=round(lim.a_max * 1000), trans_decel=round(lim.a_max * 1000),
                                  rot_accel=round(math.degrees(lim.alpha_max)),
                                  rot_decel=round(math.degrees(lim.alpha_max)))
            if not simulator:
                self.config = replace(self.config, name=EMULATED_NAME, serial_number=EMULATED_SERIAL)
            self._sim_limits = lim      # each cycle the simulator ramps with SETA's / SETRA's value in force
            # cast once before serving: the first client must not wait for the first casts' set-up
            self.sim.scan()
            self.sim.sonar()
            if pty:
                self._pty = _PtyConn()
                self.address = self._pty.path
            else:
                self._server = socket.create_server((host, port))
                self._server.settimeout(0.05)
                self.address = f"{host}:{self._server.getsockname()[1]}"
        except BaseException:
            self.sim.close()
            raise
        self._sim_odom = self.start_pose             # the SimRobot's odometry starts at its pose
        self._reset_session()

    def _release(self) -> None:
        if self._server is not None:
            self._server.close()
        if self._pty is not None:
            self._pty.close()
        self.sim.close()

    def inject(self, data: bytes) -> None:
        """Send raw bytes to the client before the next packet (garbage, bad checksums)."""
        self._inject.append(bytes(data))

    def stall(self, on: bool = True) -> None:
        """Stop (or resume) sending anything while keeping the connection and reading commands."""
        if on:
            self._stall.set()
        else:
            self._stall.clear()

    def vanish(self) -> None:
        """Drop the client connection at once and stop serving (a crashed simulator)."""
        self._vanish.set()

    @property
    def robot_time(self) -> float:
        """Robot time [s] of the simulator."""
        return self.sim.time

    # -- serving -----------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stop.is_set() and not self._vanish.is_set():
            conn: _TcpConn | _PtyConn
            if self._pty is not None:
                conn = self._pty
            else:
                assert self._server is not None
                try:
                    sock, _ = self._server.accept()
                except TimeoutError:
                    continue
                except OSError:
                    return          # the listening socket was closed
                sock.setblocking(True)
                conn = _TcpConn(sock)
            try:
                self._session(conn)
            except _Closed as exc:
                log.info("p3dx emulator: client gone (%s)", exc)
            finally:
                self._end_session()
                if isinstance(conn, _TcpConn):
                    conn.close()
                elif self._vanish.is_set():
                    conn.close()

    def _reset_session(self) -> None:
        self._stage = 0                      # next expected SYNC number; 3 = synced
        self._open = False
        cfg = self.config                    # the session starts with the limits CONFIG reports
        self.motion = ArcosMotion(cfg.trans_vel_max, cfg.rot_vel_max, cfg.trans_accel, cfg.trans_decel,
                                  cfg.rot_accel, cfg.rot_decel)
        self._handlers = self._dispatch_table()
        self._estopped = False
        self._velocity = Twist.ZERO          # the robot's speeds after the last cycle
        self._enabled = True                 # MobileSim: motors enabled at session start
        self._sonar_on = True                # ARIA assumes sonar on
        self._laser_mode = c.LRF_OFF
        # FOV start, end [deg] and increment [1/100 deg] asked for; None: the laser's own beams
        self._lrf_fov: tuple[int, int, int] | None = None
        self._beams: npt.NDArray[np.int64] | None = None      # laser beam of each reading, -1: none
        self._odom = Pose(0.0, 0.0)          # MobileSim: odometry restarts at 0, 0, 0 every session
        self._simstat = c.SIM_STAT_STOP
        self._decoder = k.CommandDecoder(max_count=255)
        self._last_cmd_time = self.sim.time
        self._cycle_wall = None

    def _end_session(self) -> None:
        self.sim.command(Twist.ZERO)
        self._reset_session()

    def _session(self, conn: _TcpConn | _PtyConn) -> None:
        period = c.SIP_PERIOD_S / self.speedup
        next_cycle = time.monotonic()
        while True:
            if self._vanish.is_set():
                conn.close()
                return
            if self._stop.is_set():     # take the commands already sent (the client's last stop)
                for cmd in self._decoder.feed(conn.recv(0.0)):
                    self._handle(cmd, conn)
                return
            now = time.monotonic()
            wait = min(0.05, next_cycle - now, SUBSTEP_S / self.speedup) if self._open else 0.05
            data = conn.recv(wait)
            if data:
                for cmd in self._decoder.feed(data):
                    if self._handle(cmd, conn):
                        return               # CLOSE
            while self._inject and not self._stall.is_set():
                conn.send(self._inject.popleft())
            if self._open and self._cycle_wall is not None:
                self._advance_cycle(time.monotonic())
            if self._open and (time.monotonic() >= next_cycle or self._stepped):
                self._stepped = False
                self._cycle(conn)
                next_cycle = time.monotonic() + period if self.lockstep else next_cycle + period
                if next_cycle < time.monotonic() - period:      # late: no burst to catch up
                    next_cycle = time.monotonic()

    def _send(self, conn: _TcpConn | _PtyConn, data: bytes) -> None:
        if not self._stall.is_set():
            conn.send(data)

    def _handle(self, cmd: k.Command, conn: _TcpConn | _PtyConn) -> bool:
        """Act on one command; True when the session ends (CLOSE)."""
        n = cmd.cmd
        self.commands.append(cmd)
        if not (n == c.CMD_PULSE and self._open):
            self.last_command = cmd
        self._last_cmd_time = self.sim.time
        if not self._open and n in (0, 1, 2) and not (n == 1 and self._stage == 3):
            # §3: answer SYNCn; an out-of-order number continues from there (as MobileSim)
            reply = k.SyncReply(2, self.config.name, self.robot_type, self.robot_subtype) if n == 2 else k.SyncReply(n)
            self._send(conn, k.encode_packet(reply))
            self._stage = n + 1
            return False
        if n == c.CMD_OPEN and not self._open:
            self._open = True
            self.sessions += 1
            log.info("p3dx emulator: session %d opened", self.sessions)
            return False
        if n == c.CMD_CLOSE:
            self.motion.stop()
            self.commanded = (0, 0)
            return True
        handler = self._handlers.get(n)
        if handler is None:
            # BATTERYINFO (62), laser power (31), ...: accepted, not emulated
            log.debug("p3dx emulator: command %d ignored", n)
            return False
        ival = cmd.arg if isinstance(cmd.arg, int) else 0
        handler(ival, cmd.arg, conn)
        if n in _VELOCITY_COMMANDS:
            self._stepped = self.lockstep and n != c.CMD_VEL    # our driver sends VEL, then RVEL
        return False

    def _dispatch_table(self) -> dict[int, Callable[[int, object, _TcpConn | _PtyConn], None]]:
        """Command number -> handler(int argument, raw argument, connection) (§4, §4.1, §8.1)."""
        m = self.motion
        table: dict[int, Callable[[int, object, _TcpConn | _PtyConn], None]] = {
            c.CMD_PULSE: lambda i, a, conn: None,
            c.CMD_OPEN: lambda i, a, conn: None,
            c.CMD_VEL: self._drive(m.set_vel),
            c.CMD_RVEL: self._drive(m.set_rot_vel),
            c.CMD_ROTATE: self._drive(m.set_rot_vel),
            c.CMD_VEL2: self._drive(self._vel2),
            c.CMD_MOVE: self._drive(m.move),
            c.CMD_HEAD: self._drive(m.head),
            c.CMD_DHEAD: self._drive(lambda deg: m.delta_head(deg, self._heading_deg())),
            c.CMD_DCHEAD: self._drive(lambda deg: m.delta_setpoint(deg, self._heading_deg())),
            c.CMD_STOP: self._drive(lambda _: m.stop()),
            c.CMD_ESTOP: self._estop,
            c.CMD_QSTOP: self._estop,
            c.CMD_SETV: lambda i, a, conn: m.set_trans_max(i),
            c.CMD_SETRV: lambda i, a, conn: m.set_rot_max(i),
            c.CMD_SETRVDIR: lambda i, a, conn: m.set_rot_max_dir(i),
            c.CMD_SETA: lambda i, a, conn: m.set_trans_accel(i),
            c.CMD_SETRA: lambda i, a, conn: m.set_rot_accel(i),
            c.CMD_ENABLE: self._enable,
            c.CMD_SONAR: lambda i, a, conn: setattr(self, "_sonar_on", bool(i)),
            c.CMD_CONFIG: lambda i, a, conn: self._send(conn, k.encode_packet(self.config)),
            c.CMD_OLD_SIM_LRF_ENABLE: self._laser_enable,
            c.CMD_SIM_LRF_ENABLE: self._laser_enable,
            c.CMD_SIM_SET_POSE: self._sim_set_pose,
            c.CMD_SIM_RESET: lambda i, a, conn: self._move(self.start_pose, reset_odom=True),
            c.CMD_SETO: self._set_odometry,
            c.CMD_SIM_STAT: self._sim_stat,
        }
        for number, which in _LRF_FOV.items():
            table[number] = self._fov_handler(which)
        return table

    def _fov_handler(self, which: int) -> Callable[[int, object, _TcpConn | _PtyConn], None]:
        """The handler of the laser field-of-view command that sets bound `which`."""
        return lambda i, a, conn: self._set_fov(which, i)

    def _drive(self, command: Callable[[int], None]) -> Callable[[int, object, _TcpConn | _PtyConn], None]:
        """A motion command's handler: ignored while the motors are disabled (as MobileSim)."""
        def handle(value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
            if self._enabled:
                command(value)
                self.commanded = (round(self.motion.vel), round(self.motion.rot_vel))
        return handle

    def _vel2(self, value: int) -> None:
        left, right = (b * c.VEL2_DIVISOR for b in k.unpack_2bytes(value))
        self.motion.set_vel(round((left + right) / 2))
        self.motion.set_rot_vel(round(math.degrees((right - left) * c.DIFF_CONV_FACTOR / 2)))

    def _estop(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        self.motion.stop()
        self.commanded = (0, 0)
        self._estopped = True                # stopped at once, not decelerating (MobileSim)

    def _enable(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        self._enabled = bool(value)
        if not self._enabled:
            self.motion.stop()
            self.commanded = (0, 0)

    def _laser_enable(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        self._laser_mode = value if value in (c.LRF_OFF, c.LRF_BASIC, c.LRF_EXTENDED) else c.LRF_OFF

    def _sim_set_pose(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        if isinstance(arg, tuple):
            self._move(Pose(arg[0] / 1000.0, arg[1] / 1000.0, wrap_angle(math.radians(arg[2]))), reset_odom=False)

    def _set_odometry(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        self._odom = Pose(0.0, 0.0) if not isinstance(arg, tuple) else Pose(
            arg[0] / 1000.0, arg[1] / 1000.0, math.radians(arg[2]))
        if self.motion.rot_mode is RotMode.HEAD:
            self.motion.stop()              # a heading goal of the old frame means nothing now

    def _sim_stat(self, value: int, arg: object, conn: _TcpConn | _PtyConn) -> None:
        self._simstat = value
        if value == c.SIM_STAT_ONCE:
            self._send(conn, k.encode_packet(self._simstat_packet()))

    def _heading_deg(self) -> float:
        return math.degrees(self._odom.theta)

    def _set_fov(self, which: int, value: int) -> None:
        fov = list(self._lrf_fov or (c.LASER_DEFAULT_START_DEG, c.LASER_DEFAULT_END_DEG, c.LASER_DEFAULT_RES_CDEG))
        fov[which] = abs(value) if which == 2 else value    # MobileSim reads the increment unsigned
        if fov[2] == 0:
            log.warning("p3dx emulator: laser increment 0 ignored")
            return
        self._lrf_fov = (fov[0], fov[1], fov[2])
        self._beams = reading_beams(self.sim.laser_config.angles(), *self._lrf_fov)

    def _move(self, pose: Pose, reset_odom: bool) -> None:
        try:
            self.sim.move_to(pose)
        except WorldError as exc:
            log.warning("p3dx emulator: cannot move the robot: %s", exc)
            return
        self._sim_odom = pose
        self.motion.stop()
        self.commanded = (0, 0)
        if reset_odom:
            self._odom = Pose(0.0, 0.0)

    # -- one SIP cycle ---------------------------------------------------------------
    def _cycle(self, conn: _TcpConn | _PtyConn) -> None:
        """End the cycle in progress (none yet, or lockstep: begin one and simulate it whole), send its
        SIP (and laser scan), and, unless lockstep, begin the next, simulated as wall time passes."""
        if self._cycle_wall is None:
            self._begin_cycle()
        self._simulate(c.SIP_PERIOD_S - self._cycle_done)
        self._cycle_wall = None
        self._end_cycle(conn)
        if not self.lockstep:
            self._begin_cycle()
            self._cycle_wall = time.monotonic()

    def _simulate(self, dt: float) -> None:
        if dt > 1e-9:
            self.sim.advance(dt)
            self._cycle_done += dt

    def _advance_cycle(self, now: float) -> None:
        """Simulate the cycle in progress up to the robot time due at wall time `now` (catch up, no more)."""
        assert self._cycle_wall is not None
        due = min(c.SIP_PERIOD_S, (now - self._cycle_wall) * self.speedup)
        self._simulate(due - self._cycle_done)

    def _begin_cycle(self) -> None:
        """The velocity goals of a cycle, from the commands received so far."""
        self._cycle_done = 0.0
        if self.watchdog is not None and self.sim.time - self._last_cmd_time > self.watchdog:
            self.motion.stop()
            self.commanded = (0, 0)
        # the cycle's velocities, held through its sub-steps: ramped over the whole cycle as one simulator
        # step would (the distance per cycle ARCOS's position control plans with)
        twist = Twist.ZERO
        if self._estopped:               # at once: no ramp
            self._estopped = False
        else:                            # the goals of this cycle, ramped (as `ArcosMotion.step`)
            now = self._velocity
            v, w = self.motion.targets(self._heading_deg(), c.SIP_PERIOD_S)
            accel, rot_accel = self.motion.ramp_rates(now.v * 1000.0, math.degrees(now.w), v, w)
            twist = Twist(approach(now.v, v / 1000.0, accel / 1000.0 * c.SIP_PERIOD_S),
                          approach(now.w, math.radians(w), math.radians(rot_accel) * c.SIP_PERIOD_S))
        self.sim.limits = replace(self._sim_limits, a_max=math.inf, alpha_max=math.inf)
        self.sim.command(twist)

    def _end_cycle(self, conn: _TcpConn | _PtyConn) -> None:
        """Odometry and the packets of the cycle just simulated."""
        state = self.sim.read()
        self._velocity = state.velocity
        # odometry of our own: the sim's odometry jumps on move_to, MobileSim's does not
        step = relative_pose(self._sim_odom, state.pose)
        self.motion.travelled(step.x * 1000.0)
        self._odom = compose_pose(self._odom, step)
        self._sim_odom = state.pose
        if self._simstat == c.SIM_STAT_EVERY_SIP:
            self._send(conn, k.encode_packet(self._simstat_packet()))
        self._send(conn, k.encode_packet(self._sip(state.velocity, state.stalled)))
        self.sips_sent += 1
        if self._laser_mode != c.LRF_OFF and state.laser is not None:
            ranges = state.laser.ranges
            if self._beams is not None:
                ranges = np.where(self._beams >= 0, ranges[self._beams], np.inf)
            mm = [c.LASER_NO_HIT_MM if not math.isfinite(r) else min(round(r * 1000), c.LASER_NO_HIT_MM)
                  for r in ranges.tolist()]
            o = self._odom
            pose = tuple(max(-32768, min(32767, round(val))) for val in
                         (o.x * 1000, o.y * 1000, math.degrees(o.theta)))
            moved = c.LASER_FLAG_ROBOT_MOVED if state.velocity.v or state.velocity.w else 0
            self._send(conn, b"".join(k.encode_laser_scan(mm, extended=self._laser_mode == c.LRF_EXTENDED,
                                                          pose=pose, flags=moved)))  # type: ignore[arg-type]

    def _sip(self, vel: Twist, stalled: bool) -> k.StandardSip:
        o = self._odom
        v_mm, w_dps = vel.v * 1000.0, math.degrees(vel.w)
        diff = vel.w / c.DIFF_CONV_FACTOR            # §5.1: wheels = v -+ rad(rotvel) / DiffConvFactor
        sonar: tuple[tuple[int, int], ...] = ()
        if self._sonar_on and self.sim.preset.sonar is not None:
            ranges = self.sim.sonar().ranges.tolist()
            sonar = tuple((i, c.SONAR_NO_ECHO_MM if not math.isfinite(r) else min(round(r * 1000),
                                                                                  c.SONAR_NO_ECHO_MM))
                          for i, r in enumerate(ranges[:c.MAX_SONAR_PER_SIP]))
        flags = (c.FLAG_MOTORS_ENABLED if self._enabled else 0) | (0x06 if self._sonar_on else 0)
        return k.StandardSip(
            xpos=k.position_to_raw(o.x * 1000.0, self.dist_conv), ypos=k.position_to_raw(o.y * 1000.0, self.dist_conv),
            thpos=k.heading_to_raw(math.degrees(o.theta)), left_vel=_i16(v_mm - diff), right_vel=_i16(v_mm + diff),
            battery_dv=c.SIM_BATTERY_DV, stall_bumpers=(c.STALL_LEFT | c.STALL_RIGHT) if stalled else 0,
            flags=flags, sonar=sonar, grip_state=0, analog_port=0, analog=0, digin=c.SIM_DIGIN, digout=c.SIM_DIGOUT,
            battery_x10=c.SIM_BATTERY_DV, charge_state=c.CHARGE_STATE_NOT_CHARGING, rot_vel_x10=_i16(w_dps * 10),
            fault_flags=0, lat_vel=0, temperature=c.TEMPERATURE_NONE, state_of_charge=0)

    def _simstat_packet(self) -> k.SimStat:
        t = self.sim.read().true_pose or self.start_pose
        ms = round(c.SIP_PERIOD_S * 1000)
        return k.SimStat(flags=c.SIMSTAT_HAVE_MAP, sim_interval_ms=ms, real_interval_ms=round(ms / self.speedup),
                         last_interval_ms=ms, true_x_mm=round(t.x * 1000), true_y_mm=round(t.y * 1000),
                         true_th_deg=round(math.degrees(t.theta)), dop_x100=-1)


def reading_beams(beam_angles: npt.NDArray[np.float64], start_deg: int, end_deg: int,
                  res_cdeg: int) -> npt.NDArray[np.int64]:
    """The laser beam that serves each reading of a field of view asked for with 36..38 / 231..233.

    MobileSim (StageInterface::Laser::setResolution) sends ceil(ceil(fov) / increment) + 1
    readings and ARIA (ArSimulatedLaser) puts reading i at min(start, end) + i * increment.

    Args:
        beam_angles: angles [rad] of the laser's beams, increasing, (beams,) float64.
        start_deg, end_deg: field of view [deg], either order.
        res_cdeg: increment between readings [1/100 deg], > 0.

    Returns:
        (readings,) int64: the index of the beam nearest to each reading, -1 when the reading
        lies more than half a beam spacing outside the laser's beams (sent as "no hit").

    Raises:
        ConfigError: `res_cdeg` is not > 0.
    """
    if res_cdeg <= 0:
        raise ConfigError(f"p3dx emulator: laser increment must be > 0 (1/100 deg), got {res_cdeg}")
    lo, hi = min(start_deg, end_deg), max(start_deg, end_deg)
    res = res_cdeg / 100.0
    n = math.ceil(math.ceil(hi - lo) / res) + 1
    want = np.radians(lo + res * np.arange(n))
    beams = np.asarray(beam_angles, dtype=np.float64)
    if len(beams) == 1:
        nearest, half = np.zeros(n, dtype=np.int64), math.pi
    else:
        i = np.clip(np.searchsorted(beams, want), 1, len(beams) - 1)
        nearest = np.where(want - beams[i - 1] <= beams[i] - want, i - 1, i)
        half = (beams[-1] - beams[0]) / (2 * (len(beams) - 1))
    outside = (want < beams[0] - half - 1e-9) | (want > beams[-1] + half + 1e-9)
    return np.where(outside, -1, nearest).astype(np.int64)


def _i16(value: float) -> int:
    return max(-32768, min(32767, round(value)))
