"""A laser attached to a robot: scans paired with the robot pose at their stamp.

A laser (`robotexp.laser.Laser`) is a device beside the robot: its scans arrive on their own
clock, stamped with the host's `time.monotonic()` when complete. `LaserMountedRobot` wraps any
`Robot` and gives its states the laser's newest scan, re-expressed in the robot frame of the state
it returns: the robot's pose when the scan was complete is interpolated between the robot's states
around its stamp (`PoseHistory`: every state the robot sends, stamped as it arrived, when the robot
offers `add_state_listener` as the stream backends do; else the states read), the sensor sits at
`mount` on the robot, and every echo is moved
to where it lies as seen from the robot's present pose (`scan_in_robot_frame`). So a map built from
`state.pose` and `state.laser` puts each echo where the laser saw it, however old the scan. A laser
that measures its beams one after the other (a turning RPLidar) says when, relative to the scan's
stamp, through an optional `beam_offsets()` method; each echo is then placed from the pose at its
own beam's time.

Mount: `Pose(x, y, theta)` of the sensor in the robot frame [m, rad]; the CLI takes it in mm and
degrees (`--laser-pose X,Y,THETA`, `parse_laser_pose`).
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from collections import deque
from dataclasses import replace
from typing import Any
import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.laser import Laser, LaserEmulator, ScanSource, StampedScan
from robotexp.robot import Clock, LaserScan, Pose, Robot, RobotState, Twist, wrap_angle

__all__ = ["PoseHistory", "LaserMountedRobot", "scan_in_robot_frame", "parse_laser_pose", "parse_laser_spec",
           "check_laser_options", "connect_laser", "attach_laser", "robot_options", "connect_with_laser", "serve_laser",
           "emulate_devices"]


class PoseHistory:
    """The robot's poses at host times, for the pose at any time between them.

    Args:
        maxlen: how many (time, pose) samples to keep.
    """

    def __init__(self, maxlen: int = 2048) -> None:
        self._t: deque[float] = deque(maxlen=maxlen)
        self._p: deque[Pose] = deque(maxlen=maxlen)
        self._lock = threading.Lock()           # added to by a reader thread, read by the control loop
        self._floor = -math.inf                 # poses at or before this time are from before `clear`

    def add(self, t: float, pose: Pose) -> None:
        """Record `pose` at host time `t` [s]; a time not after the last one (or not after the last
        `clear`) replaces nothing and is dropped."""
        with self._lock:
            if t <= self._floor or self._t and t <= self._t[-1]:
                return
            self._t.append(t)
            self._p.append(pose)

    def clear(self) -> None:
        """Forget every pose (odometry jumped) and refuse any stamped before now."""
        with self._lock:
            self._floor = time.monotonic()
            self._t.clear()
            self._p.clear()

    def oldest(self) -> Pose | None:
        """The first pose kept (None when empty)."""
        with self._lock:
            return self._p[0] if self._p else None

    def at(self, t: float) -> Pose | None:
        """The pose at host time `t`: linear between the samples around it (the heading along the
        shorter arc), the newest pose after the last sample; None before the first or when empty."""
        with self._lock:
            if not self._t or t < self._t[0]:
                return None
            i = bisect.bisect_right(self._t, t)
            if i >= len(self._t):
                return self._p[-1]
            t0, t1 = self._t[i - 1], self._t[i]
            p0, p1 = self._p[i - 1], self._p[i]
        f = (t - t0) / (t1 - t0)
        return Pose(p0.x + f * (p1.x - p0.x), p0.y + f * (p1.y - p0.y),
                    wrap_angle(p0.theta + f * wrap_angle(p1.theta - p0.theta)))

    def samples(self) -> tuple[list[float], list[Pose]]:
        """A copy of the (times, poses) kept, oldest first."""
        with self._lock:
            return list(self._t), list(self._p)


def _poses_at(history: PoseHistory, ts: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], ...] | None:
    """(x, y, theta) arrays of the poses at host times `ts` (clamped to the history's span: before the
    first sample the first pose), interpolated as `PoseHistory.at`; None when the history is empty."""
    times, poses = history.samples()
    if not times:
        return None
    t = np.asarray(times, np.float64)
    x = np.fromiter((p.x for p in poses), np.float64, len(poses))
    y = np.fromiter((p.y for p in poses), np.float64, len(poses))
    th = np.unwrap(np.fromiter((p.theta for p in poses), np.float64, len(poses)))
    if t.size == 1:
        return np.full(ts.shape, x[0]), np.full(ts.shape, y[0]), np.full(ts.shape, th[0])
    return np.interp(ts, t, x), np.interp(ts, t, y), np.interp(ts, t, th)


def _compose(a: Pose, b: Pose) -> Pose:
    """`b` (in `a`'s frame) in the frame `a` is given in."""
    c, s = math.cos(a.theta), math.sin(a.theta)
    return Pose(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.theta + b.theta))


def scan_in_robot_frame(scan: LaserScan, sensor: Pose, robot: Pose,
                        beam_sensors: tuple[npt.NDArray[np.float64], ...] | None = None) -> LaserScan:
    """A scan taken in the sensor frame with the sensor at world pose `sensor`, as the robot at world
    pose `robot` sees it: `offset_x` is the sensor's position along the robot's heading, each echo
    lands exactly where it was (angle and range from that point), beams without echo (inf, NaN, or
    at `range_max` and beyond) keep their direction and range. The sensor's sideways offset from
    the robot's axis is not representable in a `LaserScan`: echoes stay exact, the rays towards them
    start up to that offset away (a few millimetres for a laser on the robot's axis).

    `beam_sensors` = (x, y, theta) arrays, one per beam: where the sensor was when it measured each
    beam (a turning laser measures its beams one after the other while the robot moves); the echoes
    are placed from those, the rays start from `sensor`.
    """
    c, s = math.cos(robot.theta), math.sin(robot.theta)

    def in_robot(x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        dx, dy = np.asarray(x, np.float64) - robot.x, np.asarray(y, np.float64) - robot.y
        return c * dx + s * dy, -s * dx + c * dy

    origin_x, _ = in_robot(sensor.x, sensor.y)                    # the rays' origin: (ox, 0)
    ox = float(origin_x)
    ranges = np.asarray(scan.ranges, np.float64)
    if beam_sensors is None:
        bx, by = in_robot(np.full(ranges.shape, sensor.x), np.full(ranges.shape, sensor.y))
        dth = np.full(ranges.shape, sensor.theta - robot.theta)
    else:
        bx, by = in_robot(beam_sensors[0], beam_sensors[1])
        dth = np.asarray(beam_sensors[2], np.float64) - robot.theta
    angles = np.asarray(scan.angles, np.float64) + dth           # beam directions in the robot frame
    hit = np.isfinite(ranges) & (ranges < scan.range_max)
    out_r = np.where(hit, 0.0, ranges)
    out_r = np.where(np.isfinite(ranges) & ~hit, math.inf, out_r)
    out_a = angles.copy()
    # an echo lies at (bx, by) + r (cos a, sin a) in the robot frame; seen from (ox, 0):
    ex = bx[hit] - ox + ranges[hit] * np.cos(angles[hit])
    ey = by[hit] + ranges[hit] * np.sin(angles[hit])
    out_a[hit] = np.arctan2(ey, ex)
    out_r[hit] = np.hypot(ex, ey)
    out_a = (out_a + math.pi) % (2 * math.pi) - math.pi
    return LaserScan(out_a, out_r, scan.range_max, offset_x=ox)


class LaserMountedRobot(Robot):
    """`robot` with `laser` mounted at `mount` (robot frame): `read()` returns the robot's state with
    the laser's newest scan, paired with the robot pose at the scan's stamp (see the module
    docstring). Commands, clock, limits and capabilities are the robot's; closing closes both
    (the robot first: it stops).

    Raises (from `read`):
        ConnectionLost: the laser's link went away or it stayed silent (the run then ends and stops
            the robot).
    """

    first_scan_timeout = 3.0    # [s] how long the first read waits for the laser's first scan

    def __init__(self, robot: Robot, laser: Laser, mount: Pose | None = None) -> None:
        self.robot = robot
        self.laser = laser
        self.mount = mount or Pose(0.0, 0.0, 0.0)
        self.name = robot.name                                    # type: ignore[misc]  # the robot's, per instance
        self.capabilities = robot.capabilities                    # type: ignore[misc]
        self.address = robot.address
        self.limits = robot.limits
        self.radius = robot.radius
        self.history = PoseHistory()
        self.paired = 0                                           # scans given with an interpolated pose
        self.last_pair: tuple[StampedScan, Pose] | None = None   # the newest scan given and its robot pose
        listen = getattr(robot, "add_state_listener", None)
        self.streamed = listen is not None                        # every state, stamped as it arrived
        if listen is not None:
            listen(lambda stamp, _robot_time, pose: self.history.add(stamp, pose))
        super().__init__()

    @property
    def model(self) -> str:
        return self.robot.model

    def describe(self) -> dict[str, str]:
        out = self.robot.describe()
        m = self.mount
        out["laser"] = self.laser.describe()
        out["laser mount"] = f"{m.x * 1000:.0f}, {m.y * 1000:.0f} mm, {math.degrees(m.theta):.1f} deg"
        return out

    def make_clock(self, period: float) -> Clock:
        return self.robot.make_clock(period)

    def move_to(self, pose: Pose) -> None:
        self.robot.move_to(pose)
        self.history.clear()                 # odometry jumped: older poses no longer pair with scans

    def set_max_speed(self, v_max: float) -> None:
        self.robot.set_max_speed(v_max)
        self.limits = self.robot.limits

    def _read(self) -> RobotState:
        state = self.robot.read()
        if not self.streamed:
            self.history.add(time.monotonic(), state.pose)
        # no state without a scan: an explorer given an empty first view would call the world explored
        stamped = self.laser.latest() or self.laser.wait_scan(-1, self.first_scan_timeout)
        at_scan = self.history.at(stamped.stamp)
        if at_scan is None:                  # older than every state read: the oldest pose is the nearest
            at_scan = self.history.oldest() or state.pose
        else:
            self.paired += 1
        self.last_pair = (stamped, at_scan)
        sensor = _compose(at_scan, self.mount)
        beam_sensors = None
        offsets = getattr(self.laser, "beam_offsets", None)
        if offsets is not None:
            poses = _poses_at(self.history, stamped.stamp + np.asarray(offsets(), np.float64))
            if poses is not None:
                m = self.mount
                x, y, th = poses
                beam_sensors = (x + np.cos(th) * m.x - np.sin(th) * m.y, y + np.sin(th) * m.x + np.cos(th) * m.y,
                                th + m.theta)
        return replace(state, laser=replace(scan_in_robot_frame(stamped.scan, sensor, state.pose, beam_sensors),
                                            stamp=stamped.stamp))

    def _command(self, twist: Twist) -> None:
        self.robot.command(twist)

    def _close(self) -> None:
        try:
            self.robot.close()
        finally:
            self.laser.close()


def parse_laser_pose(text: str) -> Pose:
    """"X,Y,THETA" [mm, mm, deg] of a laser on the robot as a `Pose` [m, rad].

    Raises:
        ConfigError: not three numbers.
    """
    parts = [p.strip() for p in text.split(",")]
    try:
        x, y, th = (float(p) for p in parts)
    except ValueError:
        raise ConfigError(f"laser pose {text!r}: give X,Y,THETA in mm, mm, deg (e.g. 100,0,0)") from None
    if not all(math.isfinite(v) for v in (x, y, th)):
        raise ConfigError(f"laser pose {text!r}: X,Y,THETA must be finite numbers")
    return Pose(x / 1000.0, y / 1000.0, math.radians(th))


def parse_laser_spec(text: str) -> tuple[str, str]:
    """"NAME:ADDRESS" (e.g. rplidar:/dev/ttyUSB0, hokuyo:192.168.0.10:10940) as (name, address).

    Raises:
        ConfigError: no name or no address.
    """
    name, sep, address = text.partition(":")
    if not sep or not name.strip() or not address.strip():
        raise ConfigError(f"laser {text!r}: give NAME:ADDRESS, e.g. rplidar:/dev/ttyUSB0")
    return name.strip(), address.strip()


def connect_laser(spec: str) -> Laser:
    """Connect the laser "NAME:ADDRESS" (NAME registered in `robotexp.lasers`).

    Raises:
        ConfigError: a malformed spec. PluginError: an unknown laser.
        RobotError: the laser cannot be reached or refuses the handshake.
    """
    from robotexp.laser import LASERS
    from robotexp.registry import load

    name, address = parse_laser_spec(spec)
    cls = load(LASERS, name, Laser)
    return cls(address)


def check_laser_options(spec: str | None, pose: str | None) -> None:
    """Check `--laser NAME:ADDRESS` and `--laser-pose X,Y,THETA` before anything connects.

    Raises:
        ConfigError: a malformed spec or pose, or a pose without a laser.
    """
    if spec is None and pose is not None:
        raise ConfigError("--laser-pose needs --laser NAME:ADDRESS")
    if spec is not None:
        parse_laser_spec(spec)
    if pose is not None:
        parse_laser_pose(pose)


def attach_laser(robot: Robot, spec: str | None, pose: str | None) -> Robot:
    """`robot` with the laser `spec` ("NAME:ADDRESS") mounted at `pose` ("X,Y,THETA" in mm, mm, deg;
    default 0,0,0), or `robot` itself when `spec` is None. The robot is closed (stopped) when the
    laser cannot be connected.

    Raises:
        ConfigError: a pose without a laser, or a malformed spec or pose (checked before connecting).
        PluginError, RobotError: as `connect_laser`.
    """
    try:
        check_laser_options(spec, pose)
    except ConfigError:
        robot.close()
        raise
    if spec is None:
        return robot
    try:
        mount = parse_laser_pose(pose or "0,0,0")
        laser = connect_laser(spec)
    except BaseException:
        robot.close()
        raise
    return LaserMountedRobot(robot, laser, mount)


def robot_options(backend: str, laser: bool) -> dict[str, Any]:
    """The keyword options that connect robot `backend` (`robotexp.robots`) without a laser of its own
    when a laser device is mounted on it (`laser`): the class's `mounted_laser_options` (P3-DX: no
    MobileSim simulated-laser packets), else none.

    Raises:
        PluginError: an unknown backend.
    """
    from robotexp.registry import ROBOTS, load

    if not laser:
        return {}
    return dict(getattr(load(ROBOTS, backend, Robot), "mounted_laser_options", {}))


def connect_with_laser(backend: str, address: str, spec: str | None, pose: str | None) -> Robot:
    """Connect robot `backend` at `address` (`robotexp.registry.connect_robot`) and mount the laser
    `spec` at `pose` on it (`attach_laser`); with a laser, the robot is connected without its own
    simulated laser (`robot_options`). Options are checked before anything connects.

    Raises:
        ConfigError, PluginError, RobotError: as `check_laser_options`, `connect_robot`, `attach_laser`.
    """
    from robotexp.registry import connect_robot

    check_laser_options(spec, pose)
    return attach_laser(connect_robot(backend, address, **robot_options(backend, spec is not None)), spec, pose)


def serve_laser(name: str, source: ScanSource, *, pty: bool = False, port: int | None = None,
                speedup: float = 1.0) -> LaserEmulator:
    """The emulator of laser `name` (`robotexp.laser_emulators`) measuring with `source`, started.

    Raises:
        PluginError: no emulator of that name. ConfigError: a bad speedup. OSError: the port is taken.
    """
    from robotexp.laser import LASER_EMULATORS
    from robotexp.registry import load

    cls = load(LASER_EMULATORS, name, object)
    emulator: LaserEmulator = cls(source, pty=pty, port=port, speedup=speedup)
    return emulator.start()


def emulate_devices(backend: str, world: str, *, pose: str | None = None, port: int | None = None,
                    pty: bool = False, speedup: float = 1.0, laser: str | None = None,
                    laser_pose: str | None = None, **options: Any) -> list[tuple[str, Any]]:
    """What `robotexp emulate` serves, started, as (label, emulator) pairs: "robot" (a robot backend's
    emulator, `robotexp.registry.make_emulator`) with, when `laser` names one, a "laser" emulator
    measuring from that robot's simulator at `laser_pose`; or, when `backend` is a laser, that laser
    alone on a still robot at `pose`. The laser serves on a pseudo-terminal when `pty`, else on a free
    TCP port (or `port` when it serves alone). Each pair's emulator has `close()`; the caller closes
    them all (in reverse order); on an error the ones already started are closed here.

    Raises:
        ConfigError, PluginError, WorldError: bad names, options, world or pose. OSError: a port taken.
    """
    from robotexp.laser import LASER_EMULATORS
    from robotexp.registry import EMULATORS, available, make_emulator
    from robotexp.sim import SimRobot, mounted_source, preset
    from robotexp.world.loader import load_world
    from robotexp.world.poses import resolve_pose

    if port is not None and not 0 <= port <= 65535:
        raise ConfigError(f"--port must be within 0..65535, got {port}")
    mount = parse_laser_pose(laser_pose) if laser_pose is not None else Pose(0.0, 0.0, 0.0)
    lasers = available(LASER_EMULATORS)
    started: list[tuple[str, Any]] = []
    try:
        if backend in lasers and backend not in available(EMULATORS):
            if laser is not None:
                raise ConfigError(f"{backend!r} is a laser: --laser adds a laser to a robot emulator")
            for key in ("udp", "odometry"):
                if options.get(key) is not None:
                    flag = "--odometry-error" if key == "odometry" else f"--{key}"
                    raise ConfigError(f"{flag} is not an option of the {backend!r} laser emulator")
            w = load_world(world)
            robot = preset("kobuki")
            start, _ = resolve_pose(w, pose, robot.radius)
            sim = SimRobot(w, robot=robot, pose=start, sonar=False)
            started.append(("simulator", sim))
            started.append(("laser", serve_laser(backend, mounted_source(sim, mount), pty=pty, port=port,
                                                 speedup=speedup)))
            return started
        if laser is not None and laser not in lasers:
            raise ConfigError(f"--laser {laser!r}: no such laser emulator; available: {', '.join(lasers) or 'none'}")
        if laser_pose is not None and laser is None:
            raise ConfigError("--laser-pose needs --laser NAME")
        emulator = make_emulator(backend, world, pose=pose, port=port, pty=pty, speedup=speedup, **options)
        started.append(("robot", emulator.start()))
        if laser is not None:
            emulated = getattr(emulator, "sim", None)
            if emulated is None:
                raise ConfigError(f"the {backend!r} emulator has no simulator a laser could measure from")
            source = mounted_source(emulated, mount, getattr(emulator, "lock", None))
            started.append(("laser", serve_laser(laser, source, pty=pty, speedup=speedup)))
        return started
    except BaseException:
        for _, device in reversed(started):
            device.close()
        raise
