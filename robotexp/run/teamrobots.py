"""A team of robots over their drivers: the robots' addresses (`robotexp explore --team
p3dx:HOST:PORT,kobuki:/dev/ttyUSB0+rplidar:/dev/ttyUSB1`), connecting them, where each starts
(`team_starts`), and the emulators of a team sharing one simulated world (`robotexp emulate
p3dx,p3dx,kobuki`).

Start poses: the robots of a team map into one frame, so each must be told where it stands. Both sides
derive the same starts from the same input, the world, `--pose` (or `--team-poses`) and the robots'
footprints: `emulate_team` puts each emulated robot there, and the team run tells each connected robot it
stands there (`Robot.move_to`: a P3-DX in MobileSim or its emulator is moved, a Kobuki's odometry is
anchored), as a single robot's run does with `--pose`.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError, PluginError, RobotError, WorldError
from robotexp.robot import Capability, Pose, Robot

if TYPE_CHECKING:
    from robotexp.world.model import World

__all__ = ["TeamMember", "parse_members", "is_address_team", "check_members", "connect_team", "team_starts",
           "EmulatedMember", "parse_emulated", "emulate_team", "DEFAULT_TEAM_PORT"]

DEFAULT_TEAM_PORT = 8101        # the first robot's TCP port of an emulated team (MobileSim's), the others' next
_HOST_PORT = re.compile(r"^(?P<host>[^:/]*):(?P<port>\d+)$")


@dataclass(frozen=True)
class TeamMember:
    """One robot of a team over its driver: `backend` (`robotexp.robots`) at `address`, with a laser of its
    own `laser` ("NAME:ADDRESS") or None."""

    backend: str
    address: str
    laser: str | None = None

    @property
    def text(self) -> str:
        """As `--team` writes it."""
        return f"{self.backend}:{self.address}" + ("" if self.laser is None else f"+{self.laser}")


def is_address_team(text: str) -> bool:
    """`--team` names robots by address (BACKEND:ADDRESS,...) rather than presets or a number."""
    return ":" in text


def parse_members(text: str) -> list[TeamMember]:
    """`--team BACKEND:ADDRESS[+LASER:ADDRESS],...` as members (the syntax only; `check_members` checks more).

    Raises:
        ConfigError: an item without a backend or an address, or a list mixing presets and addresses.
    """
    members = []
    for n, item in enumerate((t.strip() for t in text.split(",")), start=1):
        robot, plus, laser = item.partition("+")
        backend, colon, address = robot.partition(":")
        lname, lcolon, laddress = laser.partition(":")
        if not colon or not backend.strip() or not address.strip():
            raise ConfigError(f"--team: robot {n} {item!r}: give BACKEND:ADDRESS for every robot (p3dx:127.0.0.1:8101, "
                              "kobuki:/dev/ttyUSB0), or only presets (p3dx,kobuki)")
        if plus and (not lcolon or not lname.strip() or not laddress.strip()):
            raise ConfigError(f"--team: robot {n} {item!r}: its laser is +NAME:ADDRESS (+rplidar:/dev/ttyUSB1)")
        members.append(TeamMember(backend.strip(), address.strip(),
                                  f"{lname.strip()}:{laddress.strip()}" if plus else None))
    return members


def _check_address(where: str, address: str) -> None:
    """A device path must exist, a HOST:PORT must have a port in 1..65535."""
    if address.startswith("/") and not os.path.exists(address):
        raise ConfigError(f"{where}: no device {address!r}; check the address (is the robot or its emulator on?)")
    m = _HOST_PORT.match(address.removeprefix("socket://"))
    if m and not 1 <= int(m["port"]) <= 65535:
        raise ConfigError(f"{where}: address {address!r}: TCP port must be 1..65535")


def check_members(members: Sequence[TeamMember]) -> None:
    """Check the members before anything connects: known backends reached at an address, known lasers,
    devices that exist, ports in range, no address twice.

    Raises:
        ConfigError: the first bad member, in one line naming it.
    """
    from robotexp.laser import LASERS
    from robotexp.registry import ROBOTS, available, load

    backends, lasers = available(ROBOTS), available(LASERS)
    seen: dict[str, int] = {}
    for n, m in enumerate(members, start=1):
        where = f"--team: robot {n} ({m.text})"
        if m.backend not in backends:
            raise ConfigError(f"{where}: unknown robot backend {m.backend!r}; available: {', '.join(sorted(backends))}")
        try:
            cls = load(ROBOTS, m.backend, Robot)
        except PluginError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        if not getattr(cls, "by_address", True):
            raise ConfigError(f"{where}: {m.backend!r} runs in this process and has no address; give presets "
                              "(--team p3dx,kobuki) for simulated robots")
        if Capability.MOVE_TO not in getattr(cls, "capabilities", frozenset()):
            raise ConfigError(f"{where}: a {m.backend!r} robot cannot be told where it stands, which a team needs "
                              "to share one map")
        _check_address(where, m.address)
        addresses = [m.address]
        if m.laser is not None:
            name, _, address = m.laser.partition(":")
            if name not in lasers:
                raise ConfigError(f"{where}: unknown laser {name!r}; available: {', '.join(sorted(lasers))}")
            _check_address(where, address)
            addresses.append(address)
        for a in addresses:
            if a in seen:
                raise ConfigError(f"{where}: address {a!r} is robot {seen[a]}'s too; give each robot its own")
            seen[a] = n


def connect_team(members: Sequence[TeamMember], laser_pose: str | None = None) -> list[Robot]:
    """Connect every member in order (`robotexp.run.laser_mount.connect_with_laser`); when one cannot be
    reached, the ones connected are closed (stopped) first.

    Raises:
        ConfigError: a member that cannot be reached or refuses the handshake (one line naming it).
    """
    from robotexp.run.laser_mount import connect_with_laser, parse_laser_spec

    robots: list[Robot] = []
    try:
        for n, m in enumerate(members, start=1):
            name, address = parse_laser_spec(m.laser) if m.laser is not None else (None, None)
            try:
                robots.append(connect_with_laser(m.backend, m.address, None if name is None else f"{name}:{address}",
                                                 laser_pose if name is not None else None))
            except (RobotError, OSError) as exc:
                raise ConfigError(f"--team: robot {n} ({m.text}) cannot be reached: {exc}") from None
    except BaseException:
        for robot in reversed(robots):
            robot.close()
        raise
    return robots


def listed_starts(world: World, poses: Sequence[str], radii: Sequence[float]) -> list[Pose]:
    """The poses `poses` (names or x,y,theta) in `world` of robots whose bodies turn in discs of `radii` [m],
    one each.

    Raises:
        WorldError: a pose that is not free, or two that overlap. ConfigError: a malformed pose.
    """
    from robotexp.world.poses import resolve_pose

    starts = [resolve_pose(world, p, r)[0] for p, r in zip(poses, radii, strict=True)]
    for i in range(len(starts)):
        for j in range(i):
            gap = math.hypot(starts[i].x - starts[j].x, starts[i].y - starts[j].y)
            if gap < radii[i] + radii[j]:
                raise WorldError(f"--team-poses: robots {j + 1} and {i + 1} overlap ({gap * 1000:.0f} mm "
                                 "apart); give poses farther apart")
    return starts


def team_starts(world: World, pose: str | None, radii: Sequence[float], poses: Sequence[str] = ()) -> list[Pose]:
    """Where the robots of `radii` [m] start in `world`: `poses` (names or x,y,theta in mm, mm, deg), else
    spread from `pose` (`robotexp.sim.team.spread_starts` on the reachable cells of a 100 mm grid, the
    same on every side that asks).

    Raises:
        WorldError: poses that overlap or are not free, no room for the team. ConfigError: a malformed pose.
    """
    from robotexp.run.spec import DEFAULT_CELL, RunSpec, plan_run
    from robotexp.sim import SimRobot, preset, spread_starts

    if poses:
        if len(poses) != len(radii):
            raise ConfigError(f"--team-poses: {len(poses)} poses for {len(radii)} robots; give one each")
        return listed_starts(world, poses, radii)
    rmax = max(radii)
    plan = plan_run(RunSpec(world=world.name, method="frontier", pose=pose, cell=DEFAULT_CELL), world, rmax)
    free = SimRobot(world, robot=preset("kobuki"), pose=plan.start, sonar=False)
    try:
        return spread_starts(plan.truth, plan.start, radii, free=free)
    finally:
        free.close()


@dataclass(frozen=True)
class EmulatedMember:
    """One robot of an emulated team: emulator `backend` (`robotexp.emulators`), with a laser emulator
    `laser` or None, served on a pseudo-terminal (`pty`) or TCP."""

    backend: str
    laser: str | None = None
    pty: bool = False


def parse_emulated(text: str, pty: bool = False) -> list[EmulatedMember]:
    """`robotexp emulate NAME[+LASER][:pty|:tcp],...` (the transport defaults to `pty`).

    Raises:
        ConfigError: an empty item or an unknown transport.
    """
    members = []
    for n, item in enumerate((t.strip() for t in text.split(",")), start=1):
        body, colon, transport = item.partition(":")
        backend, plus, laser = body.partition("+")
        if not backend.strip() or (plus and not laser.strip()):
            raise ConfigError(f"robot {n} {item!r}: give NAME[+LASER][:pty|:tcp] (p3dx, kobuki+rplidar:pty)")
        if colon and transport.strip() not in ("pty", "tcp"):
            raise ConfigError(f"robot {n} {item!r}: transport {transport!r}: use pty or tcp")
        members.append(EmulatedMember(backend.strip(), laser.strip() or None,
                                      transport.strip() == "pty" if colon else pty))
    return members


def emulate_team(members: Sequence[EmulatedMember], world: str, *, pose: str | None = None,  # noqa: PLR0913
                 poses: Sequence[str] = (), port: int | None = None, speedup: float = 1.0,
                 laser_pose: str | None = None, **options: Any) -> list[tuple[str, Any]]:
    """The emulators of a team in one simulated world, started: robot i at its start (`team_starts`), on
    TCP port `port` + i (default DEFAULT_TEAM_PORT + i; 0: any free port) or a pseudo-terminal, with its
    laser emulator when it has one; the robots see and touch each other (`robotexp.sim.SharedWorld`).
    Gives (label, emulator) pairs as `robotexp.run.laser_mount.emulate_devices` does ("robot N",
    "laser N"); on an error the ones started are closed here.

    Raises:
        ConfigError, PluginError, WorldError: bad names, options, world or poses. OSError: a port taken.
    """
    from robotexp.laser import LASER_EMULATORS
    from robotexp.registry import EMULATORS, available, load, make_emulator
    from robotexp.run.laser_mount import _serve_laser, parse_laser_pose
    from robotexp.sim import SharedWorld, mounted_source
    from robotexp.sim.team import MAX_TEAM
    from robotexp.world.loader import load_world

    if not 1 <= len(members) <= MAX_TEAM:
        raise ConfigError(f"a team has 1..{MAX_TEAM} robots, got {len(members)}")
    if port is not None and not 0 <= port <= 65535 - len(members):
        raise ConfigError(f"--port must be within 0..{65535 - len(members)} for {len(members)} robots, got {port}")
    robots, lasers = available(EMULATORS), available(LASER_EMULATORS)
    for n, m in enumerate(members, start=1):
        if m.backend not in robots:
            raise ConfigError(f"robot {n}: no emulator {m.backend!r}; available: {', '.join(sorted(robots))}")
        if m.laser is not None and m.laser not in lasers:
            raise ConfigError(f"robot {n}: no laser emulator {m.laser!r}; available: {', '.join(sorted(lasers))}")
    mount = parse_laser_pose(laser_pose) if laser_pose is not None else Pose(0.0, 0.0, 0.0)
    w = load_world(world)
    radii = [float(getattr(load(EMULATORS, m.backend, object), "radius", 0.0)) for m in members]
    starts = team_starts(w, pose, radii, poses)
    shared = SharedWorld()
    base = DEFAULT_TEAM_PORT if port is None else port
    started: list[tuple[str, Any]] = []
    try:
        for n, (m, start) in enumerate(zip(members, starts, strict=True), start=1):
            emulator = make_emulator(m.backend, w, pose=start, port=None if m.pty else (base + n - 1 if base else 0),
                                     pty=m.pty, speedup=speedup, **options)
            sim = getattr(emulator, "sim", None)
            if sim is None:
                emulator.close()
                raise ConfigError(f"robot {n}: the {m.backend!r} emulator has no simulator to share a world with")
            shared.join(sim)
            started.append((f"robot {n}", emulator.start()))
            if m.laser is not None:
                source = mounted_source(sim, mount, getattr(emulator, "lock", None))
                started.append((f"laser {n}", _serve_laser(m.laser, source, pty=m.pty, speedup=speedup)))
    except BaseException:
        for _, device in reversed(started):
            device.close()
        raise
    return started
