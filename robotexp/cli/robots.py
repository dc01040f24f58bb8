"""`robotexp emulate` and `robotexp connect`: a robot's emulator, and a connected robot's state."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import click

from robotexp.cli.common import compile_watch, handle_errors
from robotexp.errors import ConfigError
from robotexp.view.live import end_view, start_view, view_options

__all__ = ["emulate", "connect"]

@click.command()
@click.argument("backend")
@click.option("--world", "-w", default="dense", show_default=True,
              help="Built-in world name, or the path of a MobileSim .map or ROS .yaml map.")
@click.option("--pose", default=None, help="Start pose: a name of the world's poses, or x,y,theta in mm, mm, deg.")
@click.option("--port", type=int, default=None, help="TCP port on 127.0.0.1 (default: the backend's, 8101 for p3dx).")
@click.option("--pty", is_flag=True, help="Serve on a pseudo-terminal (prints its device path) instead of TCP.")
@click.option("--speedup", type=float, default=1.0, show_default=True, help="Robot time per wall time.")
@click.option("--udp", default=None, help="mavlink: send to a ground station at HOST:PORT (e.g. 127.0.0.1:14550).")
@click.option("--laser", default=None, help="Serve a laser on the simulated robot too (rplidar, hokuyo, lms2xx).")
@click.option("--laser-pose", default=None, help="Where that laser sits on the robot: X,Y,THETA [mm, mm, deg].")
@click.option("--odometry-error", default="none", show_default=True,
              help="Odometry error of the emulated robot's encoders, as explore's --odometry-error: none, p3dx, "
                   "kobuki, or key=value,... (the robot reports drifting odometry; its laser sees the truth).")
@click.option("--team-poses", default=None, metavar="POSE;POSE;...",
              help="A team (BACKEND a list): each robot's start pose (names or x,y,theta in mm, mm, deg), "
                   "';'-separated (default: spread from --pose, as explore --team spreads them).")
@handle_errors
def emulate(backend: str, world: str, pose: str | None, port: int | None, pty: bool, speedup: float,  # noqa: PLR0913
            udp: str | None, laser: str | None, laser_pose: str | None, odometry_error: str,
            team_poses: str | None) -> None:
    """Serve the simulated robot of a world over BACKEND's protocol (p3dx: replaces MobileSim), or
    a laser (BACKEND rplidar, hokuyo, lms2xx) on a still robot of the world.

    BACKEND a list (p3dx,p3dx,kobuki+rplidar:pty) serves a team in one world, where the robots see and touch
    each other: robot i on TCP port --port + i - 1 (default 8101 + i - 1, as MobileSim; 0: free ports) or, with
    :pty (or --pty), on a pseudo-terminal, with its laser (+NAME) beside it; it prints the --team value of
    `robotexp explore` that drives them."""
    import time

    from robotexp.run.laser_mount import emulate_devices

    odometry = None if odometry_error.strip().lower() in ("", "none") else odometry_error
    team = "," in backend or ":" in backend or "+" in backend
    if team_poses is not None and not team:
        raise ConfigError("--team-poses places the robots of a team (BACKEND a list: p3dx,p3dx,kobuki)")
    if team:
        devices = _emulate_team(backend, world, pose, team_poses, port, pty, speedup, udp, laser, laser_pose,
                                odometry)
    else:
        devices = emulate_devices(backend, world, pose=pose, port=port, pty=pty, speedup=speedup, udp=udp,
                                  laser=laser, laser_pose=laser_pose, odometry=odometry)
    try:
        served = [(label, device) for label, device in devices if label != "simulator"]
        if team:
            for label, device in served:
                click.echo(f"{label}: {device.address}")
            click.echo(f"explore with: --world {world} --team {_team_value(backend, pty, devices)}")
            click.echo(f"world {world!r}, speedup {speedup:g}; Ctrl-C stops", err=True)
        elif [label for label, _ in served] == ["robot"]:
            click.echo(f"{backend} emulator of world {world!r} at {served[0][1].address} (speedup {speedup:g}); "
                       "Ctrl-C stops")
        else:
            for label, device in served:
                click.echo(f"{label}: {device.address}")
            click.echo(f"world {world!r}, speedup {speedup:g}; Ctrl-C stops", err=True)
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        click.echo("emulator stopped", err=True)
    finally:
        for _, device in reversed(devices):
            device.close()


def _emulate_team(backend: str, world: str, pose: str | None, poses: str | None, port: int | None,  # noqa: PLR0913
                  pty: bool, speedup: float, udp: str | None, laser: str | None, laser_pose: str | None,
                  odometry: str | None) -> list[tuple[str, Any]]:
    """The emulators of `robotexp emulate p3dx,p3dx,kobuki`, started (`robotexp.run.teamrobots.emulate_team`)."""
    from robotexp.run.teamrobots import emulate_team, parse_emulated

    if laser is not None or udp is not None:
        raise ConfigError("a team's lasers are named per robot (p3dx,kobuki+rplidar); --laser and --udp serve one "
                          "robot")
    members = parse_emulated(backend, pty)
    return emulate_team(members, world, pose=pose, poses=tuple(p.strip() for p in poses.split(";") if p.strip())
                        if poses else (), port=port, speedup=speedup, laser_pose=laser_pose, odometry=odometry)


def _team_value(backend: str, pty: bool, devices: list[tuple[str, Any]]) -> str:
    """The `robotexp explore --team` value that drives the emulated team of `devices`."""
    from robotexp.run.teamrobots import parse_emulated

    members = parse_emulated(backend, pty)
    where = dict((label, device.address) for label, device in devices)
    items = []
    for n, m in enumerate(members, start=1):
        laser = "" if m.laser is None else f"+{m.laser}:{where[f'laser {n}']}"
        items.append(f"{m.backend}:{where[f'robot {n}']}{laser}")
    return ",".join(items)


def _status_line(state: Any) -> str:
    """One line of what a robot reports: pose, speeds, battery, bumpers, nearest obstacle."""
    p, v = state.pose, state.velocity
    near = [s.nearest() for s in (state.laser,) if s is not None]
    if state.sonar is not None:
        finite = [r for r in state.sonar.ranges.tolist() if math.isfinite(r)]
        near += [min(finite)] if finite else []
    nearest = f"{min(near) * 1000:.0f} mm" if near and math.isfinite(min(near)) else "none"
    battery = "?" if state.battery is None else f"{state.battery:.1f} V"
    bumped = "stalled" if state.stalled else ("bumper" if any(state.bumpers) else "free")
    return (f"t {state.time:7.1f} s  pose {p.x * 1000:7.0f} {p.y * 1000:7.0f} mm {math.degrees(p.theta):6.1f} deg  "
            f"v {v.v * 1000:5.0f} mm/s w {math.degrees(v.w):6.1f} deg/s  battery {battery}  {bumped}  "
            f"nearest {nearest}")


@click.command()
@click.argument("backend")
@click.argument("address")
@click.option("--drive", default=None, help="Drive at V,W (mm/s, deg/s) during --for; the robot stops after.")
@click.option("--for", "duration", type=float, default=2.0, show_default=True, help="How long [s] to drive / watch.")
@click.option("--laser", default=None, help="A laser of the robot's own, NAME:ADDRESS (rplidar:/dev/ttyUSB0).")
@click.option("--laser-pose", default=None, help="Where --laser sits on the robot: X,Y,THETA [mm, mm, deg].")
@click.option("--record", type=click.Path(dir_okay=False, path_type=Path), default=None, metavar="FILE.mcap",
              help="Record the states read (odometry, laser) as a ROS 2 bag in MCAP (robotexp replay maps it).")
@view_options
@handle_errors
def connect(backend: str, address: str, drive: str | None, duration: float, laser: str | None,
            laser_pose: str | None, record: Path | None, view: bool, view_port: int, view_host: str,
            view_speed: str | None) -> None:
    """Connect to robot BACKEND at ADDRESS, print what it says about itself and a live status line
    (with --view: its pose, laser, path and a map built from its scans in the browser)."""
    from robotexp.robot import Twist
    from robotexp.run.laser_mount import check_laser_options

    check_laser_options(laser, laser_pose)
    twist = None
    if drive is not None:
        try:
            v_mm, w_deg = (float(x) for x in drive.split(","))
        except ValueError:
            raise ConfigError(f"--drive {drive!r}: expected V,W in mm/s and deg/s, e.g. 200,0") from None
        twist = Twist(v_mm / 1000, math.radians(w_deg))
    if not (duration >= 0 and math.isfinite(duration)):
        raise ConfigError(f"--for must be >= 0 s, got {duration:g}")
    tty = sys.stdout.isatty()
    recorder = None
    if record is not None:
        from robotexp.bag.recorder import BagRecorder

        recorder = BagRecorder(record)
    live = start_view(view, view_host, view_port, view_speed)
    try:
        if live is None:
            _connect_watch(backend, address, twist, duration, tty, live, laser, laser_pose, recorder)
        else:
            with compile_watch():   # the view's map is built by the map kernels
                _connect_watch(backend, address, twist, duration, tty, live, laser, laser_pose, recorder)
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        if recorder is not None:
            recorder.close()
    end_view(live, interrupted=False)


def _connect_watch(backend: str, address: str, twist: Any, duration: float, tty: bool, live: Any,
                   laser: str | None = None, laser_pose: str | None = None, recorder: Any = None) -> None:
    """`connect`'s watch of the robot for `duration` [s], driving at `twist` (None: not), shown in `live`,
    with `laser` (NAME:ADDRESS) attached at `laser_pose` when given, each state read written to
    `recorder` (a `robotexp.bag.recorder.BagRecorder`) when given."""
    import time

    from robotexp.robot import new_scan
    from robotexp.run.laser_mount import connect_with_laser
    from robotexp.view.watch import StateFeed

    with connect_with_laser(backend, address, laser, laser_pose) as robot:
        feed = None if live is None else StateFeed(live.hub, f"{backend} at {address}", robot.radius)
        info = robot.describe()
        click.echo("  ".join(f"{key}: {value}" for key, value in info.items()))
        lim = robot.limits
        click.echo(f"limits: {lim.v_max * 1000:.0f} mm/s, {math.degrees(lim.w_max):.0f} deg/s; "
                   f"capabilities: {', '.join(sorted(robot.capabilities)) or 'none'}")
        end, next_line = time.monotonic() + duration, 0.0
        t0: float | None = None
        written: float | None = None        # the stamp of the last scan written (each measurement once)
        try:
            while True:
                now = time.monotonic()
                if twist is not None:
                    robot.command(twist)
                due = now >= next_line or now >= end
                state = robot.read() if due or feed is not None or recorder is not None else None
                if feed is not None and state is not None:
                    feed.publish(state)
                if recorder is not None and state is not None:
                    t0 = state.time if t0 is None else t0
                    fresh = new_scan(state.laser, written)
                    recorder.write_state(state.time - t0, state, fresh)
                    if fresh:
                        assert state.laser is not None
                        written = state.laser.stamp
                if due:
                    line = _status_line(state)
                    click.echo(f"\r{line}" if tty else line, nl=not tty)
                    next_line = now + 0.5
                if now >= end or (feed is not None and feed.stop_requested):
                    break
                time.sleep(0.1)
        finally:
            robot.stop()
            if tty:
                click.echo("")
            if feed is not None:
                feed.finish("stopped from the live view" if feed.stop_requested else "watch over; robot stopped")
    click.echo("robot stopped and disconnected")
