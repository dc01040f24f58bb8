"""The abstract `Robot` every backend implements, and the data it exchanges. SI units throughout.

A backend provides `_read`, `_command` and `_close`; the public methods here check the robot is
open, clamp commands to the backend's `Limits` and guarantee that `close()` stops the robot first.
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Protocol, Self

import numpy as np
import numpy.typing as npt

from robotexp.clock import Clock, WallClock
from robotexp.errors import ConfigError, RobotError

if TYPE_CHECKING:
    from robotexp.world.model import World

__all__ = [
    "Pose", "Twist", "Limits", "Footprint", "LaserScan", "SonarScan", "RobotState", "Robot", "Capability",
    "RobotEmulator",
    "wrap_angle", "new_scan", "sensor_origin",
]


def wrap_angle(angle: float) -> float:
    """Return `angle` [rad] wrapped to [-pi, pi)."""
    wrapped = (angle + math.pi) % (2.0 * math.pi) - math.pi
    # the modulo of a tiny negative number (angle just below -pi) rounds up to 2 pi: that is -pi
    return wrapped if wrapped < math.pi else -math.pi


@dataclass(frozen=True, slots=True)
class Pose:
    """A planar pose: position [m] and heading [rad], counter-clockwise from +x."""

    x: float
    y: float
    theta: float = 0.0

    def distance_to(self, other: Pose) -> float:
        """Euclidean distance [m] between the two positions."""
        return math.hypot(other.x - self.x, other.y - self.y)

    def as_list(self) -> list[float]:
        """[x_m, y_m, theta_rad] as plain floats (for JSON)."""
        return [float(self.x), float(self.y), float(self.theta)]


def sensor_origin(pose: Pose, offset_x: float) -> tuple[float, float]:
    """(x, y) [m] of a sensor `offset_x` [m] ahead of the robot centre along the heading, the robot at `pose`."""
    return pose.x + offset_x * math.cos(pose.theta), pose.y + offset_x * math.sin(pose.theta)


def compose_pose(a: Pose, b: Pose) -> Pose:
    """a (+) b: pose `b`, given in the frame of `a`, expressed in `a`'s parent frame."""
    ca, sa = math.cos(a.theta), math.sin(a.theta)
    return Pose(a.x + ca * b.x - sa * b.y, a.y + sa * b.x + ca * b.y, wrap_angle(a.theta + b.theta))


def relative_pose(a: Pose, b: Pose) -> Pose:
    """(-a) (+) b: pose `b` expressed in the frame of `a`, both in the same parent frame
    (so `compose_pose(a, relative_pose(a, b)) == b`)."""
    ca, sa = math.cos(a.theta), math.sin(a.theta)
    dx, dy = b.x - a.x, b.y - a.y
    return Pose(ca * dx + sa * dy, -sa * dx + ca * dy, wrap_angle(b.theta - a.theta))


@dataclass(frozen=True, slots=True)
class Twist:
    """A velocity command: forward speed `v` [m/s] and turn rate `w` [rad/s]."""

    v: float
    w: float

    ZERO: ClassVar[Twist]


Twist.ZERO = Twist(0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Limits:
    """Velocity and acceleration limits of a base."""

    v_max: float            # [m/s]
    w_max: float            # [rad/s]
    a_max: float = 0.5      # [m/s^2]
    alpha_max: float = 2.0  # [rad/s^2]

    def clamp(self, twist: Twist) -> Twist:
        """Return `twist` with each component clamped to +-its maximum; NaN becomes 0."""
        v = 0.0 if math.isnan(twist.v) else max(-self.v_max, min(self.v_max, twist.v))
        w = 0.0 if math.isnan(twist.w) else max(-self.w_max, min(self.w_max, twist.w))
        return Twist(v, w)


@dataclass(frozen=True, slots=True)
class Footprint:
    """The robot's outline on the floor in its own frame (x forward, y left), centred on the point it
    turns about: a disc (`round`, diameter `length` == `width`) or a `length` x `width` rectangle [m].

    A passage is open to the robot when it is wider than `width` (the robot crosses it straight, so a
    rectangle needs the room to turn before and after); turning in place sweeps a disc of `swing` [m].
    """

    length: float           # [m] along the heading
    width: float            # [m] across it
    round: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.length) and math.isfinite(self.width) and self.length > 0 and self.width > 0):
            raise ConfigError(f"footprint: length and width must be finite and > 0 m, got {self.length} x {self.width}")
        if self.round and self.length != self.width:
            raise ConfigError(f"footprint: a disc has one diameter, got {self.length} x {self.width}")

    @classmethod
    def disc(cls, radius: float) -> Footprint:
        """A round robot of `radius` [m]."""
        return cls(2.0 * radius, 2.0 * radius, True)

    @classmethod
    def rectangle(cls, length: float, width: float) -> Footprint:
        """A rectangular robot `length` [m] along its heading, `width` [m] across, turning about its centre."""
        return cls(float(length), float(width), False)

    @property
    def half_width(self) -> float:
        """[m] half the width: the radius of the widest disc inside (a passage must be twice as wide)."""
        return self.width / 2.0

    @property
    def swing(self) -> float:
        """[m] the radius of the disc the robot sweeps turning in place (a disc's own radius)."""
        return self.width / 2.0 if self.round else math.hypot(self.length / 2.0, self.width / 2.0)

    def distance(self, x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """[m] from the outline to the robot-frame points (`x`, `y`) (same shapes), 0 inside."""
        if self.round:
            return np.maximum(np.hypot(x, y) - self.width / 2.0, 0.0)
        return np.hypot(np.maximum(np.abs(x) - self.length / 2.0, 0.0), np.maximum(np.abs(y) - self.width / 2.0, 0.0))


@dataclass(frozen=True)
class LaserScan:
    """One planar laser scan in the robot frame.

    `angles` and `ranges` are float64 arrays of shape (n,): beam angle [rad] relative to the
    robot heading and measured range [m]; a beam that hit nothing reads `inf`. `stamp` tells one
    measurement from another: a backend that hands the same scan out in several states (its loop
    runs faster than the laser) gives them one stamp (a time or a count of its own), and the run loop
    maps each stamp once (`new_scan`); None (a new scan in every state, as on the simulator) is always
    mapped.
    """

    angles: npt.NDArray[np.float64]
    ranges: npt.NDArray[np.float64]
    range_max: float        # [m]
    offset_x: float = 0.0   # [m] sensor position ahead of the robot centre
    stamp: float | None = None  # which measurement (equal stamps: the same one); None: a new one

    def origin(self, pose: Pose) -> tuple[float, float]:
        """(x, y) [m] of the sensor when the robot stands at `pose` (`offset_x` ahead of its centre)."""
        return sensor_origin(pose, self.offset_x)

    def nearest(self) -> float:
        """The smallest finite range [m], or `inf` when no beam hit."""
        finite = self.ranges[np.isfinite(self.ranges)]
        return float(finite.min()) if finite.size else math.inf


def new_scan(scan: LaserScan | None, last: float | None) -> bool:
    """Whether `scan` is a measurement not used yet, `last` being the stamp of the last one used: a
    scan without a stamp always is; no scan is not."""
    return scan is not None and (scan.stamp is None or scan.stamp != last)


@dataclass(frozen=True)
class SonarScan:
    """Ranges [m] of a sonar ring; `angles` [rad] are the transducer headings in the robot frame.

    Each range is measured from its transducer, at `positions` (k, 2) [m] in the robot frame (None:
    not known; users then take the robot centre).
    """

    angles: npt.NDArray[np.float64]
    ranges: npt.NDArray[np.float64]
    range_max: float
    positions: npt.NDArray[np.float64] | None = None


@dataclass(frozen=True)
class RobotState:
    """Everything a robot reports at one instant.

    `pose` is what the robot believes (odometry); `true_pose` is the ground truth where a
    simulator knows it, else None. `stalled` is true while a wheel is blocked or a bumper pressed.
    """

    time: float                              # [s] robot clock
    pose: Pose
    velocity: Twist
    laser: LaserScan | None = None
    sonar: SonarScan | None = None
    stalled: bool = False
    bumpers: tuple[bool, ...] = ()
    battery: float | None = None             # [V]
    true_pose: Pose | None = None
    distance: float = 0.0                    # [m] travelled since connect (odometry)
    extra: dict[str, float] = field(default_factory=dict)


class Capability(enum.StrEnum):
    """What a robot backend can do beyond `read`/`command`, declared in `Robot.capabilities`.

    Members are strings ("move_to" == Capability.MOVE_TO), so a set of them answers `"move_to" in`.
    """

    MOVE_TO = "move_to"             # `move_to(pose)` teleports (simulators) or re-anchors odometry
    SONAR = "sonar"                 # states carry a SonarScan
    LASER = "laser"                 # states carry a LaserScan (of the robot's own laser)
    GROUND_TRUTH = "ground_truth"   # states carry `true_pose`
    BATTERY = "battery"             # states carry `battery`
    BUMPERS = "bumpers"             # states carry `bumpers`
    CLIFFS = "cliffs"               # the base reports cliff sensors (in `extra`)
    PACED_CLOCK = "paced_clock"     # the robot's own data paces the control loop (`make_clock`)


class Robot(ABC):
    """A mobile base driven by a Twist and sensed as a RobotState. SI units throughout.

    Use it as a context manager: the robot is stopped and its link released on exit, on an
    exception and on Ctrl-C.

    A backend declares what it can do in `capabilities` (`Capability` members; a string that is not
    one is refused when the class is defined), says where it is in `address` (None: in this process)
    and what it is in `describe()`; `model` names it in run records.
    """

    name: ClassVar[str] = "robot"
    capabilities: ClassVar[frozenset[Capability]] = frozenset()
    address: str | None = None                             # where the robot is reached (None: in-process)
    by_address: ClassVar[bool] = True                      # constructed as cls(address, **options) to connect
    limits: Limits
    radius: float = 0.25                                   # [m] half the footprint's width (planners' clearance)

    @property
    def footprint(self) -> Footprint:
        """The robot's outline (a backend with a non-round robot says its own; the default is a disc of
        `radius`)."""
        return Footprint.disc(self.radius)
    _closed: bool = True                                   # close() skips half-built robots

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        try:
            cls.capabilities = frozenset(Capability(c) for c in cls.capabilities)
        except ValueError as exc:
            raise TypeError(f"{cls.__module__}.{cls.__qualname__}.capabilities: {exc}; use members of "
                            f"robotexp.robot.Capability ({', '.join(c.value for c in Capability)})") from None

    def __init__(self) -> None:
        self._closed = False            # backends call this last, once their link is up

    @property
    def model(self) -> str:
        """What robot this is, as run records name it (`robot`): the backend name unless the backend
        knows better (a simulator: the simulated model)."""
        return self.name

    def describe(self) -> dict[str, str]:
        """What the robot says about itself, as key/value text (`robotexp connect` prints it)."""
        out = {"robot": self.name}
        if self.address is not None:
            out["address"] = str(self.address)
        return out

    # -- public, checked -------------------------------------------------------------
    def read(self) -> RobotState:
        """Return the newest state. Raises RobotError when closed."""
        self._ensure_open()
        return self._read()

    def command(self, twist: Twist) -> None:
        """Send a velocity command, clamped to `limits`. Raises RobotError when closed."""
        self._ensure_open()
        self._command(self.limits.clamp(twist))

    def stop(self) -> None:
        """Command zero velocity."""
        self.command(Twist.ZERO)

    def move_to(self, pose: Pose) -> None:
        """Teleport the robot (simulators only) and reset odometry to `pose`."""
        raise NotImplementedError(f"{self.name}: this robot cannot be moved by command")

    def make_clock(self, period: float) -> Clock:
        """The clock that paces a control loop on this robot: real time unless overridden."""
        return WallClock(period)

    def set_max_speed(self, v_max: float) -> None:
        """Lower or raise the forward speed limit [m/s]."""
        if not v_max > 0:
            raise ConfigError(f"{self.name}: max speed must be > 0 m/s, got {v_max}")
        lim = self.limits
        self.limits = Limits(v_max, lim.w_max, lim.a_max, lim.alpha_max)

    def close(self) -> None:
        """Stop the robot, then release the link. Safe to call twice."""
        if not self._closed:
            try:
                self._command(Twist.ZERO)
            finally:
                self._closed = True
                self._close()

    @property
    def closed(self) -> bool:
        """True once `close()` ran (or before the backend finished connecting)."""
        return self._closed

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _ensure_open(self) -> None:
        if self._closed:
            raise RobotError(f"{self.name}: the robot is closed")

    # -- backend hooks ---------------------------------------------------------------
    @abstractmethod
    def _read(self) -> RobotState: ...

    @abstractmethod
    def _command(self, twist: Twist) -> None: ...

    @abstractmethod
    def _close(self) -> None: ...


class RobotEmulator(Protocol):
    """A robot backend's protocol served by a simulated robot, for tests and `robotexp emulate`
    (entry-point group `robotexp.emulators`, under the backend's name).

    Emulator classes are constructed as
    `cls(world, *, pose=None, port=..., pty=False, speedup=1.0, **options)`: `pose` the start pose
    (None: the world's default), `port` a TCP port (0: any free one; the class's default if not
    given), `pty` serve on a pseudo-terminal instead, `speedup` robot time per wall time, and
    keyword `options` named in the class's `options` (e.g. mavlink's "udp"). They serve after
    `start()` (which returns the emulator) until `close()` (safe twice) and tell where in `address`
    (what the backend's `Robot` class accepts as its address). `radius` [m] is the simulated
    robot's footprint: the start pose must leave it room.
    """

    radius: ClassVar[float]
    options: ClassVar[frozenset[str]]
    address: str

    def __init__(self, world: World, *, pose: Pose | None = None, pty: bool = False, speedup: float = 1.0,
                 **options: object) -> None: ...

    def start(self) -> Self: ...

    def close(self) -> None: ...
