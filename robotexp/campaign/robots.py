"""Campaign runs on a connected robot: a set's `address` (with `robot` naming the backend), `laser`
and `laser_pose` keys, the same as `robotexp explore --robot B --address A --laser NAME:ADDRESS
--laser-pose X,Y,THETA`.

    [[set]]
    world = "ufmg-static"           # ground truth for coverage, as `explore --world` with --address
    poses = ["path1"]
    methods = ["frontier"]
    robot = "kobuki"                # with `address`: the robot backend (robotexp.robots)
    address = "/dev/kobuki"
    laser = "rplidar:/dev/ttyUSB0"  # optional: a laser device of its own, NAME:ADDRESS
    laser_pose = "100,0,0"          # optional: where it sits, X,Y,THETA [mm, mm, deg] (or [100, 0, 0])

A run on a robot starts as `explore --robot ... --world W --pose P` does: the robot is told it stands
at the run's start pose (`Robot.move_to`: MobileSim teleports, a real robot or the Kobuki only
re-anchors its odometry), so someone must have put it there. The runs of a campaign with a robot are
made one after another in this process (one robot: one run at a time; `--jobs` does not apply, a
Dask cluster is refused), in the file's order. Each run connects the robot (and its laser), runs and
disconnects (the robot is stopped: between runs, on an error, on Ctrl-C); before every run but the
first, `place(...)` is called so that an operator can carry the robot to the next start (the CLI
waits for Enter on stdin; at the end of stdin it does not wait).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError, PluginError, WorldError
from robotexp.run.spec import RunSpec, plan_run
from robotexp.run.record import EndReason, RunRecord
from robotexp.robot import Pose, Robot

if TYPE_CHECKING:
    from robotexp.campaign.spec import Campaign

__all__ = ["DEVICE_KEYS", "Place", "RobotDevices", "check_starts", "one_at_a_time", "operator", "robot_devices",
           "run_on_robots"]

DEVICE_KEYS = frozenset({"address", "laser", "laser_pose"})


@dataclass(frozen=True)
class RobotDevices:
    """Where a set's runs are made: robot `backend` at `address`, with the laser `laser`
    ("NAME:ADDRESS") mounted at `laser_pose` ("X,Y,THETA" in mm, mm, deg) when given."""

    backend: str
    address: str
    laser: str | None = None
    laser_pose: str | None = None

    def label(self) -> str:
        """"kobuki at /dev/kobuki with rplidar:/dev/ttyUSB0 at 100,0,0" (for messages)."""
        text = f"{self.backend} at {self.address}"
        if self.laser is not None:
            text += f" with {self.laser}" + (f" at {self.laser_pose} mm, mm, deg" if self.laser_pose else "")
        return text

    def record_extra(self) -> dict[str, Any]:
        """The keys a run on these devices adds to its record (the robot's address is added by the run)."""
        if self.laser is None:
            return {}
        return {"laser": self.laser, "laser_pose": self.laser_pose or "0,0,0"}


def robot_devices(s: Mapping[str, Any], fail: Callable[..., Exception]) -> RobotDevices | None:  # noqa: C901
    """The devices of a (merged) campaign set `s`, or None for a set run on the embedded simulator.

    Args:
        s: the set's keys (with the [campaign] defaults).
        fail: fail(key, message[, kind]) makes the error (kind ConfigError unless given) for a key
            ("address", "laser", ...) of the set (`campaign._fail`).

    Raises:
        ConfigError: a malformed address, laser or pose; a laser without an address; a backend that is
            not reached at an address. PluginError: an unknown robot backend or laser.
    """
    from robotexp.laser import LASERS
    from robotexp.run.laser_mount import parse_laser_pose, parse_laser_spec
    from robotexp.registry import ROBOTS, available

    address, laser, pose = s.get("address"), s.get("laser"), s.get("laser_pose")
    if address is None:
        for key, value in (("laser", laser), ("laser_pose", pose)):
            if value is not None:
                raise fail(key, "a laser is attached to a robot at an address: give `address` (and `robot`, "
                                "the backend) too; the embedded simulator has its own laser")
        return None
    if not isinstance(address, str) or not address.strip():
        raise fail("address", f"expected the robot's address (a serial device, host:port), got {address!r}")
    backend = s.get("robot", "p3dx")
    robots = available(ROBOTS)
    if backend not in robots:
        raise fail("robot", f"no robot backend {backend!r} to connect at {address!r}; available: "
                            f"{', '.join(sorted(robots)) or 'none'}", PluginError)
    from robotexp.registry import load

    if not getattr(load(ROBOTS, backend, Robot), "by_address", True):
        raise fail("robot", f"robot {backend!r} is not reached at an address; drop `address` to run it here")
    if laser is not None:
        if not isinstance(laser, str):
            raise fail("laser", f"expected NAME:ADDRESS (e.g. rplidar:/dev/ttyUSB0), got {laser!r}")
        try:
            name, _ = parse_laser_spec(laser)
        except ConfigError as exc:
            raise fail("laser", str(exc)) from None
        lasers = available(LASERS)
        if name not in lasers:
            raise fail("laser", f"unknown laser {name!r}; available: {', '.join(sorted(lasers)) or 'none'}",
                       PluginError)
    if pose is not None:
        if laser is None:
            raise fail("laser_pose", "a laser pose needs `laser` (NAME:ADDRESS)")
        if isinstance(pose, list) and len(pose) == 3 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in pose):
            pose = ",".join(f"{v:g}" for v in pose)
        if not isinstance(pose, str):
            raise fail("laser_pose", f"expected \"X,Y,THETA\" or [X, Y, THETA] in mm, mm, deg, got {pose!r}")
        try:
            parse_laser_pose(pose)
        except ConfigError as exc:
            raise fail("laser_pose", str(exc)) from None
    return RobotDevices(backend, address.strip(), laser, pose)


def check_starts(campaign: Campaign) -> None:
    """Plan every run on a robot in its world for the backend's radius (start poses in free space, in
    the map), before any robot moves.

    Raises:
        WorldError, ConfigError, PluginError: as `robotexp.run.spec.plan_run`, with the file named.
    """
    from robotexp.registry import ROBOTS, load

    for spec in campaign.runs:
        devices = campaign.devices_of(spec)
        if devices is None:
            continue
        radius = getattr(load(ROBOTS, devices.backend, Robot), "radius", None)
        if not isinstance(radius, float) or not math.isfinite(radius):
            continue            # told by the robot once connected
        try:
            plan_run(spec, spec.world, radius)
        except (WorldError, ConfigError, PluginError) as exc:
            raise type(exc)(f"{campaign.source}: run {spec.method} from {spec.pose or 'default'} on "
                            f"{devices.label()}: {exc}") from None


Place = Callable[[int, int, RunSpec, Pose, RobotDevices], None]


def run_on_robots(campaign: Campaign, todo: list[RunSpec], out: Path, *,
                  progress: Callable[[int, int, RunRecord | None], None] | None = None,
                  place: Place | None = None,
                  extra: Callable[[RunSpec], dict[str, Any]] = lambda spec: {}) -> list[RunRecord]:
    """Make the runs `todo` one after another, each on its robot (see the module docstring); a run
    without devices runs on the embedded simulator here too. Each record is written to
    `out/results.jsonl` as the run ends.

    Args:
        place: called before every run on a robot but the first as place(k, total, spec, start,
            devices) (k from 1): the robot is disconnected and stopped; return when it stands at `start`.
        extra: the keys each record gets (the campaign's world/pose/sweep keys).

    Returns:
        The records of the runs made.

    Raises:
        KeyboardInterrupt: Ctrl-C (the running run is ended and written, its robot stopped).
        RobotError: a robot or laser cannot be connected (the runs made so far are written).
        PluginError: an explorer failed (its record is written first).
    """
    from robotexp.experiment import run_experiment, run_on_robot
    from robotexp.run.laser_mount import connect_with_laser

    records: list[RunRecord] = []
    total = len(todo)
    on_robot = 0
    for k, spec in enumerate(todo, start=1):
        observers = []
        if campaign.record:
            from robotexp.bag.recorder import BagRecorder

            (out / "bags").mkdir(parents=True, exist_ok=True)
            observers.append(BagRecorder(folder=out / "bags", world=spec.world))
        devices = campaign.devices_of(spec)
        if devices is None:
            result = run_experiment(spec, out, observers=observers, record_extra=extra(spec))
        else:
            if on_robot and place is not None:
                place(k, total, spec, _start(spec, devices), devices)
            on_robot += 1
            with connect_with_laser(devices.backend, devices.address, devices.laser, devices.laser_pose) as bot:
                plan = plan_run(spec, spec.world, bot.radius)
                result = run_on_robot(spec, bot, out, plan.world, observers=observers, plan=plan,
                                      record_extra={**devices.record_extra(), **extra(spec)})
        records.append(result.record)
        if progress:
            progress(len(records), total, result.record)
        if result.record.end is EndReason.INTERRUPTED:
            raise KeyboardInterrupt
    return records


def _start(spec: RunSpec, devices: RobotDevices) -> Pose:
    """The start pose of a run on `devices` (resolved as the run will resolve it)."""
    from robotexp.registry import ROBOTS, load
    from robotexp.world.loader import load_world
    from robotexp.world.poses import resolve_pose

    radius = getattr(load(ROBOTS, devices.backend, Robot), "radius", 0.2)
    return resolve_pose(load_world(spec.world), spec.pose, float(radius) if isinstance(radius, float) else 0.2)[0]


def one_at_a_time(campaign: Campaign, jobs: int | None) -> str | None:
    """The notice for a campaign with runs on a robot ("... one run at a time"), None for one without."""
    if not campaign.devices:
        return None
    robots = sorted({d.label() for d in campaign.devices.values()})
    ignored = f" (--jobs {jobs} does not apply)" if jobs not in (None, 1) else ""
    return f"campaign {campaign.name}: runs on {'; '.join(robots)}: one run at a time, in the file's order{ignored}"


def operator(read_line: Callable[[], str], say: Callable[[str], None]) -> Place:
    """The `place` hook of a campaign run from a terminal: say where to put the robot for the next
    run and wait for a line (Enter) from `read_line`; at its end ("" : stdin closed or /dev/null)
    say that the run starts without waiting, and stop asking."""
    ended = False

    def place(k: int, total: int, spec: RunSpec, start: Pose, devices: RobotDevices) -> None:
        nonlocal ended
        where = (f"{spec.pose or 'the default start'} (x {start.x * 1000:.0f} mm, y {start.y * 1000:.0f} mm, "
                 f"heading {math.degrees(start.theta):.0f} deg)")
        if ended:
            say(f"run {k}/{total}: {devices.backend} is told it stands at {where}")
            return
        say(f"run {k}/{total} ({spec.method}): the {devices.backend} is stopped; put it at {where} and press Enter "
            "(Ctrl-C ends the campaign)")
        if not read_line():
            ended = True
            say(f"run {k}/{total}: no operator (stdin ended): the {devices.backend} is told it stands at {where}")

    return place
