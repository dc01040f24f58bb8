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

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from robotexp.errors import ConfigError
from robotexp.laser import (
    LASERS, LASER_EMULATORS, Laser, LaserEmulator, PoseHistory, ScanSource, StampedScan, _compose, _poses_at,
    scan_in_robot_frame)
from robotexp.robot import Clock, Pose, Robot, RobotState, Twist

__all__ = ["LaserMountedRobot", "parse_laser_pose", "parse_laser_spec", "check_laser_options", "connect_laser",
           "robot_options", "connect_with_laser", "emulate_devices"]


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


def _attach_laser(robot: Robot, spec: str | None, pose: str | None) -> Robot:
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
    `spec` at `pose` on it (`_attach_laser`); with a laser, the robot is connected without its own
    simulated laser (`robot_options`). Options are checked before anything connects.

    Raises:
        ConfigError, PluginError, RobotError: as `check_laser_options`, `connect_robot`, `_attach_laser`.
    """
    from robotexp.registry import connect_robot

    check_laser_options(spec, pose)
    return _attach_laser(connect_robot(backend, address, **robot_options(backend, spec is not None)), spec, pose)


def _serve_laser(name: str, source: ScanSource, *, pty: bool = False, port: int | None = None,
                speedup: float = 1.0) -> LaserEmulator:
    """The emulator of laser `name` (`robotexp.laser_emulators`) measuring with `source`, started.

    Raises:
        PluginError: no emulator of that name. ConfigError: a bad speedup. OSError: the port is taken.
    """
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
            started.append(("laser", _serve_laser(backend, mounted_source(sim, mount), pty=pty, port=port,
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
            started.append(("laser", _serve_laser(laser, source, pty=pty, speedup=speedup)))
        return started
    except BaseException:
        for _, device in reversed(started):
            device.close()
        raise
